"""A body's own kernel width (``bodies.N.h_over_dx``): each body's particles get ``h = width
* spacing``, a pair of particles of different h uses their mean (the sums stay symmetric, so
momentum and energy are kept), a body that names the kernel's width runs to the same bits as
one that names none, and the options that need one width for the run refuse a second."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from impactsph import preflight as pf
from impactsph.loading import load_case, validate_case
from impactsph.problem import build_problem
from impactsph.simulation import Simulation

sys.path.insert(0, str(Path(__file__).parent))
from test_preflight import block_case  # noqa: E402


def plate_and_disk(disk_width: float | None = None, plate_width: float | None = None,
                   end: float = 6e-6) -> dict:
    """A steel disk (12 particles across) at 400 m/s onto a plastic aluminium plate (40 x 6
    particles), plane strain, AV (1, 1): two bodies of different spacings and widths."""
    disk = {"name": "disk", "material": "steel", "velocity": [0.0, -400.0],
            "geometry": {"type": "disk", "centre": [0.0, 3.4e-3], "radius": 1.5e-3,
                         "spacing": 2.5e-4}}
    plate = {"name": "plate", "material": "aluminium", "velocity": [0.0, 0.0],
             "geometry": {"origin": [-6e-3, 0.0], "size": [12e-3, 1.8e-3],
                          "spacing": 3e-4}}
    if disk_width is not None:
        disk["h_over_dx"] = disk_width
    if plate_width is not None:
        plate["h_over_dx"] = plate_width
    return {"name": "widths", "dimension": 2,
            "materials": {"steel": {"model": "elastic", "density": 7850.0,
                                    "youngs_modulus": 2e11, "poisson_ratio": 0.3},
                          "aluminium": {"model": "elastic_plastic", "density": 2700.0,
                                        "youngs_modulus": 7e10, "poisson_ratio": 0.33,
                                        "yield_stress": 3e8}},
            "bodies": [disk, plate], "kernel": {"h_over_dx": 1.3},
            "time": {"end": end}, "output": {"figures": False}}


def test_each_body_gets_its_own_smoothing_length():
    case = validate_case(plate_and_disk(disk_width=1.6))
    state = build_problem(case).state
    disk, plate = state.body == 0, state.body == 1
    assert np.all(state.smoothing_length[disk] == pytest.approx(1.6 * 2.5e-4, rel=1e-12))
    assert np.all(state.smoothing_length[plate] == pytest.approx(1.3 * 3e-4, rel=1e-12))
    assert case.h_over_dx_of(0) == 1.6 and case.h_over_dx_of(1) == 1.3


def test_the_kernels_own_width_changes_nothing():
    """Naming the kernel's width for a body is the same run, to the bit."""
    runs = []
    for width in (None, 1.3):
        sim = Simulation(validate_case(plate_and_disk(plate_width=width, end=2e-6)))
        sim.run()
        runs.append(sim.state.arrays())
    for name, array in runs[0].items():
        np.testing.assert_array_equal(runs[1][name], array, err_msg=name)


@pytest.mark.parametrize("widths", [(1.6, None), (None, 1.6), (1.6, 1.0)],
                         ids=["wide disk", "wide plate", "wide disk, narrow plate"])
def test_bodies_of_different_widths_keep_momentum_and_energy(widths):
    """The disk strikes the plate (its tip is inside the plate's kernel reach from the start,
    so the bodies' pairs act for the whole run): the pair terms of particles of different h
    take ``h_ij = (h_i + h_j) / 2``, symmetric in the pair, so momentum is kept to round-off
    and the total energy to 1e-3 (measured: drifts of 5e-15, energy errors 1.9e-5 to 2.8e-5)."""
    sim = Simulation(validate_case(plate_and_disk(*widths)))
    p0 = sim.state.inertial_mass @ sim.state.velocity
    sim.run()
    s = sim.summary()
    plate = sim.state.body == 1
    assert np.abs(sim.state.velocity[plate, 1]).max() > 10.0  # the plate was struck
    assert s["momentum_drift"] <= 1e-12
    assert abs(s["total_energy_relative_error"]) <= 1e-3
    p1 = sim.state.inertial_mass @ sim.state.velocity
    np.testing.assert_allclose(p1, p0, atol=1e-12 * np.abs(p0).max())


def test_the_artificial_stress_needs_one_width():
    """Its reference spacing dx / h is one number for the run: a second width is refused in
    one line that names both fields."""
    with pytest.raises(Exception, match=r"bodies\.1\.h_over_dx = 1\.6 with "
                                        r"stabilisation\.artificial_stress = 0\.3"):
        load_case("rings", ["bodies.1.h_over_dx=1.6"])
    load_case("rings", ["bodies.1.h_over_dx=1.3"])  # the kernel's own: accepted


def test_preflight_counts_each_body_with_its_width():
    """The pre-flight's pairs per particle are each body's lattice count at its own width, and
    a body too narrow for its particles is warned about by its own field."""
    narrow = block_case(bodies__0__h_over_dx=0.1)
    found = pf.preflight(validate_case(narrow)).findings
    assert [(f.level, f.field) for f in found] == [("warning", "bodies.0.h_over_dx")]
    assert "bodies.0.h_over_dx = 0.1: too few neighbours" in found[0].line()
    case = validate_case(plate_and_disk(disk_width=1.6))
    counts = pf.count_particles(case)
    est = pf.estimate(case, counts)
    weights = np.array(counts) / sum(counts)
    expected = weights @ [pf.lattice_neighbours(pf.SUPPORT_RADIUS * w, 2) for w in (1.6, 1.3)]
    assert est.pairs_per_particle == pytest.approx(expected)
    assert pf.lattice_neighbours(pf.SUPPORT_RADIUS * 1.6, 2) > pf.lattice_neighbours(
        pf.SUPPORT_RADIUS * 1.3, 2)


def test_a_radius_per_pair_changes_nothing_but_the_lists_length(monkeypatch):
    """Where the bodies' smoothing lengths differ the list keeps each pair's own ``2 h_ij +
    skin`` (neighbours.py), not the widest body's reach in every row: the same run to
    round-off (the vectorised sums' grouping follows the rows' lengths), with fewer
    entries (measured: 6,672 against 7,876 at the end)."""
    from impactsph.solver import Solver

    def run() -> Simulation:
        sim = Simulation(validate_case(plate_and_disk(1.6, 1.0, end=3e-6)))
        assert sim.case.kernel.max_stretch == 1.0  # a fixed kernel: the widths alone differ
        sim.run()
        return sim

    short = run()
    monkeypatch.setattr(Solver, "_row_smoothing_lengths", lambda self, state: None)
    long = run()
    for name, array in long.state.arrays().items():
        if np.issubdtype(array.dtype, np.floating) and array.size:
            got = short.state.arrays()[name]
            assert np.abs(got - array).max() <= 1e-11 * max(np.abs(array).max(), 1e-300), name
    assert short.solver.neighbours.n_pairs < long.solver.neighbours.n_pairs
