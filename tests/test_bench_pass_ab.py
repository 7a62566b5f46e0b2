"""``benchmarks/bench_pass_ab.py`` compiles another tree's template beside this tree's passes
in one process: against this very tree it must find the pass, time both, and give the same
bits for every output the pass writes (a module loaded with the wrong options or models, or
inputs captured from another call, would not)."""

from __future__ import annotations

from pathlib import Path


def test_this_tree_against_itself_gives_the_same_bits(benchmark_script, tmp_path):
    script = benchmark_script("bench_pass_ab")
    tree = Path(__file__).resolve().parents[1]
    result = script.measure("bars", tree, ["pair_pass", "hourglass_pass"], 0, 2, tmp_path)
    assert result["particles"] == 202
    assert list(result["passes"]) == ["pair_pass"]  # the bars run no hourglass control
    timed = result["passes"]["pair_pass"]
    assert len(timed["here"]) == len(timed["other"]) == 2
    assert min(timed["here"] + timed["other"]) > 0.0
    # the rates it writes: density, acceleration, energy, heating, contact force, stress rate
    assert timed["written"] >= 5
    assert max(timed["differences"]) == 0.0


def test_the_stage_against_itself_gives_the_same_bits(benchmark_script, tmp_path):
    """The integrator's stage (its own module, the run's stage options), on the inputs of
    the run's next predictor stage, restored before each call: the same bits as the stage
    compiled from this tree's template again, for every array it writes."""
    script = benchmark_script("bench_pass_ab")
    tree = Path(__file__).resolve().parents[1]
    result = script.measure("bars", tree, ["stage"], 0, 2, tmp_path)
    timed = result["passes"]["stage"]
    # the module of the bars' stage options (no return map, no damage update, the linear
    # EOS), not the neighbour loops' module
    assert timed["module"].startswith("passes_1d_s_d_e0_")
    assert len(timed["here"]) == len(timed["other"]) == 2
    assert min(timed["here"] + timed["other"]) > 0.0
    # the start copy (position, velocity, density, energy, deviator, plastic work, material
    # state) and the state itself, advanced
    assert timed["written"] >= 8
    assert max(timed["differences"]) == 0.0
