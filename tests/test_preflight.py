"""The checks before a run (impactsph.preflight): particle counts and estimates, the memory
refusal, one warning per bad set-up (each triggered by a small case and checked by its text),
no warning for a clean case, the compile notice, and the kinetic energy left at the end."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph import preflight as pf
from impactsph.cli import app
from impactsph.errors import CaseError
from impactsph.loading import load_case, validate_case
from impactsph.problem import build_problem

runner = CliRunner()


def block_case(**changes) -> dict:
    """A 2D steel block, 20 x 10 particles, falling at 100 m/s; no wall."""
    case = {"name": "pre", "dimension": 2,
            "materials": {"steel": {"model": "elastic", "density": 7850.0,
                                    "youngs_modulus": 2e11}},
            "bodies": [{"name": "a", "material": "steel", "velocity": [0.0, -100.0],
                        "geometry": {"origin": [0.0, 0.0], "size": [0.01, 0.005],
                                     "spacing": 5e-4}}],
            "time": {"end": 1e-5}}
    for path, value in changes.items():
        node = case
        keys = path.split("__")
        for key in keys[:-1]:
            node = node[int(key)] if key.isdecimal() else node.setdefault(key, {})
        node[keys[-1]] = value
    return case


def findings(case: dict) -> list[pf.Finding]:
    return pf.preflight(validate_case(case)).findings


def only(case: dict, level: str, field: str) -> str:
    """The one finding of ``case``: it must be of ``level`` and name ``field``."""
    found = findings(case)
    assert [(f.level, f.field) for f in found] == [(level, field)], [f.line() for f in found]
    line = found[0].line()
    assert line.startswith(f"{level}: {field}") and "\n" not in line
    return line


def test_clean_block_has_no_finding():
    assert findings(block_case()) == []


def test_builtin_bars_is_clean():
    report = pf.preflight(load_case("bars"))
    assert report.findings == []
    res = runner.invoke(app, ["check", "bars"])
    assert res.exit_code == 0, res.output
    assert "warning" not in res.output and "error" not in res.output


def test_check_prints_counts_and_estimates_for_taylor():
    res = runner.invoke(app, ["check", "taylor"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0] == "taylor: valid (2D plane strain, 1 body)"
    assert lines[1].startswith("scheme: AC ")  # tests/test_cli.py checks the line
    assert lines[2] == "particles: bar 1,407; total 1,407 (+ 63 wall ghosts)"
    assert lines[3].startswith("estimated memory: ") and " MB" in lines[3]
    assert lines[4].startswith("estimated run time: ") and "an estimate" in lines[4]
    assert "steps of dt = 2.7e-08 s by eq 26" in lines[4]
    est = pf.preflight(load_case("taylor")).estimate
    assert est.total == 1407 and est.runs == 2  # the reference AV run too
    assert 1800 < est.steps < 1900  # the run takes 1837
    assert 17 < est.pairs_per_particle < 21


def test_memory_refusal_names_the_field():
    if (pf.available_memory() or 0) > 1e12:
        pytest.skip("this machine has more memory than 4e8 particles need")
    args = ["--set", "bodies.0.geometry.count=[20000, 20000]"]
    for command in (["check", "taylor"], ["run", "taylor", "--quiet", "--out", "/nonexistent"]):
        res = runner.invoke(app, [*command, *args])
        assert res.exit_code == 2, res.output
        lines = res.output.strip().splitlines()
        assert len(lines) == 1, res.output
        assert lines[0].startswith("error: bodies.0.geometry.count = [20000, 20000]: the run "
                                   "needs about "), lines[0]
        assert "400,000,000 particles" in lines[0] and "available" in lines[0]


def test_memory_refusal_for_a_long_history_names_time_end():
    case = validate_case(block_case(time__end=0.5))
    est = pf.estimate(case, pf.count_particles(case))
    est.available = int(0.5 * est.memory)
    refusal = pf.memory_check(case, est)
    assert refusal is not None and refusal.field == "time.end"
    assert "history" in refusal.message and "output.history_every" in refusal.message
    assert "did you mean" not in refusal.message  # 0.5 s: long, but not a likely unit slip


def test_memory_refusal_of_an_end_time_in_the_wrong_unit_says_so():
    """``time.end = 20`` (20 ms meant) is refused for its history's memory before the
    magnitude warning could be shown: the refusal carries the unit hint itself."""
    case = validate_case(block_case(time__end=20.0))
    est = pf.estimate(case, pf.count_particles(case))
    est.available = int(0.5 * est.memory)
    refusal = pf.memory_check(case, est)
    assert refusal is not None and refusal.field == "time.end"
    assert refusal.message.startswith("time.end = 20.0: the run needs about ")
    assert refusal.message.endswith(f"this machine has {pf._bytes(est.available)} "
                                    f"available; more than 1 s of simulated time for an "
                                    f"impact (micro- to milliseconds); did you mean 20 ms = "
                                    f"0.02 or 20 us = 2e-05?")


def test_particle_counts_match_the_placed_particles(tmp_path):
    cases = [block_case(),
             block_case(bodies__0__geometry={"type": "disk", "centre": [0.0, 0.0],
                                             "radius": 0.0031, "spacing": 2e-4}),
             {**block_case(dimension=3, bodies__0__velocity=[0.0, 0.0, -1.0]),
              "bodies": [{"name": "c", "material": "steel", "velocity": [0.0, 0.0, 0.0],
                          "geometry": {"type": "cylinder", "centre": [0.0, 0.0, 0.0],
                                       "radius": 0.002, "length": 0.0031, "axis": "y",
                                       "spacing": 5e-4}}]},
             {**block_case(dimension=3, bodies__0__velocity=[0.0, 0.0, -1.0]),
              "bodies": [{"name": "c", "material": "steel", "velocity": [0.0, 0.0, 0.0],
                          "geometry": {"type": "cylinder", "centre": [0.0, 0.0, 0.0],
                                       "radius": 0.0031, "length": 0.0031, "axis": "z",
                                       "spacing": 5e-4, "arrangement": "rings"}}]},
             block_case(bodies__0__geometry={"origin": [0.0, 0.0], "size": [0.0101, 0.003],
                                             "spacing": [5e-4, 3e-4]})]
    for case in cases:
        c = validate_case(case)
        assert pf.count_particles(c) == [build_problem(c).state.n]


# -- one warning per bad set-up ---------------------------------------------------------------

def two_bodies(origin_b: list[float]) -> dict:
    case = block_case()
    b = copy.deepcopy(case["bodies"][0])
    b.update(name="b", velocity=[0.0, 0.0])
    b["geometry"]["origin"] = origin_b
    case["bodies"].append(b)
    return case


def test_overlapping_bodies():
    line = only(two_bodies([0.005, 0.004]), "warning", "bodies.1.geometry")
    assert "body 'b' overlaps body 'a' (bodies.0): 20 particle pairs closer than 0.5 spacing" \
        in line
    assert findings(two_bodies([0.0, 0.005])) == []  # touching, one spacing apart: fine


def particle_file(tmp_path, x: np.ndarray) -> dict:
    np.savez(tmp_path / "cloud.npz", position=x)
    return block_case(bodies__0__geometry={"type": "file", "path": str(tmp_path / "cloud.npz"),
                                           "spacing": 1e-3})


def lattice(n: int = 10) -> np.ndarray:
    return np.stack(np.meshgrid(np.arange(n), np.arange(n)), -1).reshape(-1, 2) * 1e-3


def test_duplicate_positions_in_a_particle_file(tmp_path):
    x = lattice()
    line = only(particle_file(tmp_path, np.concatenate([x, x[[37]]])), "warning",
                "bodies.0.geometry.path")
    assert "1 pair of particles of body 'a' share a position (first: particle 100 at " \
           "[0.007, 0.003])" in line


def test_isolated_particle_in_a_particle_file(tmp_path):
    line = only(particle_file(tmp_path, np.concatenate([lattice(), [[0.05, 0.05]]])),
                "warning", "bodies.0.geometry.path")
    assert "1 particle of body 'a' has no neighbour within the kernel support 2h at t = 0 " \
           "(first: particle 100 at [0.05, 0.05])" in line


def test_particle_file_written_in_mm(tmp_path):
    case = particle_file(tmp_path, lattice() * 2e3)  # 0 to 18 "m", a spacing of 2 "m"
    case["bodies"][0]["geometry"]["spacing"] = 2.0
    lines = {f.field: f.line() for f in findings(case)}
    assert set(lines) == {"bodies.0.geometry.path", "bodies.0.geometry.spacing"}, lines
    assert "the particles span 18 m, more than 1 m for an impact specimen; were the " \
           "coordinates written in mm? (then 0.018 m)" in lines["bodies.0.geometry.path"]
    assert "did you mean mm = 0.002 m?" in lines["bodies.0.geometry.spacing"]


def test_no_neighbours_at_a_small_h_over_dx():
    line = only(block_case(kernel={"h_over_dx": 0.1}), "warning", "kernel.h_over_dx")
    assert "kernel.h_over_dx = 0.1: too few neighbours" in line
    assert "'a' 0" in line and "needs about 8 in 2D" in line


def test_a_body_one_particle_thick_has_too_few_neighbours():
    line = only(block_case(bodies__0__geometry={"origin": [0.0, 0.0], "size": [0.01, 5e-4],
                                                "spacing": 5e-4}), "warning", "bodies.0.geometry")
    assert "no particle of body 'a' has more than 4 neighbours" in line


def test_one_particle_body():
    case = block_case()
    case["bodies"].append({"name": "dot", "material": "steel", "velocity": [0.0, 0.0],
                           "geometry": {"origin": [0.05, 0.05], "size": [5e-4, 5e-4],
                                        "spacing": 5e-4}})
    line = only(case, "warning", "bodies.1.geometry")
    assert "body 'dot' has one particle" in line


def test_body_behind_a_wall_is_refused():
    case = block_case(boundaries=[{"point": [0.0, 0.002], "normal": [0.0, 1.0]}])
    line = only(case, "error", "boundaries.0")
    assert "80 of the 200 particles of body 'a' (bodies.0) start behind the wall" in line
    with pytest.raises(CaseError, match=r"^boundaries\.0: 80 of the 200"):
        pf.check_case(validate_case(case))
    # on the wall's right side: no finding
    assert findings(block_case(boundaries=[{"point": [0.0, 0.0], "normal": [0.0, 1.0]}])) == []


@pytest.mark.parametrize(("changes", "field", "text"), [
    ({"materials__steel__model": "elastic_plastic", "materials__steel__yield_stress": 792.0},
     "materials.steel.yield_stress", "792.0: implausibly low yield stress (SI, Pa: under "
                                     "1e+05); did you mean 792 MPa = 7.92e+08?"),
    ({"materials__steel__density": 7.85}, "materials.steel.density",
     "did you mean 7.85 g/cm^3 = 7.85e+03?"),
    ({"materials__steel__density": 2e5}, "materials.steel.density",
     "implausible density for a solid"),
    ({"materials__steel__youngs_modulus": 208.0}, "materials.steel.youngs_modulus",
     "did you mean 208 GPa = 2.08e+11?"),
    ({"materials__steel__youngs_modulus": 3e12}, "materials.steel.youngs_modulus",
     "implausible Young's modulus (SI: 1e+05 to 2e+12 Pa)"),
    ({"bodies__0__geometry": {"origin": [0.0, 0.0], "size": [2.0, 0.5], "spacing": 0.05}},
     "bodies.0.geometry.size", "2 m is large for an impact specimen (over 1 m); did you mean "
                               "mm = 0.002 m?"),
    ({"bodies__0__geometry": {"origin": [0.0, 0.0], "size": [5e-6, 5e-6], "spacing": 5e-7},
      "time__end": 1e-9}, "bodies.0.geometry.size", "5e-06 m is implausibly small"),
    ({"bodies__0__velocity": [0.0, -3e4]}, "bodies.0.velocity",
     "a speed of 3e+04 m/s is beyond hypervelocity impact"),
    ({"time__end": 2.0, "time__max_steps": 10}, "time.end",
     "more than 1 s of simulated time for an impact"),
    ({"time__end": 0.5, "output": {"history_every": 1_000_000}}, "time.end",
     "steps of dt = 3.79e-08 s (eq 26), more than 1e+07"),
    ({"viscosity": {"limiter": "minmod"}}, "viscosity.limiter",
     "viscosity.limiter = 'minmod': not a parameter of scheme 'av' (alpha1, alpha2, "
     "epsilon); it has no effect"),
    ({"viscosity": {"scheme": "ac", "decay": 0.2}}, "viscosity.decay",
     "not a parameter of scheme 'ac'"),
    # a case shortened below its snapshot times (--set time.end) takes none of them
    ({"output": {"snapshot_times": [5e-6, 2e-5]}}, "output.snapshot_times",
     "output.snapshot_times = [5e-06, 2e-05]: 1 of 2 after time.end = 1e-05: no snapshot is "
     "taken then, nor any figure drawn from one"),
    # a material's field or table of a model it does not use
    ({"materials__steel__yield_stress": 3.5e8}, "materials.steel.yield_stress",
     "materials.steel.yield_stress = 350000000.0: a parameter of model = 'elastic_plastic', "
     "and this material's model is 'elastic'; it has no effect"),
    ({"materials__steel__mie_gruneisen": {"sound_speed": 4569.0, "slope": 1.49,
                                          "gamma": 2.17}},
     "materials.steel.mie_gruneisen", "materials.steel.mie_gruneisen: the table of eos = "
     "'mie_gruneisen', and this material's eos is 'linear'; it has no effect"),
])
def test_implausible_magnitudes(changes, field, text):
    line = only(block_case(**changes), "warning", field)
    assert text in line, line


def test_parameters_in_use_and_defaults_are_not_warned_about():
    """A yield stress with a model that yields, a Mie-Gruneisen table with that eos, AC
    with the alpha1 and alpha2 of the AV case it was switched from (the README's
    ``impactsph run bars --set viscosity.scheme=ac``): no finding; nor for any built-in
    case."""
    assert findings(block_case(viscosity={"scheme": "ac", "alpha1": 0.3, "alpha2": 0.3})) == []
    assert findings(block_case(materials__steel__model="elastic_plastic",
                               materials__steel__yield_stress=3.5e8)) == []
    assert findings(block_case(materials__steel__eos="mie_gruneisen",
                               materials__steel__mie_gruneisen={
                                   "sound_speed": 4569.0, "slope": 1.49, "gamma": 2.17})) == []
    # a library material with a model of its own left out (docs/case-files.md's example):
    # the library's tables of it are not the case's to remove
    copper = block_case()
    copper["materials"] = {"steel": {"library": "ofhc_copper", "damage": "none",
                                     "johnson_cook": {"yield_stress": 95.0e6}}}
    assert findings(copper) == [], [f.line() for f in findings(copper)]
    for name in ("bars", "plates", "rings", "taylor", "taylor3d", "taylor_axisymmetric",
                 "cantilever"):
        case = load_case(name)
        assert pf.unused_material_fields(case) == [], name
        assert pf.unused_viscosity_fields(case) == [], name


def test_warnings_do_not_stop_check():
    res = runner.invoke(app, ["check", "taylor", "--set", "materials.iron.yield_stress=792"])
    assert res.exit_code == 0, res.output
    assert "warning: materials.iron.yield_stress = 792.0: " in res.output


# -- during and after a run ------------------------------------------------------------------

def plastic_block_on_a_wall(end: float) -> dict:
    return block_case(materials__steel__model="elastic_plastic",
                      materials__steel__yield_stress=6e8, time__end=end,
                      boundaries=[{"point": [0.0, 0.0], "normal": [0.0, 1.0]}],
                      output={"figures": False})


def test_kinetic_energy_left_at_the_end():
    plastic = validate_case(plastic_block_on_a_wall(1e-5))
    summary = {"kinetic_energy_ratio_final": 0.3, "t_end": 1e-5}
    lines = pf.after_run(plastic, summary, echo=lambda line: None)
    assert lines == ["warning: time.end = 1e-05: 30% of the initial kinetic energy remains at "
                     "the end time: the impact may not be over; consider a longer time.end"]
    assert pf.after_run(plastic, {**summary, "kinetic_energy_ratio_final": 0.01}) == []
    # stopped by time.max_steps before the end time: not the end time's fault
    assert pf.after_run(plastic, {**summary, "t_end": 5e-6}) == []
    # elastic bodies rebound and ring: they keep their kinetic energy
    assert pf.after_run(validate_case(block_case()), summary) == []
    # a plastic body in free flight keeps it too; a clamped one does not
    free = plastic_block_on_a_wall(1e-5)
    del free["boundaries"]
    assert pf.after_run(validate_case(free), summary) == []
    free["bodies"][0]["clamped"] = {"origin": [0.0, 0.0], "size": [0.001, 0.001]}
    assert len(pf.after_run(validate_case(free), summary, echo=lambda line: None)) == 1


def test_no_kinetic_energy_warning_where_the_problem_ends_during_the_impact():
    """The paper's plates (Example 2) end at 1.2 us with a third of their kinetic energy, by
    design: their wave profiles are measured while the plates are in contact.  The same
    plastic plates without that analysis are warned about."""
    plates = load_case("plates")
    summary = {"kinetic_energy_ratio_final": 0.335, "t_end": plates.time.end}
    assert plates.analysis == "plates"
    assert pf.after_run(plates, summary, echo=lambda line: None) == []
    other = load_case("plates", ['analysis="none"'])
    assert len(pf.after_run(other, summary, echo=lambda line: None)) == 1


def test_run_prints_the_estimate_and_the_kinetic_energy_warning(tmp_path):
    toml = tmp_path / "plastic.toml"
    toml.write_text(_toml(plastic_block_on_a_wall(2e-6)))
    res = runner.invoke(app, ["run", str(toml), "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "particles: a 200; total 200 (+ 60 wall ghosts)" in res.output
    assert "estimated run time: " in res.output
    assert "% of the initial kinetic energy remains at the end time" in res.output
    # the kernels are cached now: no notice
    assert pf.compile_notice(validate_case(plastic_block_on_a_wall(2e-6))) is None


def _toml(case: dict) -> str:
    """A case dict as TOML (the few shapes block_case makes)."""
    def value(v) -> str:
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, bool):
            return "true" if v else "false"
        return json.dumps(v)

    return "\n".join(f"{k} = {value(v)}" for k, v in case.items()) + "\n"


def test_compile_notice_for_kernels_not_yet_compiled():
    # options no run uses: their generated passes have no machine code on disk
    case = validate_case(block_case(stabilisation={"artificial_stress": 0.3,
                                                   "artificial_stress_exponent": 3.1415}))
    assert pf.kernels_cached(case) is False
    assert pf.compile_notice(case) == ("compiling the SPH kernels for this machine (first run "
                                       "only, ~1 min)")


def test_pair_rate_is_kept_for_later_estimates(tmp_path, monkeypatch):
    monkeypatch.setattr(pf, "_pair_rate_path", lambda: tmp_path / "rates.json")
    assert pf.pair_rate("cpu", 2) == (pf.DEFAULT_PAIR_RATE, pf.pair_rate("cpu", 2)[1])
    summary = {"pair_evaluations": 4e8, "wall_seconds": 10.0, "n_steps": 1000,
               "device": "cpu", "dimension": 2, "n_particles": 5000}
    pf.record_pair_rate(summary, "big")
    rate, source = pf.pair_rate("cpu", 2)
    assert rate == pytest.approx(4e8 / (10.0 - 1000 * pf.STEP_SECONDS))
    assert "measured on this machine by a run of 'big'" in source
    # the time numba spent compiling or loading code in the run is not the pairs' time (a
    # short first run's 1.7 s of compiling made the Taylor bar's estimate 1.5 min, 2026-12-07)
    pf.record_pair_rate({**summary, "wall_seconds": 30.0, "compile_seconds": 20.0}, "first")
    assert pf.pair_rate("cpu", 2)[0] == pytest.approx(rate)
    pf.record_pair_rate(summary, "big")
    pf.record_pair_rate({**summary, "pair_evaluations": 1e5, "wall_seconds": 1.0}, "small")
    assert pf.pair_rate("cpu", 2)[0] == rate  # too few pairs to be a rate
    pf.record_pair_rate({**summary, "wall_seconds": 100.0,
                         "thread_changes": [[1.0, 1.0, 1]]}, "loaded")
    assert pf.pair_rate("cpu", 2)[0] == rate  # it gave up cores: a loaded machine's rate
    # through after_run: not from a restarted run (pairs since t = 0, wall time since the
    # restart)
    # a 3D case with no 3D rate of its own borrows the 2D one, and says so; a 1D one does not
    rate3, source3 = pf.pair_rate("cpu", 3)
    assert rate3 == rate
    assert source3.endswith("in 2D, " + source.split(", ")[-1][:-1] + "; no 3D run has "
                            "measured one)"), source3
    assert pf.pair_rate("cpu", 1)[0] == pf.DEFAULT_PAIR_RATE
    case, summary3 = validate_case(block_case(name="rates")), {
        **summary, "dimension": 3, "wall_seconds": 20.0}
    pf.after_run(case, summary3, restarted=True, echo=lambda line: None)
    assert pf.pair_rate("cpu", 3) == (rate3, source3)
    pf.after_run(case, summary3, echo=lambda line: None)
    rate3, source3 = pf.pair_rate("cpu", 3)
    assert rate3 == pytest.approx(4e8 / (20.0 - 1000 * pf.STEP_SECONDS))
    assert "'rates', " in source3 and "2D" not in source3
    assert pf.pair_rate("cpu", 2)[0] == rate  # each dimension its own, once it has one


def test_a_kernel_that_follows_the_stretch_keeps_its_own_rate(tmp_path, monkeypatch):
    """A run whose kernel follows the stretch costs more a pair: its rate is kept apart, and
    a case of the other kind that has none of its own borrows it with STRETCH_COST."""
    monkeypatch.setattr(pf, "_pair_rate_path", lambda: tmp_path / "rates.json")
    summary = {"pair_evaluations": 4e8, "wall_seconds": 10.0, "n_steps": 1000,
               "device": "cpu", "dimension": 2, "n_particles": 5000}
    fixed = 4e8 / (10.0 - 1000 * pf.STEP_SECONDS)
    pf.record_pair_rate(summary, "fixed")
    assert pf.pair_rate("cpu", 2)[0] == pytest.approx(fixed)
    rate, source = pf.pair_rate("cpu", 2, stretch=True)
    assert rate == pytest.approx(fixed / pf.STRETCH_COST)
    assert f"with a fixed kernel, its rate over {pf.STRETCH_COST}" in source
    pf.record_pair_rate({**summary, "wall_seconds": 12.0}, "stretched", stretch=True)
    stretched = 4e8 / (12.0 - 1000 * pf.STEP_SECONDS)
    rate, source = pf.pair_rate("cpu", 2, stretch=True)
    assert rate == pytest.approx(stretched) and "'stretched'" in source
    assert "its rate" not in source
    assert pf.pair_rate("cpu", 2)[0] == pytest.approx(fixed)
    # the case decides: a plastic case's "auto" resolves to a kernel that follows the stretch
    plastic = load_case("taylor", ["kernel.max_stretch=\"auto\""])
    assert pf._stretches(plastic) and not pf._stretches(load_case("taylor"))
    assert pf.estimate(plastic, [1407]).pair_rate == pytest.approx(stretched)


def test_memory_formula_covers_the_traced_arrays():
    """The formula's arrays (less the process base) are at least what numpy allocates for
    a run with snapshots (tracemalloc; numba's own allocations are not traced), the kernels
    compiled before the trace starts (a cold cache once made this test fail in isolation)."""
    import tracemalloc

    from impactsph.simulation import Simulation

    case = validate_case(block_case(
        bodies__0__geometry={"origin": [0.0, 0.0], "size": [0.03, 0.03], "spacing": 5e-4},
        boundaries=[{"point": [0.0, 0.0], "normal": [0.0, 1.0]}], viscosity={"scheme": "ac"},
        time={"end": 1.0, "max_steps": 4}, output={"snapshot_times": [0.0, 1e-10, 2e-10]}))
    est = pf.preflight(case).estimate
    Simulation(case).run()  # compile first: the compiler's own objects are not the run's
    tracemalloc.start()
    sim = Simulation(case)
    sim.run()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert sim.state.n == 3600 and len(sim.record.snapshots) == 3
    assert est.memory - pf.BASE_MEMORY > peak
    assert est.memory - pf.BASE_MEMORY < 4 * peak  # and not wildly above
