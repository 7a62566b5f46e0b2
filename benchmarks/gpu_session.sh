#!/usr/bin/env bash
# One call on a lent machine with an NVIDIA GPU (issue 16): what it has, the GPU tests
# against the CPU on the real device, and bench_gpu.py's tables: the whole step on the GPU
# (1e5-1e7), the 3D 1e6 lattice with its records in float32 (PRECISION), the 1e6 lattices
# in the other particle order than the main table's (ORDER: 3D in the neighbour list's
# order, 2D in its own), an impact model's step (a quarter model on a wall with its
# symmetry planes and an elastic case's stabilisation, FEATURES), each kernel's time with
# ncu (KERNELS), the rates-only path and the CPU (HOST_STAGES), the launch settings at 1M 3D
# particles (TUNE=1: off by default since 2026-12-07, measured at the second lease).
# The stages' limits add up to some 18 minutes, more than a device command may run (10),
# so the call keeps to TOTAL seconds (default 540, counted from its start): a stage runs only
# if its time limit ends within TOTAL, else the session log says it was skipped and why; the
# stages come in the order of their worth (the whole step on the GPU, the tests beside it,
# float32 records, the particle order, the quarter model, ncu, the rest). Set a toggle to 0
# to leave a stage out, or TOTAL to the time the call has.
#
#   bash benchmarks/gpu_session.sh            # writes under $OUT (or runs/gpu_session)
#   TOTAL=300 FEATURES=0 bash benchmarks/gpu_session.sh
#
# The machine's own python3 runs it (its numba and numba-cuda); packages it lacks travel as
# wheels in .whl/ (pydantic, numexpr, meshio, and numpy 2.4: the image's numba-cuda 0.30.4 fails
# to compile any kernel with its numpy 2.5, which has no np.row_stack; docs/gpu.md).
# Each stage has its own time limit and writes its log under $OUT as it goes, so a stage that
# fails or overruns leaves the others' results.
set -u
OUT=${OUT:-runs/gpu_session}
source "$(dirname "$0")/gpu_env.sh"  # $OUT, stamp, the machine, the wheels, PYTHONPATH
TOTAL=${TOTAL:-540}  # seconds the whole call may take ($SECONDS counts from the script's start)

# fits LIMIT WHAT: true if a stage whose time limit is LIMIT seconds ends within TOTAL; else
# the session log says that WHAT was skipped, with the seconds left
fits() {
  local left=$((TOTAL - SECONDS))
  if [ "$left" -ge "$1" ]; then return 0; fi
  stamp "skipped: $2 (a limit of $1 s; $left s left of TOTAL=$TOTAL)"
  return 1
}

stamp "smoke: impactsph imports, numba-cuda sees the GPU"
timeout 60 python3 -c "
import impactsph
from impactsph.gpu import unavailable_reason
print('impactsph', impactsph.__version__, '| GPU:', unavailable_reason() or 'usable')
import numpy as np
from numba import cuda
@cuda.jit
def one(a):
    a[cuda.grid(1)] = 1.0
a = cuda.to_device(np.zeros(256))
one[2, 128](a)
print('a kernel compiled and ran:', a.copy_to_host().sum() == 256, '| numpy', np.__version__)
" 2>&1 | tee "$OUT/smoke.log"

# the GPU tests (mode gpu: the device against the CPU) beside the benchmark: two workers,
# one a file; their kernels are small, their compilation is on the CPU
# (their limit: TESTS_LIMIT, and no later than 20 s before TOTAL)
tests_limit=${TESTS_LIMIT:-330}
left=$(( TOTAL - SECONDS - 20 ))
tests_limit=$(( tests_limit < left ? tests_limit : left ))
tests_limit=$(( tests_limit > 10 ? tests_limit : 10 ))
stamp "tests on the GPU (in the background, at most $tests_limit s)"
( timeout "$tests_limit" python3 -m pytest -q -rA -p no:cacheprovider -n 2 --dist loadfile \
    tests/test_gpu.py tests/test_gpu_step.py -k "${TESTS_K:-not simulator and not compile_for_a_gpu}" \
    --durations=15 > "$OUT/tests.log" 2>&1; echo "tests rc $?" >> "$OUT/tests.log" ) &
tests=$!

# bench LIMIT WHAT NAME ARGS...: bench_gpu.py ARGS within LIMIT seconds, if that ends within
# TOTAL, its table in $OUT/NAME.log and $OUT/NAME.json
bench() {
  local limit=$1 what=$2 name=$3
  shift 3
  fits "$limit" "$what" || return 0
  stamp "bench: $what"
  timeout "$limit" python3 benchmarks/bench_gpu.py "$@" --json "$OUT/$name.json" 2>&1 \
    | tee "$OUT/$name.log"
}

GPU_BUDGET=${GPU_BUDGET:-240}
bench $((GPU_BUDGET + 40)) "the whole step on the GPU, 1e5-1e7 (and the CPU's steps at 1e5)" \
  bench_gpu --devices gpu --dims 3 2 --sizes 1e5 1e6 1e7 --steps 20 --compare-cpu \
  --budget "$GPU_BUDGET"
# the packed records in float32 (compute.record_precision, docs/gpu.md "Records in float32":
# 88 B a particle against 152 B in 3D, nearly half of what the pair kernel reads a
# neighbour, which bound it on the H200): against the main table's 3D 1e6 row. Not yet run
# on a GPU (2026-12-04 to 2026-12-07: no GPU lent); on the CPU 3-5% slower
[ "${PRECISION:-1}" = 1 ] && bench 100 "the 3D 1e6 lattice, records in float32 (PRECISION)" \
  bench_gpu_float32 --devices gpu --dims 3 --sizes 1e6 --steps 20 --record-precision float32 \
  --budget 70
# the particles numbered in the neighbour list's order at t = 0 (compute.particle_order =
# "cells"; "auto" does it for 2D from 5e5 particles only, where the CPU gains): each
# particle's own rows (dv[i], dS[i], S[i], ...) then lie in the order the pair kernel's warps
# walk, so its writes coalesce; against the main table's 3D 1e6 row in the lattice's order.
# Not yet run on a GPU (2026-12-07, fifth session); on the CPU 1.01-1.04 of the rate in 3D
[ "${ORDER:-1}" = 1 ] && bench 100 "the 3D 1e6 lattice in the list's order (ORDER)" \
  bench_gpu_cells_order --devices gpu --dims 3 --sizes 1e6 --steps 20 --particle-order cells \
  --budget 70
# the 2D 1e6 lattice in its own order, against the main table's row, renumbered in the list's
# order by the default (compute.particle_order = "auto", 2026-12-07: 0.80-0.81 of the 2D
# Taylor bar's step on the CPU at 1e6)
[ "${ORDER:-1}" = 1 ] && bench 90 "the 2D 1e6 lattice in its own order (ORDER)" \
  bench_gpu_input_order --devices gpu --dims 2 --sizes 1e6 --steps 20 --particle-order input \
  --budget 60
# what a user's impact model adds to a step: the ghosts' stages, their mirror, the walls'
# constraint, the hourglass control (bench_gpu.py --model quarter), on the GPU and the CPU
[ "${FEATURES:-1}" = 1 ] && bench 140 "a quarter model on a wall, 3D, GPU and CPU (FEATURES)" \
  bench_gpu_quarter --devices gpu cpu --dims 3 --sizes 1e5 1e6 --steps 20 --model quarter \
  --budget 110
# the launch settings at 1M 3D particles: threads a block and the pair kernel's register cap
# (benchmarks/gpu_registers.py, 3D: 166 registers free, 3 blocks of 128 a multiprocessor;
# capped at 128, 4 blocks with 284 B of spills), a process each
[ "${TUNE:-0}" = 1 ] && bench 170 "threads a block x register cap, 1e6 3D (TUNE)" \
  bench_gpu_tune --devices gpu --dims 3 --sizes 1e6 --steps 20 --threads-per-block 128 256 \
  --max-registers 0 128 --budget 150
if [ "${KERNELS:-1}" = 1 ] && command -v ncu > /dev/null && fits 150 "ncu (KERNELS)"; then
# each kernel's time in a step at 1M 3D particles (the rest of the step is launches and waits)
stamp "kernels: ncu over three steps at 1e6 3D"
timeout 150 ncu --clock-control none --target-processes all --launch-skip 150 \
  --launch-count 45 --print-summary per-kernel python3 benchmarks/bench_gpu.py --devices gpu \
  --dims 3 --sizes 1e6 --steps 12 --budget 120 --json "$OUT/bench_gpu_ncu.json" \
  > "$OUT/ncu.log" 2>&1
grep -E "^\s+[a-z_]+kernel|Duration|^  [a-z_]+\(" "$OUT/ncu.log" | head -80
fi
[ "${HOST_STAGES:-1}" = 1 ] && bench 75 "the rates on the GPU, the state on the host" \
  bench_gpu_host --devices gpu-host --dims 3 2 --sizes 1e5 1e6 --steps 10 --budget 40
[ "${HOST_STAGES:-1}" = 1 ] && bench 75 "the CPU (HOST_STAGES)" \
  bench_cpu --devices cpu --dims 3 2 --sizes 1e5 1e6 --steps 3 --budget 40

stamp "waiting for the tests"
wait "$tests"
tail -30 "$OUT/tests.log"
stamp "done"
