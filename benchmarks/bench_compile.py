"""Compile time of the generated passes: numba's own inliner against the one without its
unread copies (:func:`impactsph.jitcache.inline_fresh_ir_in_place`), alternating in one
process, and whether the two give the same machine code.

    .venv/bin/python benchmarks/bench_compile.py [--case taylor] [--set KEY=VALUE ...]
        [--passes pair_pass stage] [--rounds 3]

The case's passes are compiled once (from the cache where it has them, else with the
in-place inliner) to learn their signatures; then each named pass is compiled again
``--rounds`` times with each inliner, from its Python function, without the cache (CPU
seconds, so that the other core's load counts less).  The machine code is compared with the
names' compile counters and addresses taken out (``jitcache.normalised_machine_code``).  One
pass's compilation includes the functions it calls that numba compiles apart.
"""

from __future__ import annotations

import argparse
import sys
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--case", default="taylor")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--passes", nargs="+", default=["pair_pass"])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()

    import numba as nb
    from numba.core import inline_closurecall

    from impactsph import jitcache
    from impactsph.loading import load_case
    from impactsph.simulation import Simulation

    if not jitcache.inline_fresh_ir_in_place():
        sys.exit("the in-place inliner does not apply to this numba "
                 "(or IMPACTSPH_NUMBA_INLINE_COPIES is set)")
    in_place = inline_closurecall.InlineWorker.inline_function
    numba_own = in_place.numba_original
    sim = Simulation(load_case(args.case, ["time.max_steps=1", *args.set]))
    sim.run()
    modules = [m for name, m in sys.modules.items() if name.startswith("impactsph_generated")]
    for pass_name in args.passes:
        used = [getattr(m, pass_name) for m in modules
                if getattr(getattr(m, pass_name, None), "signatures", None)]
        if not used:
            print(f"{pass_name}: not compiled by this case")
            continue
        dispatcher = used[0]
        signature = dispatcher.signatures[0]
        options = {k: v for k, v in dispatcher.targetoptions.items()
                   if k not in ("cache", "nopython")}
        seconds: dict[str, list[float]] = {"numba": [], "in place": []}
        code: dict[str, str] = {}
        try:
            for _ in range(args.rounds):
                for name, inline_function in (("numba", numba_own), ("in place", in_place)):
                    inline_closurecall.InlineWorker.inline_function = inline_function
                    fresh = nb.njit(**options)(dispatcher.py_func)
                    t0 = time.process_time()
                    fresh.compile(signature)
                    seconds[name].append(time.process_time() - t0)
                    code.setdefault(name, jitcache.normalised_machine_code(fresh, signature))
        finally:
            inline_closurecall.InlineWorker.inline_function = in_place
        same = "the same" if code["numba"] == code["in place"] else "DIFFERENT"
        ratio = min(seconds["in place"]) / min(seconds["numba"])
        print(f"{pass_name} ({dispatcher.py_func.__module__}): CPU s, numba's inliner "
              + " ".join(f"{t:.2f}" for t in seconds["numba"]) + "; in place "
              + " ".join(f"{t:.2f}" for t in seconds["in place"])
              + f"; best in place / best numba's {ratio:.2f}; machine code {same}", flush=True)


if __name__ == "__main__":
    main()
