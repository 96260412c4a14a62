#!/usr/bin/env bash
# The README's test command: installs what a fresh machine lacks (Python h5py + numpy for the
# HDF5 interoperability tests and the Python module's), a C++ compiler and clang, runs the whole test
# suite in release mode, then builds the Python module and runs its tests (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! python3 -c "import h5py, numpy, pytest" 2>/dev/null; then
  python3 -m pip install --quiet -r bench/requirements-test.txt
fi
export MOTILE_REQUIRE_H5PY=1
# The GPU kernels are also tested on the CPU, compiled by a C++ compiler (the host emulation of
# crate motile-gpu): installed when missing (Debian package), and its absence is a failure here.
if ! command -v c++ >/dev/null 2>&1 && ! command -v g++ >/dev/null 2>&1 \
  && ! command -v clang++ >/dev/null 2>&1 && [ -z "${CXX:-}" ]; then
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq g++ >/dev/null
fi
export MOTILE_REQUIRE_CXX=1
# The kernels are also compiled as CUDA device code, without a GPU or a CUDA toolkit, by
# clang's CUDA front end (motile_gpu::frontend: every kernel compiles, keeps no stack but the
# kernels each set's test names, and declares at most 48 KB of shared memory per block): clang
# is installed when missing (Debian package), its absence a failure here.
if ! command -v clang >/dev/null 2>&1 && [ -z "${MOTILE_CUDA_CLANG:-}" ]; then
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq clang >/dev/null
fi
export MOTILE_REQUIRE_CUDA_CLANG=1
# The emulation's compiled kernel sets, kept for the processes the tests start (each would
# otherwise compile the same sets again); emptied first, so that every set is compiled anew.
export MOTILE_EMULATION_CACHE="$PWD/target/emulation-cache"
rm -rf "$MOTILE_EMULATION_CACHE"
# The habits: formatting, clippy without warnings (the default build and the GPU features'),
# and the API docs without warnings (broken links included). rustfmt and clippy are rustup
# components, added where missing.
if ! cargo fmt --version >/dev/null 2>&1 || ! cargo clippy --version >/dev/null 2>&1; then
  rustup component add rustfmt clippy
fi
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
cargo clippy --workspace --all-targets \
  --features motile-particle/gpu,motile-meanfield/gpu,motile-experiments/gpu -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --workspace
cargo test --release --workspace
# The Python module (python/, outside the cargo workspace): built by maturin through pip, in
# this target folder (it reuses the crates just compiled), then its tests, which also run the
# motile binary just built (target/release/motile) to compare runs bit for bit.
CARGO_TARGET_DIR="$PWD/target" python3 -m pip install --quiet ./python
python3 -m pytest -q python/tests
# The feature builds below replace target/release/motile (the MPI build would then need
# libmpi to start): the default build, which the README's first command uses, is put back
# however this script ends.
# (Removed before the copy back: cargo hard-links target/release/motile to the feature build's
# own file in deps/, and writing through that link would leave the feature build there
# holding the default binary, which a later run of this script would then test as fresh.)
cp target/release/motile target/release/.motile-default
trap 'rm -f target/release/motile; cp target/release/.motile-default target/release/motile' EXIT
# The optional GPU back-end builds everywhere (CUDA is loaded at run time); its parity tests run
# where a GPU is present and say why they were skipped elsewhere (MOTILE_REQUIRE_GPU=1 makes a
# missing GPU a failure). All GPU kernels also run here through the host emulation: against
# their CPU twins, and end to end through the motile binary (MOTILE_GPU_BACKEND=emulation).
cargo build --release -p motile-experiments --features gpu
cargo test --release -p motile-meanfield --features gpu --test gpu
cargo test --release -p motile-particle --features gpu --test gpu_ewald
cargo test --release -p motile-particle --features gpu --test gpu_step
cargo test --release -p motile-particle --features gpu --test gpu_resident
cargo test --release -p motile-particle --features gpu --test gpu_slender
# The resident dipole step's device buffers against its memory budget, and the sbt
# step's against its design (the process's tally: the same bytes on the emulation as on CUDA;
# a file of one test, as the tally is shared).
cargo test --release -p motile-particle --features gpu --test gpu_memory
cargo test --release -p motile-meanfield --features gpu --test gpu_memory
# The GPU modules' own unit tests (kernel declarations against their sources, the kernels
# compiled as CUDA device code, the spreaders' reach and work model), which the default build
# leaves out with the feature.
cargo test --release -p motile-particle --features gpu --lib gpu
cargo test --release -p motile-meanfield --features gpu --lib gpu
cargo test --release -p motile-experiments --features gpu --test gpu_runs
cargo test --release -p motile-experiments --features gpu --test gpu_faults
# The optional distributed particle run (feature mpi) needs OpenMPI and libclang to build; they
# are installed when missing (Debian packages), then its tests run motile under mpirun on 1, 2
# and 3 ranks (oversubscribed, one thread per rank) against one process.
if ! command -v mpicc >/dev/null 2>&1 || ! command -v mpirun >/dev/null 2>&1 \
  || ! ls /usr/lib/llvm-*/lib/libclang*.so* >/dev/null 2>&1; then
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libopenmpi-dev openmpi-bin libclang-dev >/dev/null
fi
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
cargo test --release -p motile-experiments --features mpi --test mpi
