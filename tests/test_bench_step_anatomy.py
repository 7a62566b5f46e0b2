"""``benchmarks/bench_step_anatomy.py`` times a run's parts by wrapping the run's own
functions: its table must add up, its timers must find the passes (a renamed function would
leave a part silently untimed), and it must leave the package as it found it."""

from __future__ import annotations

from impactsph import solver as solver_module
from impactsph.neighbours import NeighbourList


def test_the_parts_of_a_short_run_add_up_and_the_package_is_restored(benchmark_script):
    script = benchmark_script("bench_step_anatomy")
    before = (solver_module.fill_ghosts, solver_module.serial_rate_totals, NeighbourList.stale)
    result = script.anatomy("bars", ["time.end=2e-6"], threads=1)
    assert (solver_module.fill_ghosts, solver_module.serial_rate_totals,
            NeighbourList.stale) == before
    parts = {row["part"]: row for row in result["parts"]}
    assert result["steps"] > 10 and result["particles"] == 202
    # the midpoint step: two rate evaluations, each with its particle and pair passes, and
    # two stages of the update
    for name in ("pair_pass", "particle_pass", "stage (update, return map, walls, survey)",
                 "rate totals"):
        assert parts[name]["calls_per_step"] == 2.0, (name, parts[name])
        assert parts[name]["parent"] == "step"
    # a survey after each step and one before the first
    assert round(parts["survey"]["calls_per_step"] * result["steps"]) == result["steps"] + 1
    # each level's parts and its rest make up the level, and the rest is not negative
    for level in ("run (wall)", "step"):
        inner = sum(r["us_per_step"] for r in result["parts"] if r["parent"] == level)
        assert abs(inner - parts[level]["us_per_step"]) < 1e-6 * parts[level]["us_per_step"]
        assert parts[f"{level}: the rest (Python)"]["us_per_step"] >= 0.0
    assert parts["step"]["us_per_step"] < parts["run (wall)"]["us_per_step"]
    script.print_table(result)
