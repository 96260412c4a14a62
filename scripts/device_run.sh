#!/usr/bin/env bash
# On the lent GPU machine, from the repository root with device-bin/ carried (see
# device_bundle.sh): `bash device-bin/device_run.sh PHASE`, results into $OUT. Each phase fits
# one 10-minute command:
#   parity   the GPU parity tests (mean-field step, fast sums, cell lists) with MOTILE_REQUIRE_GPU=1
#   bench    gpu_bench: GPU against the 16-thread CPU, side by side (BENCH_ARGS passed on,
#            e.g. "--cases mf" to split it)
#   scaling  the thread-scaling table at 1, 2, 4, 8, 16 threads (SCALING_ARGS passed on)
#   science  a short science run on the GPU: the paper's mean-field case at 128^3 to t = 128
#   all      parity, bench (every case), science in one command of at most 8 minutes: each
#            phase under its own time limit (timeout), so a slow phase cannot hide the others'
#            results; at most 8 files in $OUT (device.txt, parity.txt, gpu_bench.{md,csv,log},
#            science.txt, science_timeseries.csv, all.txt)
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
      "$B/test_particle_gpu_ewald" --include-ignored --nocapture --test-threads 1
      "$B/test_particle_gpu_step" --include-ignored --nocapture --test-threads 1; } \
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
  science)
    # The paper's case (meanfield_paper_64.toml) on 128^3 to t = 128; the run directory stays
    # in /tmp, only its log and time series come back.
    sed -e 's/^grid = .*/grid = 128/' -e 's/^t_end = .*/t_end = 128.0/' \
      -e 's/^snapshot_interval = .*/snapshot_interval = 128.0/' \
      -e 's/^checkpoint_interval = .*/checkpoint_interval = 128.0/' \
      "$B/meanfield_paper_64.toml" >/tmp/motile-science.toml
    rm -rf /tmp/motile-science
    start=$(date +%s)
    "$B/motile" meanfield run /tmp/motile-science.toml --device gpu --out /tmp/motile-science \
      >"$OUT/science.txt" 2>&1
    rc=$?
    echo "science exit $rc after $(($(date +%s) - start)) s" >>"$OUT/science.txt"
    cp /tmp/motile-science/timeseries.csv "$OUT/science_timeseries.csv" 2>/dev/null || true
    tail -5 "$OUT/science.txt"
    ;;
  all)
    # Limits in seconds (sum 460 s, under 8 minutes with the start-up).
    { echo "== parity (limit 120 s)"; timeout 120 bash "$0" parity; echo "rc $?"
      echo "== bench (limit 240 s)"; timeout 240 bash "$0" bench; echo "rc $?"
      echo "== science (limit 100 s)"; timeout 100 bash "$0" science; echo "rc $?"; } \
      >"$OUT/all.txt" 2>&1
    cat "$OUT/all.txt"
    ;;
  *)
    echo "usage: device_run.sh parity|bench|scaling|science|all" >&2
    exit 2
    ;;
esac
