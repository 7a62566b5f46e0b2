"""Registers, stack frame and spills of the CUDA kernels for a Hopper GPU (sm_90), from
``ptxas -v`` on numba-cuda's PTX: no GPU needed (issue 16).

Needs numba-cuda with its CUDA 12 toolkit wheels (``pip install -e ".[gpu]"``), whose
``nvidia-cuda-nvcc`` package carries ptxas. The argument types are those the tests use to
compile the kernels for sm_90 (``tests/test_gpu.py``). At 128 threads a block, a kernel of R
registers a thread keeps at most ``65536 // (128 R)`` blocks on a multiprocessor (of 16).

    python benchmarks/gpu_registers.py              # 2D and 3D, the paper's options
    python benchmarks/gpu_registers.py --dims 3 --record-precision float32
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

ROOT = Path(__file__).resolve().parents[1]
RATE_KERNELS = {0: "particle_kernel", 1: "pair_kernel", 2: "correction_kernel"}
STEP_KERNELS = ("advance", "survey", "neighbours", "totals", "displacement")


def ptxas_path() -> str:
    """The ptxas of the ``nvidia-cuda-nvcc-cu12`` wheel (the gpu extra)."""
    import nvidia.cuda_nvcc

    return str(Path(nvidia.cuda_nvcc.__path__[0]) / "bin" / "ptxas")


def blocks_a_multiprocessor(registers: int, threads: int = 128) -> int:
    """Blocks of ``threads`` threads that an sm_90 multiprocessor (65,536 registers, at most
    16 blocks) keeps for a kernel of ``registers`` registers a thread."""
    return min(16, 65536 // (threads * registers))


def ptxas_report(ptxas: str, ptx: str, max_registers: int = 0) -> dict:
    """Registers, stack frame and spill stores of the one kernel in ``ptx`` (with
    ``max_registers``, ptxas's ``-maxrregcount``: what ``cuda.jit(max_registers=...)`` asks
    the linker for)."""
    with tempfile.TemporaryDirectory() as folder:
        source = os.path.join(folder, "kernel.ptx")
        Path(source).write_text(ptx)
        cap = [f"-maxrregcount={max_registers}"] if max_registers else []
        out = subprocess.run([ptxas, "-v", "-arch=sm_90", *cap, source, "-o",
                              os.path.join(folder, "kernel.o")],
                             capture_output=True, text=True, check=True)
    entry = out.stderr[out.stderr.rindex("Compiling entry function"):]
    return {key: int(re.search(pattern, entry).group(1))
            for key, pattern in (("registers", r"Used (\d+) registers"),
                                 ("stack", r"(\d+) bytes stack frame"),
                                 ("spills", r"(\d+) bytes spill stores"))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--dims", nargs="+", type=int, default=[2, 3], choices=[1, 2, 3])
    ap.add_argument("--caps", nargs="*", type=int, default=[128, 96, 80, 64],
                    help="also the pair kernel under these register caps (ptxas "
                    "-maxrregcount): its spills")
    ap.add_argument("--record-precision", choices=("float64", "float32"), default="float64",
                    help="the rate kernels' records (compute.record_precision)")
    args = ap.parse_args(argv)
    import numba.cuda.dispatcher

    # a function the kernels call without inlining compiles for the current device: none here
    numba.cuda.dispatcher.get_current_device = (
        lambda: SimpleNamespace(compute_capability=(9, 0)))
    from numba import cuda

    sys.path.insert(0, str(ROOT / "tests"))
    import test_gpu

    from impactsph.gpu import gpu_kernels
    from impactsph.physics.options import PassOptions

    ptxas = ptxas_path()
    print("| dim | kernel | registers | blocks of 128 a multiprocessor | stack B | spill B |")
    print("|---|---|---|---|---|---|")
    for dim in args.dims:
        types = test_gpu._kernel_argument_types(dim)
        if args.record_precision == "float32":
            from numba import types as nbt

            types["P"] = nbt.float32[::1, :]
        kernels = gpu_kernels(dim, False, -1,
                              PassOptions(record_precision=args.record_precision))
        items = [(name, kernels[i].py_func,
                  tuple(types[p] for p in inspect.signature(kernels[i].py_func).parameters))
                 for i, name in RATE_KERNELS.items()]
        for name in STEP_KERNELS:
            kernel, argtypes = test_gpu._step_kernel_types(name, dim)
            items.append((name, kernel.py_func, argtypes))
        for name, function, argtypes in items:
            ptx, _ = cuda.compile_ptx(function, argtypes, cc=(9, 0))
            r = ptxas_report(ptxas, ptx)
            blocks = blocks_a_multiprocessor(r["registers"])
            print(f"| {dim} | {name} | {r['registers']} | {blocks} | {r['stack']} | "
                  f"{r['spills']} |", flush=True)
            if name != "pair_kernel":
                continue
            for cap in args.caps:
                r = ptxas_report(ptxas, ptx, cap)
                blocks = blocks_a_multiprocessor(r["registers"])
                print(f"| {dim} | {name}, at most {cap} | {r['registers']} | {blocks} | "
                      f"{r['stack']} | {r['spills']} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
