"""Small runs on one thread and on two (issue 16's "serial path where threads cost more than
they give"): the built-in bars (202 particles, 1D), plates (400, 1D), rings (1,096, 2D, to 4
ms) and Taylor bar (1,407, 2D), each with ``compute.threads`` 1, 2 and "auto" (the governor's
trials choose the count while the run goes: :mod:`impactsph.threads`), best of two rounds of
the runs' own wall time, with the counts the last "auto" run's trials chose.

    .venv/bin/python benchmarks/bench_small.py
"""

from __future__ import annotations

from impactsph import Simulation, load_case

CASES = {"bars": [], "plates": [], "rings": ["time.end=4e-3"], "taylor": []}


def main() -> None:
    settings = (1, 2, "auto")
    for name, extra in CASES.items():
        best: dict[object, float] = {}
        n = 0
        chosen: list[object] = []
        for _round in range(2):
            for threads in settings:
                case = load_case(name, ["output.figures=false", f"compute.threads={threads}",
                                        *extra])
                sim = Simulation(case)
                sim.run()
                n = sim.state.n
                best[threads] = min(best.get(threads, float("inf")), sim.record.wall_seconds)
                if threads == "auto":
                    chosen = [t["chosen"] for t in sim.record.thread_trials]
        print(f"{name:8s} {n:6d} particles: 1 thread {best[1]:.3f} s, 2 threads {best[2]:.3f} s,"
              f" auto {best['auto']:.3f} s (trials chose {chosen}); two/one"
              f" {best[2] / best[1]:.2f}, auto/best {best['auto'] / min(best[1], best[2]):.2f}",
              flush=True)


if __name__ == "__main__":
    main()
