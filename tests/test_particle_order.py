"""``compute.particle_order = "cells"``: the particles renumbered at t = 0 in the neighbour
list's order (:func:`impactsph.problem.cell_numbering`), each particle's results those of the
input order's run."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.errors import CaseError
from impactsph.loading import validate_case
from impactsph.output import load_run
from impactsph.runner import run_case

FIELDS = ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
          "plastic_work", "material_state", "mass", "smoothing_length", "body", "material",
          "clamped", "added_mass", "initial_position")


def block(dim: int, side: int, order: str) -> dict:
    """A steel block on a lattice (``side`` particles an axis), AV, no walls."""
    return {"name": f"block_{dim}d", "dimension": dim,
            "materials": {"steel": {"model": "elastic_plastic", "density": 7850.0,
                                    "youngs_modulus": 2e11, "poisson_ratio": 0.3,
                                    "yield_stress": 3e8}},
            "bodies": [{"name": "b", "material": "steel", "velocity": [0.0] * dim,
                        "geometry": {"origin": [0.0] * dim, "size": [side * 1e-3] * dim,
                                     "spacing": 1e-3}}],
            "viscosity": {"scheme": "av"},
            "stabilisation": {"gradient_correction": "none", "hourglass": 0.0},
            "time": {"end": 1e-6}, "output": {"figures": False},
            "compute": {"particle_order": order}}


def pair(case: dict) -> tuple[Simulation, Simulation]:
    """The case's simulations in the input order and renumbered, with the same random
    velocities given particle by particle (each particle its input row's)."""
    sims = []
    for order in ("input", "cells"):
        sim = Simulation(validate_case({**case, "compute": {"particle_order": order}}))
        rng = np.random.default_rng(7)
        v = rng.normal(0.0, 1.0, size=sim.state.velocity.shape)
        index = sim.problem.input_index
        sim.state.velocity[:] = v if index is None else v[index]
        sims.append(sim)
    return sims[0], sims[1]


@pytest.mark.parametrize("dim,side", [(2, 24), (3, 9)])
def test_the_first_list_is_in_particle_order_and_the_rates_are_the_same_to_the_bit(dim, side):
    given, renumbered = pair(block(dim, side, "input"))
    index = renumbered.problem.input_index
    n = given.state.n
    # a permutation, which the lattice's row-major numbering is not already
    assert sorted(index) == list(range(n)) and not np.array_equal(index, np.arange(n))
    assert not np.array_equal(given.solver.neighbours.order[:n], np.arange(n))
    np.testing.assert_array_equal(renumbered.solver.neighbours.order[:n], np.arange(n))
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(renumbered.state, name),
                                      getattr(given.state, name)[index], err_msg=name)
    compared = 0
    for a, b in zip(given.solver.rates(given.state), renumbered.solver.rates(renumbered.state),
                    strict=True):
        if a.shape[0]:  # (the hourglass control's rates: no rows without it)
            np.testing.assert_array_equal(b, a[index])
            compared += 1
    assert compared == 4  # dv, drho, de, dS


@pytest.mark.parametrize("name,overrides", [
    ("taylor", ["time.max_steps=120"]),   # a wall (ghosts), plasticity, AC
    ("rings", ["time.max_steps=120"]),    # two bodies, which stay apart in the numbering
    # clamped columns, a tip mass as added inertia, a probe and a gauge
    ("cantilever", ["time.max_steps=120", 'bodies.0.tip_mass.carried_as="added_inertia"',
                    'output.probes=[{name = "tip", body = "beam", position = [0.3, 0.0]}]',
                    'output.gauges=[{name = "root", body = "beam", position = [0.01, 3e-3]}]']),
])
def test_a_renumbered_run_is_the_input_orders_to_round_off(name, overrides):
    """Later lists' rows may hold a cell's particles in another order (the grid moves with
    the bodies), so a pair loop adds them in another order: the same run to round-off (at
    most 2.1e-14 of a field's scale found, the Taylor bar's stress; the cantilever's to the
    bit)."""
    runs = {}
    for order in ("input", "cells"):
        case = load_case(name, [*overrides, "output.figures=false",
                                f"compute.particle_order={order!r}"])
        sim = Simulation(case)
        sim.run()
        runs[order] = sim
    given, renumbered = runs["input"], runs["cells"]
    index = renumbered.problem.input_index
    assert renumbered.state.step == given.state.step == 120
    # each body's particles stay together, in the bodies' order
    np.testing.assert_array_equal(renumbered.state.body, given.state.body)
    for field in ("mass", "clamped", "added_mass", "initial_position", "material"):
        np.testing.assert_array_equal(getattr(renumbered.state, field),
                                      getattr(given.state, field)[index], err_msg=field)
    scale = {"position": np.abs(given.state.initial_position).max(),
             "velocity": np.abs(given.state.velocity).max(),
             "density": given.state.density.max(),
             "deviatoric_stress": np.abs(given.state.deviatoric_stress).max()}
    for field, size in scale.items():
        difference = np.abs(getattr(renumbered.state, field) - getattr(given.state, field)[index])
        assert difference.max() <= 1e-12 * size, (field, difference.max(), size)
    # the probes and gauges follow the same material points
    followed = {**given.problem.probes, **given.problem.gauges}
    assert followed.keys() == {**renumbered.problem.probes, **renumbered.problem.gauges}.keys()
    for label, i in followed.items():
        j = {**renumbered.problem.probes, **renumbered.problem.gauges}[label]
        assert index[j] == i, label
    if name == "cantilever":
        assert len(followed) == 2 and given.state.added_mass.any()
        # the summaries name each one's number, and as placed
        summary = renumbered.summary()
        assert summary["probes"]["tip"]["input_index"] == given.problem.probes["tip"]
        assert "input_index" not in given.summary()["probes"]["tip"]
        from impactsph.gauges import gauge_summary

        root = gauge_summary(renumbered)["root"]
        assert root["input_index"] == given.problem.gauges["root"]
        assert root["initial_position"] == gauge_summary(given)["root"]["initial_position"]
    assert given.state.kinetic_energy() == pytest.approx(renumbered.state.kinetic_energy(),
                                                         rel=1e-9)


def test_the_snapshots_carry_each_particles_input_number(tmp_path):
    case = load_case("taylor", ["time.end=2e-6", "output.snapshot_times=[1e-6]",
                                "output.figures=false", "output.vtk_interval=1e-6",
                                'compute.particle_order="cells"'])
    run_case(case, tmp_path)
    run = load_run(tmp_path)
    (snapshot,) = run["snapshots"]
    index = snapshot["input_index"]
    assert sorted(index) == list(range(index.size))
    # the input numbers order the particles as the bodies placed them: row by row
    x0 = snapshot["initial_position"][np.argsort(index)]
    given = Simulation(load_case("taylor", ["output.figures=false"])).state.initial_position
    np.testing.assert_array_equal(x0, given)
    vtu = sorted((tmp_path / "vtk").glob("*.vtu"))
    assert vtu and "input_index" in vtu[-1].read_bytes().decode("latin-1")
    assert "numbered in their first neighbour list's order" in (tmp_path / "run.log").read_text()


def test_input_order_snapshots_have_no_input_numbers():
    sim = Simulation(load_case("bars", ["output.figures=false"]))
    assert sim.problem.input_index is None
    assert "input_index" not in sim._snapshot_fields()


def test_a_bad_particle_order_is_refused_naming_the_field():
    with pytest.raises(CaseError, match=r"compute.particle_order = 'morton': Input should "
                                        r"be 'auto', 'input' or 'cells'"):
        load_case("bars", ['compute.particle_order="morton"'])


def test_auto_renumbers_2d_runs_from_renumber_from_particles(monkeypatch):
    from impactsph import problem as problem_module

    def renumbered(case: dict) -> bool:
        return Simulation(validate_case(case)).problem.input_index is not None

    auto = block(2, 24, "auto")  # 576 particles
    assert validate_case(block(2, 4, "input")).compute.particle_order == "input"
    assert load_case("bars").compute.particle_order == "auto"  # the default
    assert not renumbered(auto)
    monkeypatch.setattr(problem_module, "RENUMBER_FROM", 576)
    assert renumbered(auto)
    assert not renumbered(block(2, 24, "input"))
    assert not renumbered(block(3, 9, "auto"))  # 729 particles: 3D gained nothing
    assert not renumbered({**auto, "formulation": "total_lagrangian"})  # not measured
    monkeypatch.setattr(problem_module, "RENUMBER_FROM", 577)
    assert not renumbered(auto)


def test_the_estimate_says_how_a_large_2d_run_is_numbered():
    from impactsph import preflight as pf
    from impactsph.problem import RENUMBER_FROM

    big = RENUMBER_FROM

    def line(order: str, n: int, dim: int = 2, **more) -> str:
        estimate = pf.estimate(validate_case({**block(dim, 10, order), **more}), [n])
        assert (estimate.order_line in estimate.lines()) == bool(estimate.order_line)
        return estimate.order_line

    assert line("auto", big).startswith(f"particle order: the {big:,} particles renumbered")
    assert line("input", big).startswith("note: compute.particle_order = 'input' numbers the")
    assert line("cells", big) == ""  # asked for: nothing to say
    for order in ("auto", "input"):
        assert line(order, big - 1) == ""
        assert line(order, big, dim=3) == ""
        assert line(order, big, formulation="total_lagrangian") == ""
