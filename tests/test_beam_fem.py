"""The plane-strain elasticity reference of the clamped beam (``validation/beam_fem.py``):
it converges, and it meets Timoshenko's beam theory where that theory becomes exact (a
slender beam), so the per-cent-level difference at the SPH beams' slenderness is the
theory's (docs/stabilisation.md, "The plate (nu = 0.4, L/H = 10)")."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent.parent / "validation"))
import beam  # noqa: E402
import beam_fem  # noqa: E402

pytest.importorskip("skfem")


@pytest.fixture
def beam_of():
    """``beam.set_beam`` for one test, the module's beam restored after it."""
    saved = beam.NU, beam.LENGTH
    yield beam.set_beam
    beam.NU, beam.LENGTH = saved


def test_the_period_converges_with_the_mesh(beam_of):
    """The plate (nu = 0.4, L = 10 H) at 2, 4, 8 elements through the depth: the period rises
    (approached from the stiff side) by steps that shrink at least twofold per halving
    (measured 0.25%, 0.084%: 2.9-fold; 16 and 32 elements: 0.031%, 0.011%; the clamped
    corners' stress singularity keeps the rate below the smooth one)."""
    beam_of(0.4, 10.0)
    p2, p4, p8 = (beam_fem.first_period(n) for n in (2, 4, 8))
    assert p2 < p4 < p8
    assert (p8 - p4) <= (p4 - p2) / 2
    assert (p8 - p4) / p8 < 1e-3


def test_a_slender_beam_is_timoshenkos(beam_of):
    """At L = 40 H the 2D solid's period is Timoshenko's to 0.1% (measured -0.06%), and the
    difference shrinks with H / L: at L = 12 H it is -0.18% (the clamped face holds the root
    section's warping, which the beam theory's clamp lets free)."""
    differences = {}
    for slenderness in (12.0, 40.0):
        beam_of(0.3, slenderness)
        differences[slenderness] = beam_fem.first_period(4) / beam.timoshenko_period() - 1.0
    assert abs(differences[40.0]) < 1e-3
    assert abs(differences[40.0]) < abs(differences[12.0]) / 2
    assert -3e-3 < differences[12.0] < 0.0
