#!/usr/bin/env bash
# On the lent GPU machine, from the repository root with device-bin/ carried (see
# device_bundle.sh): `bash device-bin/device_run.sh PHASE`, results into $OUT. Each phase fits
# one 10-minute command:
#   parity   the GPU parity tests (mean-field step, fast sums) with MOTILE_REQUIRE_GPU=1
#   bench    gpu_bench: GPU against the 16-thread CPU, side by side (BENCH_ARGS passed on,
#            e.g. "--cases mf" to split it)
#   scaling  the thread-scaling table at 1, 2, 4, 8, 16 threads (SCALING_ARGS passed on)
set -uo pipefail
B="$(dirname "$0")"
OUT="${OUT:-/tmp/motile-out}"
mkdir -p "$OUT"
nvidia-smi -L >"$OUT/device.txt" 2>&1 || true
case "${1:-}" in
  parity)
    export MOTILE_REQUIRE_GPU=1
    # The CUDA tests are #[ignore]d (a run without a GPU reports them as not run): included here.
    { "$B/test_meanfield_gpu" --include-ignored --nocapture --test-threads 1
      "$B/test_particle_gpu_ewald" --include-ignored --nocapture --test-threads 1; } \
      >"$OUT/parity.txt" 2>&1
    echo "parity exit $?" >>"$OUT/parity.txt"
    tail -40 "$OUT/parity.txt"
    ;;
  bench)
    # shellcheck disable=SC2086
    "$B/gpu_bench" ${BENCH_ARGS:-} --out "$OUT/gpu_bench.csv" >"$OUT/gpu_bench.md" 2>"$OUT/gpu_bench.log"
    echo "bench exit $?"
    cat "$OUT/gpu_bench.md"
    ;;
  scaling)
    # shellcheck disable=SC2086
    "$B/scaling" --threads 1,2,4,8,16 --reps 3 ${SCALING_ARGS:-} >"$OUT/scaling.md" 2>&1
    echo "scaling exit $?"
    cat "$OUT/scaling.md"
    ;;
  *)
    echo "usage: device_run.sh parity|bench|scaling" >&2
    exit 2
    ;;
esac
