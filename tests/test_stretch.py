"""A smoothing length that follows the local stretch (``kernel.max_stretch``,
:mod:`impactsph.physics.stretch`): the neighbourhood's deformation gradient is exact for a
homogeneous deformation, at free surfaces too; a rigid motion leaves ``h`` alone; the pair
sums stay conservative; the option is refused where it does not apply."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from impactsph.config import AUTO_MAX_STRETCH
from impactsph.loading import CaseError, load_case
from impactsph.neighbours import NeighbourList
from impactsph.physics.stretch import principal_stretches, stretched_smoothing_length
from impactsph.simulation import Simulation, _cpu_only

H_OVER_DX = 1.3


def _lattice(dim: int, n: int = 7) -> np.ndarray:
    axes = [np.arange(n, dtype=float)] * dim
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim) * 1e-3


def _stretches(X: np.ndarray, F: np.ndarray, body: np.ndarray | None = None,
               ghosts: np.ndarray | None = None) -> np.ndarray:
    """Each particle's largest principal stretch after ``x = F X + c`` (``ghosts``: rows
    appended after the particles, which the list holds and the estimate must skip)."""
    x = X @ F.T + 0.37e-3
    n = X.shape[0]
    rows = x if ghosts is None else np.vstack([x, ghosts])
    rows0 = X if ghosts is None else np.vstack([X, ghosts])
    h = np.full(rows.shape[0], H_OVER_DX * 1e-3 * max(1.0, np.linalg.norm(F, 2)))
    lst = NeighbourList.build(rows, 2.0 * float(h.max()), 0.0)
    body = np.zeros(rows.shape[0], np.int32) if body is None else body
    return principal_stretches(lst.order, lst.offsets, lst.indices, rows, rows0, body, h, n)


@pytest.mark.parametrize("dim, F", [
    (1, np.array([[1.7]])),
    (2, np.array([[1.5, 0.2], [0.1, 0.7]])),
    (3, np.array([[1.3, 0.2, -0.1], [0.05, 0.8, 0.3], [0.0, -0.2, 1.1]])),
])
def test_a_homogeneous_deformation_gives_its_stretch_everywhere(dim, F):
    """(ST-2) is a least-squares fit of a linear map, exact whatever the neighbours: the
    interior, the faces, the edges and the corners of a block all give F's largest singular
    value."""
    stretch = _stretches(_lattice(dim), F)
    expected = np.linalg.svd(F, compute_uv=False)[0]
    np.testing.assert_allclose(stretch, expected, rtol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_rigid_rotation_stretches_nothing(dim):
    angle = 0.7
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]]) if dim == 2 else np.array([[c, -s, 0], [s, c, 0],
                                                               [0, 0, 1]])
    np.testing.assert_allclose(_stretches(_lattice(dim), R), 1.0, rtol=1e-12)


def test_each_body_and_no_wall_ghost_counts():
    """Two blocks side by side, one stretched and one not, give each its own stretch: the
    neighbours of another body are left out, and so are a rigid wall's ghosts (body -1)
    placed among them."""
    X = _lattice(2)
    n = X.shape[0]
    both = np.vstack([X, X + [7e-3, 0.0]])
    body = np.repeat(np.array([0, 1], np.int32), n)
    F = np.array([[1.4, 0.0], [0.0, 1.0]])
    x = both.copy()
    x[:n] = X @ F.T  # the first block stretched along x; the second one rigid
    ghosts = both[:10] + [0.3e-3, 0.4e-3]
    rows = np.vstack([x, ghosts])
    h = np.full(rows.shape[0], H_OVER_DX * 1.4e-3)
    lst = NeighbourList.build(rows, 2.0 * float(h.max()), 0.0)
    all_body = np.concatenate([body, np.full(10, -1, np.int32)])
    got = principal_stretches(lst.order, lst.offsets, lst.indices, rows,
                              np.vstack([both, ghosts]), all_body, h, 2 * n)
    np.testing.assert_allclose(got[:n], 1.4, rtol=1e-12)
    np.testing.assert_allclose(got[n:], 1.0, rtol=1e-12)


def test_a_symmetry_plane_gives_the_whole_models_stretch():
    """A half model's neighbourhoods by a symmetry plane include its mirror images (now and
    at t = 0), so that its stretches are the whole model's under a deformation symmetric
    about the plane and far from homogeneous (to round-off); a rigid wall's ghosts count
    for nothing."""
    from impactsph.boundaries import FREE_SLIP, SYMMETRY
    from impactsph.physics.stretch import mirrored_rows

    u = _lattice(2, 10) / 1e-3 - [4.5, 2.0]  # columns at x = -4.5 .. 4.5 mm

    def deformed(u):
        return np.stack([u[:, 0] * (1.0 + 0.02 * u[:, 0] ** 2),
                         u[:, 1] + 0.03 * u[:, 0] ** 2 - 0.01 * u[:, 1] ** 2], axis=1) * 1e-3

    X_whole, x_whole = u * 1e-3, deformed(u)
    h = H_OVER_DX * 1.5e-3
    whole_list = NeighbourList.build(x_whole, 2.0 * h, 0.0)
    n_whole = X_whole.shape[0]
    whole = principal_stretches(whole_list.order, whole_list.offsets, whole_list.indices,
                                x_whole, X_whole, np.zeros(n_whole, np.int64),
                                np.full(n_whole, h), n_whole)
    right = u[:, 0] > 0.0
    X, x = X_whole[right], x_whole[right]
    n = X.shape[0]
    points, normals = np.zeros((2, 2)), np.array([[1.0, 0.0], [0.0, 1.0]])
    for kind, expected in ((SYMMETRY, whole[right]), (FREE_SLIP, None)):
        kinds = np.array([kind, FREE_SLIP], np.int8)
        src, wall = np.arange(n), np.zeros(n, np.int64)  # every particle's mirror image
        rows = mirrored_rows(x, X, np.zeros(n, np.int64), np.full(n, h), src, wall, points,
                             normals, kinds)
        np.testing.assert_allclose(rows[0][n:, 0], -x[:, 0], rtol=0, atol=1e-18)
        lst = NeighbourList.build(rows[0], 2.0 * h, 0.0)
        half = principal_stretches(lst.order, lst.offsets, lst.indices, *rows, n)
        if expected is not None:
            np.testing.assert_allclose(half, expected, rtol=1e-12)
            assert half.max() > 1.05  # the deformation does stretch the block
        else:  # a wall's images: the half's own neighbours only, as with no ghosts
            own = NeighbourList.build(x, 2.0 * h, 0.0)
            alone = principal_stretches(own.order, own.offsets, own.indices, x, X,
                                        np.zeros(n, np.int64), np.full(n, h), n)
            np.testing.assert_allclose(half, alone, rtol=1e-12)
            assert np.abs(half - whole[right]).max() > 1e-3  # and the plane's row differs


def test_the_smoothing_length_is_clamped_and_kept_where_undetermined():
    """``h = h0 clamp(lambda, 1, max_stretch)``: a stretch beyond the limit gives the limit, a
    uniform compression gives h0, and a neighbourhood that cannot fix F (two particles: a
    singular moment in 2D) keeps h0."""
    X = _lattice(2)
    h0 = np.full(X.shape[0], H_OVER_DX * 1e-3)
    for F, factor in ((np.diag([1.5, 1.0]), 1.23), (np.diag([0.8, 0.8]), 1.0),
                      (np.diag([1.1, 0.9]), 1.1)):
        x = X @ F.T
        lst = NeighbourList.build(x, 2.0 * float(h0.max()) * 1.5, 0.0)
        h = stretched_smoothing_length(lst, x, X, np.zeros(X.shape[0], np.int32), h0, 1.23,
                                       h0)
        np.testing.assert_allclose(h, factor * h0, rtol=1e-12)
    pair = np.array([[0.0, 0.0], [1e-3, 0.0]])
    lst = NeighbourList.build(pair, 3e-3, 0.0)
    h = stretched_smoothing_length(lst, 1.5 * pair, pair, np.zeros(2, np.int32),
                                   np.full(2, 1.3e-3), 1.23, np.full(2, 1.3e-3))
    np.testing.assert_array_equal(h, 1.3e-3)


def test_a_run_keeps_momentum_and_energy_and_bounds_h():
    """The paper's Taylor bar to 20 us with AC's pairwise form, the walls and a kernel that
    follows the stretch: the pair sums stay symmetric (mean h_ij), so momentum is kept to
    round-off and energy to the time step's error; h grows where the foot spreads, by at most
    the limit, and nowhere falls below h0."""
    sim = Simulation(load_case("taylor", [
        'viscosity.scheme="ac_pairwise"', 'contact.traction="normal_stress"',
        "contact.wall_layer=0.25", "kernel.max_stretch=1.25", "time.end=20e-6",
        "output.figures=false"]))
    h0 = sim.state.smoothing_length.copy()
    sim.run()
    summary = sim.summary()
    assert summary["momentum_drift"] <= 1e-12
    assert summary["total_energy_relative_error"] <= 1e-3
    assert summary["wall_constraint_events"] == 0
    ratio = sim.state.smoothing_length / h0
    # the measures count in the nominal kernel, h at t = 0, not the grown one
    np.testing.assert_array_equal(sim.h_reference, h0)
    assert ratio.min() >= 1.0 and ratio.max() <= 1.25 + 1e-12
    low = sim.state.position[:, 1] < sim.state.position[:, 1].min() + 1e-3  # the foot
    assert ratio[low].max() == pytest.approx(1.25)
    high = sim.state.position[:, 1] > sim.state.position[:, 1].max() - 5e-3  # the tail
    assert ratio[high].max() < 1.02


def test_one_length_at_t0_is_held_once_and_gives_a_copys_bits():
    """With the stretch, a run whose particles all start with one smoothing length holds it
    as a read-only view of that number (8 bytes a particle less) and gives the bits that a
    copy per particle gives, its h grown where the foot spreads; lengths that differ are
    copied."""
    from impactsph.problem import build_problem

    case = load_case("taylor", ["kernel.max_stretch=1.25", "time.end=3e-6",
                                "output.figures=false"])
    sim = Simulation(case)
    h0 = sim.state.smoothing_length.copy()
    assert sim.h_reference.strides == (0,) and not sim.h_reference.flags.writeable
    assert sim.solver._h_reference is sim.h_reference
    copied = Simulation(case)
    copied.h_reference = copied.solver._h_reference = np.array(copied.h_reference)
    for run in (sim, copied):
        run.run()
    assert (sim.state.smoothing_length > h0).any()  # the stretch has grown some h
    for name, value in sim.state.arrays().items():
        assert np.array_equal(value, copied.state.arrays()[name]), name
    np.testing.assert_array_equal(sim.h_reference, h0)
    problem = build_problem(case)
    problem.state.smoothing_length[0] *= 1.01
    uneven = Simulation(case, problem=problem)
    assert uneven.h_reference.flags.writeable
    np.testing.assert_array_equal(uneven.h_reference, problem.state.smoothing_length)


@pytest.mark.parametrize("extra, field", [
    (["stabilisation.artificial_stress=0.3"], "stabilisation.artificial_stress"),
    (['formulation="total_lagrangian"', 'viscosity.scheme="av"'], "total_lagrangian"),
])
def test_what_the_stretch_refuses(extra, field):
    with pytest.raises(CaseError) as caught:
        load_case("taylor", ["kernel.max_stretch=1.2", *extra])
    message = str(caught.value)
    assert "kernel.max_stretch = 1.2" in message and field in message
    assert "\n" not in message.strip()


def test_the_stretch_runs_on_the_gpu_with_the_state_there_only():
    """The stretch is set on the device at its rebuilds (tests/test_gpu_step.py), but with
    the state on the host (``compute.resident = false``) the run goes to the CPU."""
    assert _cpu_only(load_case("taylor", ["kernel.max_stretch=1.2"])) is None
    why = _cpu_only(load_case("taylor", ["kernel.max_stretch=1.2", "compute.resident=false"]))
    assert why is not None and "kernel.max_stretch" in why and "resident = false" in why
    assert _cpu_only(load_case("taylor", [])) is None


@pytest.mark.parametrize("value", [0.9, 5.0])
def test_the_limit_is_checked(value):
    with pytest.raises(CaseError) as caught:
        load_case("taylor", [f"kernel.max_stretch={value}"])
    assert "kernel.max_stretch" in str(caught.value)


def test_preflight_sizes_the_list_for_the_grown_kernel():
    """The list's reach grows with the largest h, so pre-flight's memory estimate counts the
    neighbours within ``max_stretch`` times the reach: about 1.23^2 as many in 2D."""
    from impactsph.preflight import estimate

    plain, stretched = (load_case("taylor", [f"kernel.max_stretch={s}"]) for s in (1.0, 1.23))
    a, b = (estimate(c, [c.bodies[0].geometry.count[0] * c.bodies[0].geometry.count[1]])
            for c in (plain, stretched))
    assert b.neighbours / a.neighbours == pytest.approx(1.23 ** 2, rel=0.15)
    assert b.memory > a.memory
    assert b.pairs_per_particle == a.pairs_per_particle  # the support at t = 0


sys.path.insert(0, str(Path(__file__).parent.parent / "validation"))
from resolution import DEFAULTS  # noqa: E402

JC_DAMAGE = ['materials.iron.damage="johnson_cook_damage"',
             "materials.iron.johnson_cook_damage={d1=0.05, d2=3.44, d3=-2.12}"]


@pytest.mark.parametrize("source, extra, expected", [
    ("taylor", DEFAULTS, AUTO_MAX_STRETCH),                    # a plastic bar of one's own
    ("cantilever", DEFAULTS, AUTO_MAX_STRETCH),
    ("taylor3d", [], AUTO_MAX_STRETCH),
    ("taylor", [], 1.0),                                      # the paper's fixed h
    ("bars", ['kernel.max_stretch="auto"'], 1.0),              # nothing yields
    ("taylor", [*DEFAULTS, "kernel.h_over_dx=1.2"], 1.0),      # tore the beam at 1.2 dx
    ("taylor", [*DEFAULTS, "bodies.0.h_over_dx=1.25"], 1.0),   # one body is enough
    ("taylor", [*DEFAULTS, *JC_DAMAGE], 1.0),                  # cracks not measured
    ("taylor", [*DEFAULTS, "stabilisation.artificial_stress=0.3"], 1.0),
    ("taylor", [*DEFAULTS, 'compute.device="gpu"'], AUTO_MAX_STRETCH),  # the device's step
    ("taylor", [*DEFAULTS, 'compute.device="gpu"', "compute.resident=false"], 1.0),  # host path
    ("taylor_axisymmetric", ['kernel.max_stretch="auto"'], 1.0),
])
def test_auto_gives_the_stretch_where_it_was_measured(source, extra, expected):
    """``kernel.max_stretch = "auto"`` (the default) resolves, when the case is validated, to
    1.23 where it was measured to make the answers converge (a plastic body, updated-
    Lagrangian, plane strain or 3D, at least 1.3 dx, no damage, no artificial stress, on the
    CPU or on the GPU with the state there), to 1 everywhere else; the case recorded with a
    run holds the number."""
    case = load_case(source, extra)
    assert case.kernel.max_stretch == expected
    assert case.model_dump()["kernel"]["max_stretch"] == expected


@pytest.mark.parametrize("source", ["taylor", "cantilever"])
def test_the_defaults_scheme_is_a_case_of_ones_own(source):
    """``validation/resolution.py``'s "defaults" scheme gives the paper's example the tables
    a case of one's own leaves out: the same resolved case as deleting them."""
    from impactsph.loading import read_case_dict, validate_case

    raw = read_case_dict(source)
    for table in ("viscosity", "stabilisation", "contact", "kernel"):
        raw.pop(table, None)
    bare = validate_case(raw).model_dump()
    named = load_case(source, DEFAULTS).model_dump()
    for table in ("viscosity", "stabilisation", "contact", "kernel"):
        assert named[table] == bare[table], table


def test_a_radius_per_pair_changes_nothing_but_the_lists_length(monkeypatch):
    """With the stretch the list keeps each pair's own ``2 h_ij + skin``, not the largest h's
    reach for every row: the entries it leaves out are beyond every pass's support, so the run
    is the same to round-off (the vectorised sums' grouping follows the rows' lengths), with
    fewer entries (Taylor bar, the defaults, 12 us)."""
    from impactsph.solver import Solver

    overrides = [*DEFAULTS, "time.end=12e-6", "output.figures=false"]

    def run() -> Simulation:
        sim = Simulation(load_case("taylor", overrides))
        sim.run()
        return sim

    short = run()
    monkeypatch.setattr(Solver, "_row_smoothing_lengths", lambda self, state: None)
    long = run()
    assert short.state.smoothing_length.max() > short.state.smoothing_length.min()  # grown
    for name in ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
                 "smoothing_length"):
        a, b = getattr(short.state, name), getattr(long.state, name)
        assert np.abs(a - b).max() <= 1e-11 * np.abs(b).max(), name
    assert short.solver.neighbours.n_pairs < 0.9 * long.solver.neighbours.n_pairs


def test_positions_of_four_columns_are_refused_by_name():
    """The stretch is compiled for 1, 2 and 3 dimensions; other widths get a one-line error
    before any kernel is compiled."""
    x = np.zeros((3, 4))
    no = np.zeros(0, dtype=np.int32)
    with pytest.raises(ValueError, match="x has 4 columns"):
        principal_stretches(no, np.zeros(1, dtype=np.int32), no, x, x, np.zeros(3, np.int64),
                            np.ones(3), 3)
