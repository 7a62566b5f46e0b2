"""The command line: a run writes its outputs; bad input is refused with one line and exit
code 2 before any computation; an unstable run stops with where and when, keeping its
history."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph.cli import app
from impactsph.loading import builtin_case_path, load_case
from impactsph.runner import run_case
from impactsph.simulation import SimulationError

runner = CliRunner()


def test_run_bars_writes_outputs(tmp_path):
    out = tmp_path / "bars"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out),
                              "--set", "viscosity.alpha1=0.3", "--set", "viscosity.alpha2=0.3"])
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    for key in ("n_particles", "n_steps", "t_end", "wall_seconds", "compile_seconds",
                "pair_evaluations_per_second",
                "kinetic_energy_initial", "kinetic_energy_final", "kinetic_energy_ratio_final",
                "total_energy_relative_error", "momentum_drift", "contact_time_us",
                "velocity_profile_l1_error", "velocity_profile_oscillation",
                "mid_velocity_l1_error"):
        assert key in summary, key
    assert summary["n_particles"] == 202
    assert summary["status"] == "finished"
    assert summary["provenance"]["impactsph"]
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []  # no lock
    resolved = json.loads((out / "case.json").read_text())
    assert resolved["case"]["viscosity"]["alpha1"] == 0.3
    assert resolved["case"]["time"]["courant"] == 0.3  # defaults are written out
    header = (out / "history.csv").read_text().splitlines()[0].split(",")
    assert {"time", "kinetic_energy", "internal_energy", "total_energy", "momentum_x"} <= set(
        header)
    for fig in ("velocity_profile.png", "mid_velocity.png", "kinetic_energy.png"):
        assert (out / fig).stat().st_size > 10_000
    assert "figure:" in res.output


def test_example_file_is_the_builtin():
    example = Path(__file__).parents[1] / "examples" / "bars.toml"
    with open(example, "rb") as a, open(builtin_case_path("bars"), "rb") as b:
        assert tomllib.load(a) == tomllib.load(b)


def test_set_overrides_nested_and_indexed_fields():
    case = load_case("bars", ["viscosity.alpha1=0.7", "bodies.1.velocity=[-20.0]",
                              "time.end=1e-6"])
    assert case.viscosity.alpha1 == 0.7
    assert case.bodies[1].velocity == [-20.0]
    assert case.time.end == 1e-6


BAD = [
    (["--set", "viscosity.alpah1=0.3"], "viscosity.alpah1"),
    (["--set", "viscosity.alpha1=abc"], "viscosity.alpha1"),
    (["--set", "viscosity.alpha1=-1"], "viscosity.alpha1"),
    (["--set", "materials.steel.density=0"], "materials.steel.density"),
    (["--set", "materials.steel.density=-7900"], "materials.steel.density"),
    (["--set", "materials.steel.youngs_modulus=0"], "materials.steel.youngs_modulus"),
    (["--set", "time.end=0"], "time.end"),
    (["--set", "time.end=-1"], "time.end"),
    (["--set", "materials.steel.poisson_ratio=0.5"], "materials.steel.poisson_ratio"),
    (["--set", "materials.steel.poisson_ratio=-1.2"], "materials.steel.poisson_ratio"),
    (["--set", "viscosity.scheme=magic"], "viscosity.scheme"),
    (["--set", "bodies.0.material=gold"], "gold"),
    (["--set", "bodies.0.velocity=[1.0, 2.0]"], "bodies.0.velocity"),
    (["--set", "time.end"], "KEY=VALUE"),
    (["--set", 'boundaries=[{type="symmetry", point=[0.0], normal=[1.0], friction=0.2}]'],
     "boundaries.0.friction: unknown key; friction is a field of type = 'wall' (this table's "
     "type is 'symmetry')"),
    # a boundary's field by its own path (not pydantic's boundaries.0.wall.friction)
    (["--set", 'boundaries=[{point=[0.0], normal=[1.0], friction=-1.0}]'],
     "error: boundaries.0.friction = -1.0: Input should be greater than or equal to 0"),
    # a boolean shown as the case file writes it, not as Python does
    (["--set", "time.end=true"], "time.end = true: Input should be a valid number"),
    # a boundary's type is named with its value, as a geometry's is
    (["--set", 'boundaries=[{type="symetry", point=[0.0], normal=[1.0]}]'],
     "boundaries.0.type = 'symetry': Input should be 'wall' or 'symmetry'"),
]


@pytest.mark.parametrize(("args", "named"), BAD)
def test_bad_input_exit_code_2_one_line(tmp_path, args, named):
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(tmp_path / "x"), *args])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1, res.output
    assert named in lines[0]
    assert "Traceback" not in res.output
    assert not (tmp_path / "x").exists()  # refused before any work


def test_unknown_builtin_and_missing_file(tmp_path):
    for name in ("nosuchcase", str(tmp_path / "missing.toml")):
        res = runner.invoke(app, ["run", name, "--quiet"])
        assert res.exit_code == 2
        assert len(res.output.strip().splitlines()) == 1
        assert "bars" in res.output or "does not exist" in res.output
    # an empty name is not the current directory read as a case file
    res = runner.invoke(app, ["check", ""])
    assert res.exit_code == 2
    assert res.output.strip().startswith("error: case '': give a case file or a built-in "
                                         "case: bars"), res.output


def test_case_file_with_unknown_key(tmp_path):
    text = builtin_case_path("bars").read_text().replace("[kernel]", "[kernel]\ncolour = 1")
    path = tmp_path / "c.toml"
    path.write_text(text)
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 2
    assert res.output.strip() == "error: kernel.colour: unknown key"


def test_unstable_run_stops_with_where_and_when(tmp_path):
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(tmp_path / "u"),
                              "--set", "time.courant=1.0", "--set", "viscosity.alpha1=0",
                              "--set", "viscosity.alpha2=0"])
    assert res.exit_code == 3
    assert "step" in res.output and "particle" in res.output and "t = " in res.output
    rows = (tmp_path / "u" / "history.csv").read_text().splitlines()
    assert len(rows) > 100  # the history up to the failure is kept
    summary = json.loads((tmp_path / "u" / "summary.json").read_text())
    assert summary["status"] == "unstable" and summary["failure"]
    assert summary["n_steps"] == len(rows) - 2  # the rows of t = 0 and of every step


def _strict_json(text: str):
    """``json.loads`` that refuses NaN and infinities, as JSON itself (and e.g. JavaScript's
    ``JSON.parse``) does."""
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def test_a_measure_not_taken_is_null_in_the_summary_not_nan(tmp_path):
    """The bars stopped before they part: their contact time is not measured (a note says
    so) and is written ``null``, in summary.json and in what the command prints: strict
    JSON, which has no NaN."""
    out = tmp_path / "short"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out),
                              "--set", "time.end=5e-6"])
    assert res.exit_code == 0, res.output
    summary = _strict_json((out / "summary.json").read_text())
    assert summary["contact_time_us"] is None
    assert any("contact_time_us" in note for note in summary["notes"]), summary["notes"]
    printed = res.output[res.output.index("{"): res.output.index("}\n") + 1]
    assert _strict_json(printed)["contact_time_us"] is None


def test_json_text_writes_what_is_not_finite_as_null():
    from impactsph.output import json_text

    value = {"a": float("nan"), "b": [1.5, float("inf"), np.float64("-inf")],
             "c": {"d": np.float32("nan"), "e": np.array(2.0), "f": np.int64(3)},
             "g": None, "h": "text", "i": (np.float64(0.25),)}
    assert _strict_json(json_text(value)) == {
        "a": None, "b": [1.5, None, None], "c": {"d": None, "e": 2.0, "f": 3.0},
        "g": None, "h": "text", "i": [0.25]}


def test_nan_is_reported_with_step_time_and_particle(tmp_path):
    case = load_case("bars")

    def poison(sim):
        if sim.state.step == 50:
            sim.state.velocity[17, 0] = np.nan

    with pytest.raises(SimulationError) as info:
        run_case(case, tmp_path / "n", callback=poison, figures=False)
    msg = str(info.value)
    assert "non-finite velocity" in msg and "step 50" in msg and "particle 17" in msg
    assert info.value.step == 50 and info.value.particle == 17
    rows = (tmp_path / "n" / "history.csv").read_text().splitlines()
    assert len(rows) == 1 + 51  # header, t = 0 and steps 1-50: all kept
    _strict_json((tmp_path / "n" / "summary.json").read_text())  # (a failed run's too)


def test_a_callback_that_only_reads_the_clock_costs_no_second_survey(monkeypatch):
    """A run surveys its state once a step.  A callback that reads only ``sim.time``,
    ``sim.step`` or the record (the command line's progress bar, the history stream) adds no
    survey; one that reads ``sim.state`` may have changed it, so the state is surveyed again
    before the next step (``test_nan_is_reported_with_step_time_and_particle`` checks that
    such a change is caught at its own step)."""
    from impactsph.simulation import Simulation

    surveys = []
    original = Simulation._survey
    monkeypatch.setattr(Simulation, "_survey",
                        lambda sim: surveys.append(sim.step) or original(sim))
    case = load_case("bars", ["time.end=2e-6"])
    counts = {}
    for name, callback in (("none", None),
                           ("clock", lambda sim: (sim.time, sim.step, sim.record.history[-1])),
                           ("state", lambda sim: sim.state.velocity)):
        sim = Simulation(case)
        surveys.clear()
        sim.run(callback=callback)
        counts[name] = (len(surveys), sim.step)
    steps = counts["none"][1]
    assert steps > 10 and counts["clock"][1] == counts["state"][1] == steps
    assert counts["none"][0] == counts["clock"][0] == steps + 1  # the run's start, each step
    assert counts["state"][0] == 2 * steps + 1


@pytest.mark.parametrize(("scheme", "surge", "fail", "every", "noted"), [
    ("ac", 100, 160, 1, True),      # a surge over the last 60 steps
    ("ac", None, 160, 1, False),    # none: the correction's own work
    ("av", 100, 160, 1, False),     # no correction
    ("ac", 10, 50, 1, False),       # too short a history to tell (51 rows)
    ("ac", 1550, 1605, 10, True),   # rows every 10 steps: the books since the last row count
])
def test_a_failure_after_the_correction_surges_says_so(tmp_path, scheme, surge, fail, every,
                                                         noted):
    """A run with the acceleration correction that fails after the correction's work on the
    particles has surged (here booked by hand from step ``surge``) says so in its failure
    message, with the numbers and the scheme that holds such runs; a run whose correction did
    not surge, a run without a correction, or one too short to tell, does not."""
    case = load_case("bars", [f'viscosity.scheme="{scheme}"', f"output.history_every={every}"])

    def surge_then_poison(sim):
        if surge is not None and sim.state.step >= surge:
            sim.correction_work += 10.0 * (sim.state.step - surge + 1)
        if sim.state.step == fail:
            sim.state.velocity[17, 0] = np.nan

    with pytest.raises(SimulationError) as info:
        run_case(case, tmp_path / "n", callback=surge_then_poison, figures=False)
    msg = str(info.value)
    assert "non-finite velocity" in msg and f"step {fail}" in msg and info.value.particle == 17
    assert info.value.step == fail
    assert ("acceleration correction's work on the particles rose" in msg) == noted
    if noted:
        assert 'viscosity.scheme = "ac_pairwise"' in msg
        # the last window: 50 rows back from the books at the failure (every 10 steps: from
        # the row of step 1110 to step 1605)
        assert f"over the last {50 if every == 1 else 495} steps" in msg
    summary = json.loads((tmp_path / "n" / "summary.json").read_text())
    assert summary["failure"] == msg


@pytest.mark.parametrize("source, extra, expected", [
    ("taylor", [], "scheme: AC (neighbours_only), updated-Lagrangian; h = 1.3 dx, fixed; "
     "gradient correction none, hourglass 0; walls: pressure traction, layer 0"),
    ("taylor3d", [], "h = 1.3 dx, growing with the stretch to 1.23 h0 (kernel.max_stretch)"),
    ("bars", ['stabilisation.gradient_correction="auto"', 'stabilisation.hourglass="auto"'],
     "gradient correction velocity gradient and forces, hourglass 2"),
    ("rings", ['formulation="total_lagrangian"', "stabilisation.artificial_stress=0"],
     "scheme: AV (1, 1), total-Lagrangian; h = 1.3 dx, fixed"),
])
def test_check_says_which_scheme_runs(source, extra, expected):
    """``check`` (and the run's log) name the discretisation with its "auto" defaults
    resolved: what a case of one's own gets is not hidden."""
    res = runner.invoke(app, ["check", source, *(a for s in extra for a in ("--set", s))])
    assert res.exit_code == 0, res.output
    line = res.output.splitlines()[1]
    assert line.startswith("scheme: ") and expected in line, line


def test_the_command_line_starts_without_matplotlib():
    """``import impactsph`` and the command line's module leave matplotlib alone (a run
    imports it where it draws): it was a third of every command's start, ``impactsph --help``
    and each sweep worker's included."""
    import subprocess
    import sys

    code = "import sys, impactsph.cli; print(sorted(m for m in sys.modules if 'matplotlib' in m))"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert res.stdout.strip() == "[]", res.stdout


def test_the_built_in_cases_are_the_case_files_the_package_ships():
    """`impactsph run NAME` runs ``src/impactsph/cases/NAME.toml``: a case file added there
    without its name in ``loading.BUILTIN_CASES`` (or a name without its file) is caught."""
    from importlib import resources

    from impactsph.loading import BUILTIN_CASES

    shipped = {p.name[:-5] for p in resources.files("impactsph").joinpath("cases").iterdir()
               if p.name.endswith(".toml")}
    assert sorted(BUILTIN_CASES) == sorted(shipped)


def test_the_annotated_bars_of_the_docs_are_the_built_in_case():
    """docs/case-files.md, "Example: the bars", says it is ``examples/bars.toml`` annotated:
    it had lost the [stabilisation] and [contact] tables, so a copy of it ran another scheme
    (an audit, 2026-12-08)."""
    root = Path(__file__).parent.parent
    text = (root / "docs" / "case-files.md").read_text()
    start = text.index("The built-in `bars` case (`examples/bars.toml`), annotated:")
    block = text[start:].split("```toml\n", 1)[1].split("```", 1)[0]
    assert tomllib.loads(block) == tomllib.loads((root / "examples" / "bars.toml").read_text())
