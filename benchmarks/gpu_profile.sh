#!/usr/bin/env bash
# One short call on a lent machine with an NVIDIA GPU (issue 16): where a step's time goes.
# gpu_profile.py (each kernel's and copy's device time, the host's time to issue it) at 1M 3D
# particles with the default launch settings and with others, at 1e5 3D and 1M 2D, then ncu's
# view of the rate kernels at 1M 3D (occupancy, throughput, what the warps wait for), and
# bench_gpu's comparison with the CPU at 1e5 (COMPARE); the GPU tests (TESTS) start after
# TESTS_AFTER profiles and run beside what follows.  About 5 minutes; each stage has its own
# limit and its log under $OUT.  The first profile also compiles the CPU's code (about 40 s
# on the H200's host): its limit, PROFILE_LIMIT, is 100 s.
#
#   bash benchmarks/gpu_profile.sh                 # PROFILES="3:1e6:128:0 ..." to choose
#   PROFILES="3:1e6:128:0 3:1e6:128:0:float32" bash benchmarks/gpu_profile.sh  # the records'
#                                                  # precision (compute.record_precision)
set -u
OUT=${OUT:-runs/gpu_profile}
source "$(dirname "$0")/gpu_env.sh"  # $OUT, stamp, the machine, the wheels, PYTHONPATH

tests() {  # the GPU tests (the device against the CPU), in the background
  stamp "tests on the GPU (in the background: the stages after this one run beside them)"
  ( timeout "${TESTS_LIMIT:-300}" python3 -m pytest -q -rA -p no:cacheprovider -n 2 \
      --dist loadfile ${TESTS_FILES:-tests/test_gpu.py tests/test_gpu_step.py} \
      -k "${TESTS_K:-not simulator and not compile_for_a_gpu}" > "$OUT/tests.log" 2>&1
    echo "tests rc $?" >> "$OUT/tests.log" ) &
}

# dim:size:threads a block:register cap (0: none)[:record precision, float64 unless given];
# the tests start after TESTS_AFTER of them
count=0
for p in ${PROFILES:-3:1e6:128:0 3:1e6:128:0:float32 2:1e6:128:0 2:1e6:128:0:float32 3:1e5:128:0}; do
  if [ "${TESTS:-1}" = 1 ] && [ "$count" = "${TESTS_AFTER:-0}" ]; then tests; fi
  count=$((count + 1))
  IFS=: read -r dim size tpb regs precision <<< "$p"
  precision=${precision:-float64}
  stamp "profile ${dim}D $size, $tpb threads a block, register cap $regs, records in $precision"
  IMPACTSPH_CUDA_THREADS_PER_BLOCK=$tpb IMPACTSPH_CUDA_MAX_REGISTERS=$regs \
    timeout "${PROFILE_LIMIT:-100}" python3 benchmarks/gpu_profile.py --dim "$dim" --size "$size" \
    --steps "${STEPS:-10}" --record-precision "$precision" --json "$OUT/profile.json" 2>&1 \
    | grep -v Warning
done

if [ "${TESTS:-1}" = 1 ] && [ "$count" -le "${TESTS_AFTER:-0}" ]; then tests; fi
if [ "${NCU:-1}" = 1 ] && command -v ncu > /dev/null; then
  stamp "ncu: the rate kernels at 1e6 3D"
  timeout "${NCU_LIMIT:-110}" ncu --clock-control none --target-processes all \
    -k "regex:pair_kernel|particle_kernel|advance_kernel" --launch-count 4 \
    --section SpeedOfLight --section Occupancy --section LaunchStats \
    --section WarpStateStats --section MemoryWorkloadAnalysis \
    python3 benchmarks/gpu_profile.py --dim 3 --size 1e6 --steps 1 > "$OUT/ncu.txt" 2>&1
  echo "ncu rc $?"
  grep -E "^  [a-z_]|Duration|Registers Per|Achieved Occupancy|Theoretical Occupancy|Compute \(SM\) Throughput|Memory Throughput|DRAM Throughput|L1/TEX Hit|L2 Hit|Warp Cycles Per Issued|Block Limit" \
    "$OUT/ncu.txt" | head -90
fi
if [ "${COMPARE:-1}" = 1 ]; then  # the whole step on the device against the CPU, 1e5
  stamp "bench_gpu: 1e5 on the device, the same steps on the CPU"
  timeout "${COMPARE_LIMIT:-150}" python3 benchmarks/bench_gpu.py --devices gpu --dims 3 2 \
    --sizes 1e5 --steps 20 --compare-cpu --budget $(( ${COMPARE_LIMIT:-150} - 25 )) \
    --json "$OUT/bench_gpu.json" 2>&1 | grep -v Warning
fi
if [ "${TESTS:-1}" = 1 ]; then
  stamp "waiting for the tests"
  wait
  grep -E "PASSED|FAILED|ERROR|passed|failed|rc " "$OUT/tests.log" | tail -40
fi
stamp "done"
