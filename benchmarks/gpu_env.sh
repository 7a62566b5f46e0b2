# Sourced by gpu_session.sh and gpu_profile.sh on a lent machine with an NVIDIA GPU: $OUT
# made, `stamp` (a timed line into $OUT/session.log), the machine's GPU, Python packages and
# CPU into $OUT/machine.txt, the wheels of .whl/ installed into /tmp/site (what the machine's
# own python3 lacks, and numpy 2.4: docs/gpu.md, "Running on a lent machine"), src and
# /tmp/site on PYTHONPATH, numba's and impactsph's caches under /tmp.
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
stamp() { echo "== $(date -u +%T) $*" | tee -a "$OUT/session.log"; }

stamp "machine"
{
  nvidia-smi --query-gpu=name,memory.total,memory.used,clocks.sm,clocks.max.sm,driver_version \
    --format=csv
  python3 -c "import sys, numpy, numba; print(sys.version); print('numpy', numpy.__version__, 'numba', numba.__version__)"
  python3 -m pip show numba-cuda 2>/dev/null | head -2
  echo "cores $(nproc)"; lscpu | grep -E "Model name|^CPU\(s\)"
} > "$OUT/machine.txt" 2>&1
cat "$OUT/machine.txt"

if [ -d .whl ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl > "$OUT/wheels.log" 2>&1 || stamp "wheels failed"
fi
export PYTHONPATH="$PWD/src:/tmp/site${PYTHONPATH:+:$PYTHONPATH}"
if [ -z "${CUDA_HOME:-}" ] && [ -d /usr/local/cuda ]; then export CUDA_HOME=/usr/local/cuda; fi
export NUMBA_CACHE_DIR=/tmp/numba-cache IMPACTSPH_CACHE_DIR=/tmp/impactsph-cache
