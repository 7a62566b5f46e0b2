"""``benchmarks/bench_split_loops.py`` times the pair pass with its first loop cut down to the
kinematic sums or to the force sums: each cut must still be Python, leave everything outside
that loop as it is, and remove exactly the other half's sums (a template whose lines no
longer match would otherwise time the whole pass against itself and report a split that
costs nothing)."""

from __future__ import annotations

import ast
from pathlib import Path

SOURCE = (Path(__file__).resolve().parents[1] / "src" / "impactsph" / "physics"
          / "passes.py").read_text()
#: a sum of each half, as the first loop accumulates it in 2D and 3D
KINEMATIC = ("L00 += velocity_gradient_pair", "L11 += velocity_gradient_pair",
             "L22 += velocity_gradient_pair")
FORCES = ("G0 += ws0", "G2 += ws2", "a0 += sa0", "a1 += sa1", "w0 += visc * d0",
          "de_v += ", "T00 += ", "T22 += ")


def _loop(source: str, script) -> str:
    start = source.index(script.LOOP_START)
    return source[start:source.index(script.LOOP_END)]


def test_each_cut_keeps_its_half_of_the_sums_and_nothing_else_changes(benchmark_script):
    script = benchmark_script("bench_split_loops")
    whole = _loop(SOURCE, script)
    assert all(s in whole for s in KINEMATIC + FORCES)  # the template the cuts were made for
    start = SOURCE.index(script.LOOP_START)
    for variant, kept, gone in (("kinematic", KINEMATIC, FORCES),
                                ("forces", FORCES[:5], KINEMATIC + FORCES[6:])):
        cut = script.variant_source(SOURCE, variant)
        ast.parse(cut)  # still Python (an emptied ``if`` would not be)
        loop = _loop(cut, script)
        assert all(s in loop for s in kept), variant
        assert not any(s in loop for s in gone), variant
        assert cut[:start] == SOURCE[:start]
        assert cut[start + len(loop):] == SOURCE[start + len(whole):]
