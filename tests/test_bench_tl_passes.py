"""``benchmarks/bench_tl_passes.py`` times the total-Lagrangian passes by wrapping the
module's functions that the solver calls: its timers must find both passes (a renamed or
bypassed function would leave a pass silently untimed), once per rate evaluation, and it must
leave the package as it found it."""

from __future__ import annotations

from impactsph.physics import total_lagrangian as tl


def test_both_passes_are_timed_each_evaluation_and_the_package_is_restored(benchmark_script):
    script = benchmark_script("bench_tl_passes")
    before = (tl.deformation_pass, tl.force_pass)
    result = script.measure(3, steps=4)
    assert (tl.deformation_pass, tl.force_pass) == before
    assert result["particles"] == 117  # 3 x 36 along the beam, and its clamp's 9
    assert result["calls_per_step"] == 2.0  # the midpoint step: two rate evaluations
    assert result["entries"] > 10 * result["particles"]
    for name in ("deformation_pass", "force_pass"):
        assert result[f"{name} best"] > 0.0
