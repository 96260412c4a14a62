#!/usr/bin/env bash
# On the lent GPU machine, from the repository root with device-bin/ carried (see
# device_bundle.sh): `bash device-bin/device_run.sh PHASE`, results into $OUT. Each phase fits
# one 10-minute command:
#   parity   the GPU parity tests (mean-field step, fast sums, the resident particle step's
#            kernels and steps) with MOTILE_REQUIRE_GPU=1
#   bench    gpu_bench: GPU against the 16-thread CPU, side by side (BENCH_ARGS passed on,
#            e.g. "--cases mf" to split it); rows appended to gpu_bench.md and gpu_bench.log
#   runs     whole particle runs through the binary (none, dipole, sbt-explicit, sbt; 1 024 rods at
#            nu = 2, 100 steps): resident on the GPU against the CPU, and a second GPU run
#            against the first (run-to-run difference, bit for bit or not)
#   science  the paper-dilute scene's L/l = 100 member (625 000 rods, sbt-explicit) resident on
#            the GPU for up to 100 steps: a real run's steps/s, its log and time series
#   profile  where the GPU's time goes (gpu_bench --profile, GPU sides only): each kernel,
#            transform and transfer of the mean-field step, the sums and the particle steps,
#            then Nsight Compute's speed-of-light and occupancy of the spreaders and gathers at
#            1e6 points; into profile.txt and ncu.txt (PROFILE_CASES: the gpu_bench case lists
#            to profile, one run each; default "mf sum dipole,explicit100,sbt")
#   ptxas    the compiler's resource report (registers, stack, spills) of every kernel set
#   check    a second, shorter device check after changes (about 7 minutes): the CUDA parity
#            tests only, ptxas, the sums (every spreader at 1e6 points, the resident product),
#            the mean-field step, the dipole and explicit steps, the sbt step's profile, the
#            whole runs and Nsight Compute on the dipole sum's spreader and gather, each phase
#            under its own limit
#   memory   the memory and speed figures (about 5 minutes): the CUDA parity tests of the sums and
#            the resident steps (sbt's among them), ptxas (no stack in the dipole step's
#            kernels), then gpu_bench's dipole steps at L/l = 100 and 175 and the sbt step at
#            L/l = 50 (the resident rows print steps/s, bytes in use per rod and the breakdown)
#   meanfield  the paper's mean-field case at 128^3 to t = 128 on the GPU
#   scaling  the thread-scaling table at 1, 2, 4, 8, 16 threads (SCALING_ARGS passed on)
#   series   the paper's series, grown a few members at a time: first the members of the
#            paper-concentrated scene not yet in docs/gallery/paper_concentrated_series.csv (L16,
#            L24, L32), then those of paper-dilute not yet in docs/gallery/paper_dilute_series.csv
#            (L75, L100, L150, L175, mf128, mf256), each resident on the GPU under the time left
#            (SERIES_LIMIT seconds in all, default 540); a member whose estimate does not fit is
#            not started. Into $OUT/series-concentrated.tgz and $OUT/series.tgz: each member's
#            compact products (config, time series, lowest modes, log, analysis; no snapshots or
#            checkpoints), the comparison of the members run here (compare/: series.csv and
#            particle_statistics.csv rows, curves, figures), and series.log;
#            `bash scripts/series_harvest.sh ARCHIVE` files each into docs/gallery/.
#            Where no member fits, the first that does not runs for the time left as a
#            measurement (MEMBER-partial: its time series and log, whose last lines split the
#            wall time; SERIES_MEASURE=0 turns this off). SERIES_CONCENTRATED_MEMBERS,
#            SERIES_MEMBERS, SERIES_DEVICE and MOTILE_BIN change them; SERIES_SCENE (with
#            SERIES_MEMBERS and SERIES_CSV) runs one scene alone (the test suite runs it so on
#            the host emulation with a small scene).
#   all      parity, bench (every target case, in two parts), runs and science in one command
#            of at most 8 minutes: each phase under its own time limit (timeout), so a slow
#            phase cannot hide the others' results; 8 files in $OUT (device.txt, parity.txt,
#            gpu_bench.md, gpu_bench.log, runs.txt, science.txt, science_timeseries.csv, all.txt)
set -uo pipefail
B="$(dirname "$0")"
# The CUDA parity tests of the particle sums and the resident steps, each under its own limit.
particle_cuda_parity() {
  timeout 60 "$B/test_particle_gpu_ewald" --include-ignored --nocapture --test-threads 1 gpu_sums
  timeout 60 "$B/test_particle_gpu_step" --include-ignored --nocapture --test-threads 1 cuda
  timeout 60 "$B/test_particle_gpu_resident" --include-ignored --nocapture --test-threads 1 cuda
  timeout 60 "$B/test_particle_gpu_slender" --include-ignored --nocapture --test-threads 1 cuda
}
OUT="${OUT:-/tmp/motile-out}"
MOTILE="${MOTILE_BIN:-$B/motile}"
mkdir -p "$OUT"
if [ ! -f "$OUT/device.txt" ]; then
  { nvidia-smi -L; nvidia-smi --query-gpu=name,memory.total,clocks.max.sm --format=csv
    nproc; echo "ldd motile:"; ldd "$MOTILE"; "$MOTILE" --version; } >"$OUT/device.txt" 2>&1
fi

# One stage of the series phase: the members MEMBERS of scene S not yet in table CSV, run in
# RS under the time left (globals LIMIT, start, ran, measured, log), their compact products
# and the comparison into $OUT/NAME.tgz.
grow_series() {
  local S="$1" CSV="$2" MEMBERS="$3" NAME="$4" RS="$5"
  local D="$RS-products"
  rm -rf "$D"
  mkdir -p "$D" "$RS"
  # A built-in scene's name tells series_harvest.sh which table the rows go to.
  case "$S" in
    */* | *.toml) ;;
    *) echo "$S" >"$D/scene_name" ;;
  esac
  for m in $MEMBERS; do
    if grep -q "^$m," "$CSV" 2>/dev/null; then
      log "$m: in $CSV already"
      continue
    fi
    left=$((LIMIT - ($(date +%s) - start)))
    said=$("$MOTILE" run "$S" --only "$m" --device "${SERIES_DEVICE:-gpu}" --dry-run --estimate 2>&1)
    est=$(echo "$said" | sed -n 's/.*: \([0-9]*\) s in all.*/\1/p' | head -1)
    if [ -z "$est" ]; then
      log "$m: no estimate: $(echo "$said" | tail -1)"
      continue
    fi
    # The estimate (steps, analysis and comparison), 20% over, and half a minute of set-up.
    need=$((est * 6 / 5 + 30))
    if [ "$need" -gt "$left" ]; then
      if [ -z "$measured" ] && [ -z "$ran" ] && [ "$left" -gt 120 ] \
        && [ "${SERIES_MEASURE:-1}" = 1 ]; then
        # Nothing fits: the first member that does not is run for the time left as a
        # measurement (its steps/s and the log's split of the wall time come back as
        # MEMBER-partial; no row), so that each GPU at hand says where the time goes.
        log "$m: does not fit (estimated $est s, $left s left): run for $((left - 60)) s to measure it"
        measured=1
        timeout $((left - 60)) "$MOTILE" run "$S" --only "$m" --device "${SERIES_DEVICE:-gpu}" \
          --out "$RS" >"$D/$m.txt" 2>&1
        log "$m: measurement stopped ($?)"
        mkdir -p "$D/$m-partial"
        for f in config.toml timeseries.csv modes.csv run.log; do
          cp "$RS/$m/$f" "$D/$m-partial/" 2>/dev/null
        done
        continue
      fi
      log "$m: not started (estimated $est s, needs $need s, $left s left)"
      continue
    fi
    ran=1
    log "$m: starting (estimated $est s, $left s left)"
    t0=$(date +%s)
    # SIGTERM when the time is up: the run stops at a step boundary with a checkpoint.
    timeout "$left" "$MOTILE" run "$S" --only "$m" --device "${SERIES_DEVICE:-gpu}" --out "$RS" \
      >"$D/$m.txt" 2>&1
    rc=$?
    log "$m: exit $rc after $(($(date +%s) - t0)) s"
    grep -E "steps, .* s \(with analysis\)|^motile: error|^Error" "$D/$m.txt" | tail -3
    # The compact products (what is committed); the snapshots and checkpoints stay here.
    mkdir -p "$D/$m/analysis"
    for f in config.toml timeseries.csv modes.csv run.log; do
      cp "$RS/$m/$f" "$D/$m/" 2>/dev/null
    done
    cp "$RS/$m"/analysis/*.csv "$RS/$m"/analysis/*.toml "$RS/$m"/analysis/*.svg "$D/$m/analysis/" \
      2>/dev/null
    [ "$rc" = 0 ] || mv "$D/$m" "$D/$m-partial"
  done
  # The last comparison covers every member run here.
  if [ -d "$RS/compare" ]; then
    rm -rf "$D/compare"
    cp -r "$RS/compare" "$D/compare"
  fi
  cp "$RS/scene.md" "$D/" 2>/dev/null
  cp "$R/series.log" "$D/" 2>/dev/null
  tar czf "$OUT/$NAME.tgz" -C "$D" .
  cat "$D/compare/series.csv" 2>/dev/null
}

case "${1:-}" in
  parity)
    export MOTILE_REQUIRE_GPU=1
    # The CUDA tests are #[ignore]d (a run without a GPU reports them as not run): included here.
    { "$B/test_meanfield_gpu" --include-ignored --nocapture --test-threads 1
      "$B/test_particle_gpu_ewald" --include-ignored --nocapture --test-threads 1
      "$B/test_particle_gpu_step" --include-ignored --nocapture --test-threads 1
      "$B/test_particle_gpu_resident" --include-ignored --nocapture --test-threads 1
      "$B/test_particle_gpu_slender" --include-ignored --nocapture --test-threads 1; } \
      >"$OUT/parity.txt" 2>&1
    echo "parity exit $?" >>"$OUT/parity.txt"
    tail -40 "$OUT/parity.txt"
    ;;
  bench)
    # shellcheck disable=SC2086
    "$B/gpu_bench" ${BENCH_ARGS:-} >>"$OUT/gpu_bench.md" 2>>"$OUT/gpu_bench.log"
    echo "bench exit $?"
    tail -20 "$OUT/gpu_bench.md"
    ;;
  scaling)
    # shellcheck disable=SC2086
    "$B/scaling" --threads 1,2,4,8,16 --reps 3 ${SCALING_ARGS:-} >"$OUT/scaling.md" 2>&1
    echo "scaling exit $?"
    cat "$OUT/scaling.md"
    ;;
  runs)
    R=/tmp/motile-runs
    rm -rf "$R"
    mkdir -p "$R"
    for level in none dipole sbt-explicit sbt; do
      printf '%s\n' "box_length = 8" "volume_fraction = 2" "hydrodynamics = \"$level\"" \
        "dt = 0.02" "t_end = ${RUNS_T_END:-2.0}" "diagnostic_interval = 0.1" "snapshot_interval = 2.0" \
        "checkpoint_interval = 1.0" "vtk = false" >"$R/$level.toml"
      { echo "== $level"
        "$B/motile" particle run "$R/$level.toml" --out "$R/$level-cpu" 2>&1 | tail -1
        for k in 1 2; do
          "$B/motile" particle run "$R/$level.toml" --out "$R/$level-gpu$k" --device gpu 2>&1 \
            | tail -1
        done
        grep -i -m1 "device\|gpu" "$R/$level-gpu1/run.log"
        echo -n "GPU against CPU: "; python3 "$B/device_compare.py" "$R/$level-cpu" "$R/$level-gpu1"
        echo -n "second GPU run against the first: "
        python3 "$B/device_compare.py" "$R/$level-gpu1" "$R/$level-gpu2"; } >>"$OUT/runs.txt" 2>&1
    done
    cat "$OUT/runs.txt"
    ;;
  science)
    # The paper-dilute scene's L100 member (its settings), resident on the GPU, 100 steps; the
    # run directory stays in /tmp, only its log and time series come back.
    printf '%s\n' "box_length = 100.0" "volume_fraction = 0.625" "dt = 0.05" "t_end = 5.0" \
      "seed = 1" "hydrodynamics = \"sbt-explicit\"" "device = \"gpu\"" \
      "diagnostic_interval = 0.5" "snapshot_interval = 5.0" "checkpoint_interval = 5.0" \
      "lowest_modes = true" "vtk = false" "[contact]" "margin = 0.15" "[hydro]" \
      "sum_tolerance = 1e-2" "quadrature_points = 4" >/tmp/motile-science.toml
    rm -rf /tmp/motile-science
    start=$(date +%s)
    # SIGTERM at SCIENCE_LIMIT seconds: the run stops at a step boundary with a checkpoint.
    timeout "${SCIENCE_LIMIT:-45}" "$B/motile" particle run /tmp/motile-science.toml \
      --out /tmp/motile-science >"$OUT/science.txt" 2>&1
    rc=$?
    echo "science exit $rc after $(($(date +%s) - start)) s" >>"$OUT/science.txt"
    tail -30 /tmp/motile-science/run.log >>"$OUT/science.txt" 2>/dev/null
    cp /tmp/motile-science/timeseries.csv "$OUT/science_timeseries.csv" 2>/dev/null || true
    tail -5 "$OUT/science.txt"
    ;;
  profile)
    P="--profile --reps 1 --cpu-max 0"
    { for c in ${PROFILE_CASES:-mf sum dipole,explicit100,sbt}; do
        echo "== gpu_bench $P --cases $c"
        # shellcheck disable=SC2086
        "$B/gpu_bench" $P --cases "$c" 2>&1
      done; } >>"$OUT/profile.txt" 2>&1
    grep -A12 "^profile:" "$OUT/profile.txt" | head -60
    ;;
  ncu)
    ncu -k 'regex:spread_cells|spread_sorted|gather_sorted' -c 6 --section SpeedOfLight \
      --section Occupancy --section LaunchStats --section MemoryWorkloadAnalysis \
      "$B/gpu_bench" --cases sum --sum-sizes 1000000 --cpu-max 0 --reps 1 >"$OUT/ncu.txt" 2>&1
    echo "ncu exit $?"
    grep -E "^  [a-z_]+|Duration|Memory Throughput|DRAM Throughput|Compute \(SM\)|Achieved Occupancy|Registers Per|Shared Memory Config|Block Limit" "$OUT/ncu.txt" | head -60
    ;;
  ptxas)
    NVCC="$(command -v nvcc || ls /usr/local/cuda*/bin/nvcc 2>/dev/null | head -1)"
    {
      for set in meanfield particle_sums particle_step particle_slender; do
        echo "== $set"
        "$NVCC" -arch=sm_90 -cubin -Xptxas -v -o /tmp/$set.cubin "$B/kernels_$set.cu" 2>&1 \
          | grep -E "Compiling entry|registers|stack frame|spill" | sed 's/ptxas info *: //'
      done
    } >"$OUT/ptxas.txt" 2>&1
    grep -B1 -A2 "bytes spill stores" "$OUT/ptxas.txt" | grep -v " 0 bytes spill stores" | head -40
    ;;
  check)
    export MOTILE_REQUIRE_GPU=1
    { echo "== parity (CUDA tests only)"
      particle_cuda_parity
      timeout 40 "$B/test_meanfield_gpu" --include-ignored --nocapture --test-threads 1 --exact gpu_step_matches_the_cpu_step
    } >"$OUT/parity.txt" 2>&1
    grep -E "test result|FAILED|panicked|Cells|device vs CPU|steps of" "$OUT/parity.txt"
    timeout 30 bash "$0" ptxas
    BENCH_ARGS="--cases sum --sum-sizes 1000000,10000000 --cpu-max 0" timeout 70 bash "$0" bench
    BENCH_ARGS="--cases mf --cpu-max 0" timeout 40 bash "$0" bench
    BENCH_ARGS="--cases dipole,explicit100 --cpu-max 0" timeout 75 bash "$0" bench
    BENCH_ARGS="--cases sbt --cpu-max 0 --profile" timeout 50 bash "$0" bench
    timeout 40 bash "$0" runs
    # Where the spreader and the gather of the dipole level's sum spend their time.
    timeout 60 ncu -k 'regex:spread_cells|gather_sorted' -c 2 --section SpeedOfLight \
      --section Occupancy --section LaunchStats --section WarpStateStats \
      --section SchedulerStats --section MemoryWorkloadAnalysis "$B/gpu_bench" --cases dipole \
      --cpu-max 0 --reps 1 >"$OUT/ncu.txt" 2>&1
    grep -E "^  [a-z_]+|Duration|Throughput|Registers Per|Achieved Occupancy|Stall|Issued|Eligible|Local|Shared Memory" "$OUT/ncu.txt" | head -60
    ;;
  memory)
    export MOTILE_REQUIRE_GPU=1
    { echo "== parity (CUDA tests of the sums and the resident steps)"
      particle_cuda_parity
    } >"$OUT/parity.txt" 2>&1
    grep -E "test result|FAILED|panicked|device vs CPU|steps of" "$OUT/parity.txt"
    timeout 30 bash "$0" ptxas
    echo "== kernels with a stack (the driver reserves it for every thread the device holds)"
    grep -B1 -E "^[[:space:]]*[1-9][0-9]* bytes stack frame" "$OUT/ptxas.txt" | grep -E "entry|stack"
    BENCH_ARGS="--cases dipole --cpu-max 0" timeout 90 bash "$0" bench
    # The sbt step resident on the device at L/l = 50 (its GMRES there too): steps/s, memory.
    BENCH_ARGS="--cases sbt --cpu-max 0" timeout 60 bash "$0" bench
    ;;
  meanfield)
    # The paper's case (meanfield_paper_64.toml) on 128^3 to t = 128; the run directory stays
    # in /tmp, only its log and time series come back.
    sed -e 's/^grid = .*/grid = 128/' -e 's/^t_end = .*/t_end = 128.0/' \
      -e 's/^snapshot_interval = .*/snapshot_interval = 128.0/' \
      -e 's/^checkpoint_interval = .*/checkpoint_interval = 128.0/' \
      "$B/meanfield_paper_64.toml" >/tmp/motile-mf.toml
    rm -rf /tmp/motile-mf
    start=$(date +%s)
    "$B/motile" meanfield run /tmp/motile-mf.toml --device gpu --out /tmp/motile-mf \
      >"$OUT/meanfield.txt" 2>&1
    rc=$?
    echo "meanfield exit $rc after $(($(date +%s) - start)) s" >>"$OUT/meanfield.txt"
    cp /tmp/motile-mf/timeseries.csv "$OUT/meanfield_timeseries.csv" 2>/dev/null || true
    tail -5 "$OUT/meanfield.txt"
    ;;
  series)
    LIMIT="${SERIES_LIMIT:-540}"
    R="${SERIES_DIR:-/tmp/motile-series}"
    start=$(date +%s)
    ran=""
    measured=""
    # The log of every stage; each stage's products are gathered on the node and come back as
    # one archive (the device tool brings back a few files, not a tree).
    mkdir -p "$R"
    rm -f "$R/series.log"
    log() { echo "$(($(date +%s) - start)) s: $*" | tee -a "$R/series.log"; }
    if [ -n "${SERIES_SCENE:-}" ]; then
      grow_series "$SERIES_SCENE" "${SERIES_CSV:-docs/gallery/paper_dilute_series.csv}" \
        "${SERIES_MEMBERS:-L75 L100 L150 L175 mf128 mf256}" series "$R"
    else
      # The concentrated members first: each fits a command by its estimate, while the dilute
      # members left (L/l >= 100) do not and would only be measured.
      grow_series paper-concentrated docs/gallery/paper_concentrated_series.csv \
        "${SERIES_CONCENTRATED_MEMBERS:-L16 L24 L32}" series-concentrated "$R/concentrated"
      grow_series paper-dilute docs/gallery/paper_dilute_series.csv \
        "${SERIES_MEMBERS:-L75 L100 L150 L175 mf128 mf256}" series "$R/dilute"
    fi
    log "done"
    cp "$R/series.log" "$OUT/"
    ;;
  all)
    # Limits in seconds (sum 480 s, 8 minutes); the CPU sides of the largest cases left
    # out (their 16-thread figures are in BENCHMARKS.md).
    { echo "== parity (limit 90 s)"; timeout 90 bash "$0" parity; echo "rc $?"
      echo "== bench: mean-field, sums (limit 120 s)"
      BENCH_ARGS="--cases mf,sum --cpu-max 1000000" timeout 120 bash "$0" bench; echo "rc $?"
      echo "== bench: particle steps (limit 150 s)"
      BENCH_ARGS="--cases dipole,explicit100,sbt,explicit --cpu-max 1000000" \
        timeout 150 bash "$0" bench; echo "rc $?"
      echo "== runs (limit 60 s)"; timeout 60 bash "$0" runs; echo "rc $?"
      echo "== science (limit 60 s)"; timeout 60 bash "$0" science; echo "rc $?"; } \
      >"$OUT/all.txt" 2>&1
    cat "$OUT/all.txt"
    ;;
  *)
    echo "usage: device_run.sh parity|bench|runs|science|series|profile|ncu|ptxas|check|memory|meanfield|scaling|all" >&2
    exit 2
    ;;
esac
