#!/usr/bin/env bash
# The README's test command: installs what a fresh machine lacks (Python h5py + numpy for the
# HDF5 interoperability tests), then runs the whole test suite in release mode.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! python3 -c "import h5py, numpy" 2>/dev/null; then
  python3 -m pip install --quiet -r bench/requirements-test.txt
fi
export MOTILE_REQUIRE_H5PY=1
cargo test --release --workspace
# The optional GPU back-end builds everywhere (CUDA is loaded at run time); its parity test runs
# where a GPU is present and says why it was skipped elsewhere (MOTILE_REQUIRE_GPU=1 makes a
# missing GPU a failure).
cargo build --release -p motile-experiments --features gpu
cargo test --release -p motile-meanfield --features gpu --test gpu
