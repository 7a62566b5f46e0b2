"""The integrator's stage in one pass (:func:`impactsph.physics.passes.stage`): the start
copy, the update and return map, the walls' constraint and the survey of the result, particle
by particle, give what the start copy alone (``MidpointIntegrator._keep``), the update alone,
the walls' pass (:meth:`impactsph.boundaries.Walls.enforce`) and the survey's own pass
(:func:`impactsph.integrate._survey_kernel`) give one after another:
the state to the bit, the survey to the bit, the walls' impulse to round-off (its chunks'
sums are added in chunk order, the walls' pass added particle by particle)."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.integrate import run_stage, stage_options
from impactsph.materials import EOS_KIND
from impactsph.models.columns import THICKNESS_RATIO
from impactsph.physics.rates import compiled_passes

FIELDS = ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
          "plastic_work", "material_state", "hourglass_acceleration")


def _pushed_through_the_wall(overrides: list[str]) -> Simulation:
    """The Taylor bar with the particles of its first two rows put behind the anvil's plane,
    so that the walls' constraint has work to do."""
    sim = Simulation(load_case("taylor", ["output.figures=false", *overrides]))
    s, walls = sim.state, sim.walls
    d = (s.position - walls.points[0]) @ walls.normals[0]
    near = d < 2.5 * float(np.median(np.diff(np.unique(s.position[:, 1]))))
    s.position[near] -= np.outer(d[near] + 1e-4, walls.normals[0])
    assert near.sum() > 50
    return sim


@pytest.mark.parametrize("overrides", [
    [],
    ['two_dimensional="plane_stress"'],  # the material density is rho over the thickness
    ["stabilisation.hourglass=1.0"],  # the hourglass control's signal speed
], ids=["plane_strain", "plane_stress", "hourglass"])
def test_the_stage_in_one_pass_is_the_stage_then_the_walls_then_the_survey(overrides):
    sim = _pushed_through_the_wall(overrides)
    s, it = sim.state, sim.integrator
    if "plane_stress" in str(overrides):  # a plate thinned already: rho / 0.9 sets the CFL
        s.material_state[:, THICKNESS_RATIO] = 0.9
    rates = [np.array(r) for r in sim.solver.rates(s)]
    dt = 0.3 * it.survey_kernel(s.n, s.position, s.velocity, s.material_density,
                                s.specific_energy, s.deviatoric_stress, s.mass, s.inertial_mass,
                                s.smoothing_length, s.material, it.table, 1.0,
                                it.hourglass, *it.planes)[0]
    it._inertia = s.inertial_mass
    # apart: the step's start copy (numpy's), the stage alone (no walls, no survey), the
    # walls' pass, the survey's pass
    apart = s.copy()
    start = it._keep(apart, "_apart")
    dim = apart.dim
    stage = compiled_passes(dim, options=it.stage_options).stage
    run_stage(
        stage, it.stage_options.parallel, it.n_active, dt, False, start.position,
        start.velocity, start.density, start.specific_energy, start.deviatoric_stress,
        start.plastic_work, start.material_state, start.hourglass_acceleration,
        start.velocity, *rates, apart.clamped, apart.material, it.table, apart.smoothing_length,
        *(getattr(apart, f) for f in FIELDS), np.zeros((0, dim)), np.zeros((0, dim)),
        it._inertia, np.zeros_like(it._wall_parts), False, apart.mass,
        it.hourglass, np.zeros_like(it._survey_parts), np.zeros_like(it._bad_of))
    moved, impulse = sim.walls.enforce(apart.position, apart.velocity, it._inertia)
    expected = it.survey_kernel(apart.n, apart.position, apart.velocity,
                                apart.material_density, apart.specific_energy,
                                apart.deviatoric_stress, apart.mass, apart.inertial_mass,
                                apart.smoothing_length, apart.material, it.table, 1.0,
                                it.hourglass, *it.planes)
    # in one pass, the start copy made by the stage itself
    kept = {f: getattr(s, f).copy() for f in FIELDS}
    together = it._save_start(s, copy=False)
    count = it._stage(s, dt, together, rates, 1.0, True, keep=True,
                      survey=True)
    assert moved > 50 and count == moved == it.constraint_events
    np.testing.assert_allclose(it.constraint_impulse, impulse, rtol=1e-13, atol=0.0)
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(s, f), getattr(apart, f), err_msg=f)
        if f == "material_state":  # the columns a stage changes (material_state_kept)
            np.testing.assert_array_equal(together.material_state,
                                          kept[f][:, :it.material_state_kept], err_msg=f)
        elif f != "deviatoric_stress":  # kept as its six components
            np.testing.assert_array_equal(getattr(together, f), kept[f], err_msg=f)
    np.testing.assert_array_equal(together.deviatoric_stress, start.deviatoric_stress)
    survey = it.take_survey()
    # -1: the constraint left no particle behind the wall, and nothing is bad
    assert survey[0] == expected[0] and survey[2] == expected[2] == -1
    np.testing.assert_array_equal(survey[1], expected[1])
    assert it.take_survey() is None  # handed out once


def test_the_stages_survey_finds_the_first_bad_value_and_needs_no_thread_count():
    """A non-finite value is reported as the survey's own pass reports it (the first particle
    of the first bad field), and the survey's bits do not depend on the number of threads."""
    sim = Simulation(load_case("taylor", ["output.figures=false"]))
    s, it = sim.state, sim.integrator
    rates = [np.array(r) for r in sim.solver.rates(s)]
    s.specific_energy[[900, 31]] = np.nan
    s.velocity[1200, 1] = np.inf
    it._inertia = s.inertial_mass
    results = []
    threads = numba.get_num_threads()
    try:
        for n_threads in sorted({1, threads}):
            numba.set_num_threads(n_threads)
            state = s.copy()
            start = it._save_start(state, copy=False)
            it._stage(state, 1e-9, start, rates, 1.0, True, keep=True,
                      survey=True)
            results.append((state, it.take_survey()))
    finally:
        numba.set_num_threads(threads)
    state, (step, sums, bad) = results[0]
    # the infinite velocity moves its particle to infinity: the position (field 0) comes
    # before the other fields and the NaN energies (field 3) of lower particles
    assert bad == 0 * s.n + 1200
    expected = it.survey_kernel(state.n, state.position, state.velocity,
                                state.material_density, state.specific_energy,
                                state.deviatoric_stress, state.mass, state.inertial_mass,
                                state.smoothing_length, state.material, it.table, 1.0, 0.0,
                                *it.planes)
    assert (step, bad) == (expected[0], expected[2])
    np.testing.assert_array_equal(sums, expected[1])
    for other, (o_step, o_sums, o_bad) in results[1:]:
        assert (o_step, o_bad) == (step, bad)
        np.testing.assert_array_equal(o_sums, sums)
        for f in FIELDS:
            np.testing.assert_array_equal(getattr(other, f), getattr(state, f), err_msg=f)


def test_a_run_surveyed_by_its_stages_is_a_run_surveyed_apart():
    """A run whose steps are surveyed by their last stage, and the same run with a callback
    that reads the state (so that every step is surveyed again by the survey's own pass,
    whose CFL step the next step takes), end in the same state and history, to the bit."""
    case = load_case("taylor", ["output.figures=false", "time.end=3e-6"])
    runs = []
    for callback in (None, lambda sim: sim.state):
        sim = Simulation(case)
        sim.run(callback=callback)
        runs.append(sim)
    a, b = runs
    assert a.step == b.step > 50
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(a.state, f), getattr(b.state, f), err_msg=f)
    assert a.record.history == b.record.history


def test_a_particle_behind_a_wall_is_the_surveys_last_kind_of_bad_value():
    """The survey reports a particle behind a wall (or symmetry plane) as bad, after every
    bad field (``6 n + i``, as the GPU's survey does), and the run stops before its next
    step saying so."""
    from impactsph.errors import SimulationError

    sim = Simulation(load_case("taylor", ["output.figures=false"]))
    s, it = sim.state, sim.integrator
    d = (s.position - sim.walls.points[0]) @ sim.walls.normals[0]
    behind = [int(np.argsort(d)[5]), int(np.argsort(d)[2])]
    s.position[behind] -= np.outer(d[behind] + 1e-5, sim.walls.normals[0])

    def survey():
        return it.survey_kernel(s.n, s.position, s.velocity, s.material_density,
                                s.specific_energy, s.deviatoric_stress, s.mass, s.inertial_mass,
                                s.smoothing_length, s.material, it.table, 1.0, 0.0,
                                *it.planes)[2]

    assert survey() == 6 * s.n + min(behind)
    s.density[max(behind) + 1] = -1.0  # a bad field comes first, whichever the particle
    assert survey() == 5 * s.n + max(behind) + 1
    s.density[max(behind) + 1] = s.density[0]
    with pytest.raises(SimulationError, match="particle crossed a wall") as info:
        sim.run()
    assert info.value.particle == min(behind) and info.value.step == 0


def test_the_stage_in_shares_is_the_stage_in_one(monkeypatch):
    """The stage runs in shares of its chunks on numba's threads
    (:func:`impactsph.integrate.run_stage`, a chunked pass): in four shares (whatever this
    worker's thread count) the state, the walls' count and impulse, and the survey are the
    one share's to the bit, the chunks' sums folded in chunk order after the shares."""
    import impactsph.integrate as integrate

    results = []
    for shares in (1, 4):
        monkeypatch.setattr(integrate, "threads_for", lambda rows, chunk, threaded, k=shares: k)
        sim = _pushed_through_the_wall([])
        s, it = sim.state, sim.integrator
        rates = [np.array(r) for r in sim.solver.rates(s)]
        it._inertia = s.inertial_mass
        start = it._save_start(s, copy=False)
        count = it._stage(s, 2e-9, start, rates, 1.0, True, keep=True,
                          survey=True)
        results.append((s, count, it.constraint_impulse.copy(), it.take_survey()))
    (one, count, impulse, survey), (four, count4, impulse4, survey4) = results
    assert count == count4 > 50 and integrate.survey_chunks(one.n) >= 4
    np.testing.assert_array_equal(impulse4, impulse)
    assert survey4[0] == survey[0] and survey4[2] == survey[2] == -1
    np.testing.assert_array_equal(survey4[1], survey[1])
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(four, f), getattr(one, f), err_msg=f)


def _taylor_of(tmp_path, library: str):
    """The Taylor bar with its iron replaced by the library's ``library`` material."""
    from importlib.resources import files

    text = (files("impactsph") / "cases" / "taylor.toml").read_text()
    start = text.index("[materials.iron]")
    end = text.index("\n[", text.index("[materials.iron.mie_gruneisen]") + 1)
    text = text[:start] + f'[materials.iron]\nlibrary = "{library}"\n' + text[end:]
    path = tmp_path / f"taylor_{library}.toml"
    path.write_text(text)
    return load_case(path, ["time.max_steps=60", "output.figures=false"])


def test_the_stage_names_only_its_runs_models(tmp_path):
    """The integrator's stage comes from a module whose dispatches name only the strength
    models with a return map and the damage models with an update that its materials use
    (``PassOptions.strength_kinds``, ``damage_kinds``): none for the elastic bars, von Mises
    for the Taylor bar, Johnson-Cook's hardening and damage for a copper bar; and that stage
    gives the run the stage of every registered model gives it, to the bit."""
    from dataclasses import replace

    from impactsph.models import DAMAGE, EOS, STRENGTH

    def names(registry, kinds):
        return [list(registry)[k].name for k in kinds]

    bars = Simulation(load_case("bars", ["output.figures=false"])).integrator.stage_options
    assert (bars.strength_kinds, bars.damage_kinds) == ((), ())
    assert names(EOS, bars.eos_kinds) == ["linear"]
    taylor = Simulation(load_case("taylor", ["output.figures=false"])).integrator.stage_options
    assert names(STRENGTH, taylor.strength_kinds) == ["elastic_plastic"]
    assert taylor.damage_kinds == ()
    assert names(EOS, taylor.eos_kinds) == ["mie_gruneisen"]
    case = _taylor_of(tmp_path, "ofhc_copper")
    lean, full = Simulation(case), Simulation(case)
    options = lean.integrator.stage_options
    assert names(STRENGTH, options.strength_kinds) == ["johnson_cook"]
    assert names(DAMAGE, options.damage_kinds) == ["johnson_cook_damage"]
    module = compiled_passes(2, options=options)
    every = compiled_passes(2, options=replace(options, strength_kinds=None, damage_kinds=None,
                                               eos_kinds=None))
    assert module is not every and module.__name__ != every.__name__
    source = open(module.__file__).read()
    dispatch = source[source.index("def strength_return"):source.index("def damage_update")]
    assert dispatch.count("return _strength_") == 1
    dispatch = source[source.index("def eos_pressure"):source.index("def strength_return")]
    assert dispatch.count("return _eos_") == 1
    full.integrator._stage_pass = every.stage
    lean.run()
    full.run()
    for field in ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
                  "plastic_work", "material_state"):
        assert np.array_equal(getattr(lean.state, field), getattr(full.state, field)), field
    assert lean.state.plastic_work.max() > 0.0


def test_a_stage_of_two_equations_of_state_gives_each_material_its_own(tmp_path):
    """The bars as OFHC copper, the right bar with the linear EOS, the left with
    Mie-Gruneisen's: the stage's module names those two (``eos_kinds``; the second the
    dispatch's fallback), and its ``eos_pressure`` gives each material's row its own EOS's
    pressure, to the bit, compressed and stretched.  (The dispatch alone is compiled: a run
    with this stage against the module of every EOS would compile two stages more, some 15 s
    of the suite; the copper Taylor bar above runs one EOS's stage against every EOS's.)"""
    from importlib.resources import files

    from impactsph.materials import BULK, RHO0, TableLayout
    from impactsph.models import EOS
    from impactsph.problem import build_problem

    text = (files("impactsph") / "cases" / "bars.toml").read_text()
    start = text.index("[materials.steel]")
    end = text.index("[[bodies]]")
    text = (text[:start] + '[materials.steel]\nlibrary = "ofhc_copper"\n\n'
            '[materials.linear_copper]\nlibrary = "ofhc_copper"\neos = "linear"\n\n'
            + text[end:])
    text = text.replace('name = "right"\nmaterial = "steel"',
                        'name = "right"\nmaterial = "linear_copper"')
    path = tmp_path / "bars_two_eos.toml"
    path.write_text(text)
    case = load_case(path, ["output.figures=false", 'analysis="none"'])
    table = build_problem(case).table
    options = stage_options(table)
    assert [list(EOS)[k].name for k in options.eos_kinds] == ["linear", "mie_gruneisen"]
    module = compiled_passes(1, options=options)
    source = open(module.__file__).read()
    dispatch = source[source.index("def eos_pressure"):source.index("def strength_return")]
    assert dispatch.count("return _eos_") == 2
    eos_params = TableLayout.registered().eos_params
    pressures = []
    for row in table:
        kind = int(row[EOS_KIND])
        for rho, e in ((1.05 * row[RHO0], 2e4), (0.97 * row[RHO0], 0.0)):
            own = list(EOS)[kind].pressure(rho, e, row[RHO0], row[BULK], row[eos_params:])
            assert module.eos_pressure(kind, rho, e, row[RHO0], row[BULK],
                                       row[eos_params:]) == own
            pressures.append(own)
    assert len(set(pressures)) == len(pressures)  # the two EOS differ at every point


@pytest.mark.parametrize(("field", "kinds"), [("strength_kinds", (3, 2)),
                                               ("strength_kinds", (99,)),
                                               ("damage_kinds", (0, 0)),
                                               ("eos_kinds", ()),
                                               ("eos_kinds", (1, 0))])
def test_the_stage_models_are_checked(field, kinds):
    from impactsph.physics.options import PassOptions

    with pytest.raises(ValueError, match=field):
        PassOptions(**{field: kinds})


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_a_chunks_rows_are_finite_exactly_where_no_particle_has_a_bad_field(dim):
    """:func:`impactsph.physics.survey.rows_finite`, the survey's one vectorised check of a
    chunk, is true exactly where :func:`~impactsph.physics.survey.bad_field` finds no bad
    field in any of the chunk's particles: a non-finite value planted in each field and each
    component in turn (an infinity, a NaN), a density of zero or below, and arrays that are
    not C-contiguous (a copy's rows are checked)."""
    from impactsph.physics.survey import bad_field, rows_finite

    @numba.njit
    def bad_fields(lo, hi, x, v, rho, e, S):
        return [bad_field(i, x, v, rho, e, S) for i in range(lo, hi)]

    rng = np.random.default_rng(8)
    n = 40
    fields = {"x": rng.normal(size=(n, dim)), "v": rng.normal(size=(n, dim)),
              "rho": rng.uniform(1.0, 2.0, n), "e": rng.normal(size=n),
              "S": rng.normal(size=(n, 3, 3))}
    plants = [(name, index) for name, a in fields.items()
              for index in np.ndindex(a.shape[1:])]
    cases = 0
    for (name, index), bad in zip(plants * 2, [np.inf] * len(plants) + [np.nan] * len(plants),
                                  strict=True):
        for i in (0, 17, n - 1):
            a = {k: f.copy() for k, f in fields.items()}
            a[name][(i, *index)] = -bad if cases % 2 else bad
            for lo, hi in ((0, n), (0, i), (i, i + 1), (min(i + 1, n - 1), n)):
                args = (a["x"], a["v"], a["rho"], a["e"], a["S"])
                found = any(f >= 0 for f in bad_fields(lo, hi, *args))
                assert found == (lo <= i < hi), (name, index, i, lo, hi)
                assert rows_finite(lo, hi, *args) is not found, (name, index, i, lo, hi)
            cases += 1
    for density in (0.0, -1.0):
        a = {k: f.copy() for k, f in fields.items()}
        a["rho"][5] = density
        args = (a["x"], a["v"], a["rho"], a["e"], a["S"])
        assert not rows_finite(0, n, *args) and rows_finite(6, n, *args)
        assert bad_fields(5, 6, *args) == [5]
    # arrays that are not C-contiguous: Fortran order, and every other row of a larger one
    fortran = {k: np.asfortranarray(f) for k, f in fields.items()}
    strided = {k: np.repeat(f, 2, axis=0)[::2] for k, f in fields.items()}
    for a in (fortran, strided):
        args = (a["x"], a["v"], a["rho"], a["e"], a["S"])
        assert rows_finite(0, n, *args) and rows_finite(3, 30, *args)
        a["S"][20, 2, 1] = np.nan
        assert not rows_finite(0, n, *args) and rows_finite(21, n, *args)
        assert not rows_finite(20, 21, *args) and bad_fields(20, 21, *args) == [4]


def test_the_survey_in_shares_is_the_survey_in_one(monkeypatch):
    """The survey on its own (:func:`impactsph.integrate._survey_kernel`, a chunked pass run
    in shares of its chunks) gives the one share's step, sums and first bad value to the bit
    in four shares: the chunks' partial sums are folded in chunk order after the shares, and
    the first bad value is the lowest code of any share, not the first share's."""
    import impactsph.integrate as integrate

    sim = _pushed_through_the_wall([])
    s, it = sim.state, sim.integrator
    assert integrate.survey_chunks(s.n) >= 4
    s.velocity[:, 0] += np.linspace(-3.0, 5.0, s.n)  # sums with something to add up
    results = []
    for bad_rows in ([], [s.n - 7, 900]):  # both bad rows in the last two shares' chunks
        planted = s.copy()
        planted.specific_energy[bad_rows] = np.nan
        for shares in (1, 4):
            monkeypatch.setattr(integrate, "threads_for",
                                lambda rows, chunk, threaded, k=shares: k)
            results.append(it.survey_kernel(
                planted.n, planted.position, planted.velocity, planted.material_density,
                planted.specific_energy, planted.deviatoric_stress, planted.mass,
                planted.inertial_mass, planted.smoothing_length, planted.material, it.table, 0.3,
                it.hourglass, *it.planes))
    (step, sums, bad), four, (_, _, bad_planted), four_planted = results
    assert bad == 6 * s.n + int(np.flatnonzero(
        (s.position - sim.walls.points[0]) @ sim.walls.normals[0] < 0)[0])  # behind the wall
    assert bad_planted == 3 * s.n + 900  # the energy (field 3) before "behind a wall" (6)
    assert four[0] == step and four[2] == bad
    np.testing.assert_array_equal(four[1], sums)
    assert four_planted[2] == bad_planted
    assert step > 0.0 and sums[0] > 0.0
