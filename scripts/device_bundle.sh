#!/usr/bin/env bash
# Builds what a GPU machine without Rust runs (scripts/device_run.sh), into device-bin/ (ignored
# by git; name it in the device tool's `carry`): the motile binary and the benchmark examples
# with the gpu feature, the GPU parity test executables, stripped, device_run.sh and the
# science phase's config.
# The device machine has CUDA but no Rust: everything is built here.
set -euo pipefail
cd "$(dirname "$0")/.."
rm -rf device-bin
mkdir -p device-bin
# The gpu build replaces target/release/motile: the default build is put back at the end (after
# removing the link: cargo hard-links that file to its own in deps/, which a copy onto it would
# overwrite).
if [ -f target/release/motile ]; then
  cp target/release/motile target/release/.motile-default
  trap 'rm -f target/release/motile; cp target/release/.motile-default target/release/motile' EXIT
fi
cargo build --release -p motile-experiments --features gpu --bin motile --example gpu_bench \
  --example scaling
cp target/release/motile target/release/examples/gpu_bench target/release/examples/scaling \
  device-bin/
# The test executables, by the paths cargo reports for them.
exe() {
  cargo test --release -p "$1" --features gpu --test "$2" --no-run --message-format=json 2>/dev/null \
    | python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("executable") and m.get("target", {}).get("kind") == ["test"]:
        print(m["executable"])'
}
cp "$(exe motile-meanfield gpu)" device-bin/test_meanfield_gpu
cp "$(exe motile-particle gpu_ewald)" device-bin/test_particle_gpu_ewald
cp "$(exe motile-particle gpu_step)" device-bin/test_particle_gpu_step
cp "$(exe motile-particle gpu_resident)" device-bin/test_particle_gpu_resident
cp "$(exe motile-particle gpu_slender)" device-bin/test_particle_gpu_slender
strip device-bin/*
cp scripts/device_run.sh scripts/device_compare.py experiments/configs/meanfield_paper_64.toml device-bin/
# The kernel sets' sources, for the compiler's resource report on the device (device_run.sh ptxas).
cp meanfield/src/gpu/kernels.cu device-bin/kernels_meanfield.cu
cat particle/src/ewald/gpu/{kernels,resident,scan}.cu >device-bin/kernels_particle_sums.cu
cat particle/src/step/gpu/{cells,update,contacts,step}.cu particle/src/ewald/gpu/scan.cu \
  >device-bin/kernels_particle_step.cu
cp particle/src/hydro/gpu/slender.cu device-bin/kernels_particle_slender.cu
du -sh device-bin
