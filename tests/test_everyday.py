"""Measures and figures for any case (issue 12): analyses that never crash a finished run,
per-body measures, the energies figure, gauges, ``sweep --metric``, ``run.log``,
``--version``, "did you mean" and ``impactsph animate``."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph.cli import app

runner = CliRunner()

#: a steel disk (52 particles) striking an aluminium plate (96) at 500 m/s, 2D
PLATE = """
name = "plate"
dimension = 2

[materials.steel]
model = "elastic_plastic"
density = 7850.0
youngs_modulus = 200e9
yield_stress = 1.0e9

[materials.aluminium]
model = "elastic_plastic"
density = 2700.0
youngs_modulus = 70e9
yield_stress = 3e8

[[bodies]]
name = "projectile"
material = "steel"
velocity = [0.0, -500.0]
[bodies.geometry]
type = "disk"
centre = [0.0, 0.0032]
radius = 0.002
spacing = 0.0005

[[bodies]]
name = "plate"
material = "aluminium"
velocity = [0.0, 0.0]
[bodies.geometry]
origin = [-0.006, -0.002]
size = [0.012, 0.002]
spacing = 0.0005

[time]
end = 3e-6

[output]
snapshot_times = [0.0, 1e-6, 2e-6, 3e-6]

[[output.gauges]]
name = "back"
body = "plate"
position = [0.0, -0.002]
fields = ["displacement", "velocity", "pressure", "von_mises_stress", "plastic_work"]

[[output.gauges]]
name = "nose"
body = "projectile"
position = [0.0, 0.0012]
"""


def _env() -> dict[str, str]:
    """The environment of a subprocess: this source tree first on the path."""
    src = str(Path(__file__).resolve().parents[1] / "src")
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [src, *filter(None, [os.environ.get("PYTHONPATH")])])}


@pytest.fixture(scope="module")
def plate(tmp_path_factory) -> Path:
    """The projectile-on-plate case, run once (figures on) by ``impactsph run``."""
    folder = tmp_path_factory.mktemp("plate")
    case = folder / "plate.toml"
    case.write_text(PLATE)
    out = folder / "run"
    res = runner.invoke(app, ["run", str(case), "--quiet", "--out", str(out)])
    assert res.exit_code == 0, res.output
    return out


# --- analyses never crash a finished run ------------------------------------------------------

def test_taylor_bar_past_its_rebound_gives_a_summary_and_its_figures(tmp_path):
    """The Taylor bar run past its rebound off the wall (here a coarse one, 9 x 29 particles,
    to 100 us, with its figures and the reference run) ends with exit 0, a complete summary
    that says the bar has lifted off, and every figure; ``run.log`` holds the INFO lines
    that --quiet kept off the console."""
    out = tmp_path / "t"
    res = subprocess.run(
        [sys.executable, "-m", "impactsph", "run", "taylor", "--quiet", "--out", str(out),
         "--set", "time.end=100e-6", "--set", "bodies.0.geometry.count=[9, 29]"],
        capture_output=True, text=True, env=_env(), timeout=600)
    assert res.returncode == 0, res.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished"
    assert summary["lift_off"] > 0
    assert 0.5 < summary["final_length_ratio"] < 1 and summary["footprint_half_width_ratio"] > 1
    assert any("rebounded off the wall" in n for n in summary["notes"])
    assert "note: the bar has rebounded" in res.stderr
    assert {Path(f).name for f in summary["figures"]} == {
        "kinetic_energy.png", "energies.png", "deformed_shape.png"}
    assert summary["bodies"]["bar"]["final_velocity"][1] > 0  # moving away from the wall
    log = (out / "run.log").read_text()
    assert "INFO impactsph: taylor: 261 particles" in log and "reference run with" in log
    assert "figure " in log and f"note ({out}): the bar has rebounded" in log
    assert "INFO" not in res.stderr  # --quiet: warnings and notes only on the console
    assert (out / "reference" / "run.log").is_file()


BROKEN = '''
from impactsph.problems import ProblemKind, register_problem


class Broken(ProblemKind):
    name = "broken_everyday"

    def metrics(self, sim):
        raise ZeroDivisionError("the toy divides by zero")

    def figures(self, runs, labels, out):
        raise ValueError("zero-size array to reduction operation maximum")


register_problem(Broken, replace=True)
'''


def test_a_problem_whose_metrics_and_figures_raise_still_gives_a_summary(tmp_path):
    from impactsph.loading import builtin_case_path
    from impactsph.problems import unregister_problem

    (tmp_path / "broken.py").write_text(BROKEN)
    text = builtin_case_path("bars").read_text().replace(
        'analysis = "bars"', 'analysis = "broken_everyday"\nplugins = ["broken.py"]')
    case = tmp_path / "broken.toml"
    case.write_text(text)
    out = tmp_path / "run"
    try:
        res = runner.invoke(app, ["run", str(case), "--quiet", "--out", str(out),
                                  "--set", "time.end=2e-6"])
    finally:
        unregister_problem("broken_everyday")
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["n_steps"] > 0
    assert 0 < summary["bodies"]["left"]["final_velocity"][0] < 50.0  # slowed by the impact
    notes = " | ".join(summary["notes"])
    assert "analysis 'broken_everyday': its metrics could not be taken (ZeroDivisionError" \
        in notes
    assert "figure of analysis 'broken_everyday': not drawn (ValueError: zero-size" in notes
    assert {Path(f).name for f in summary["figures"]} == {"kinetic_energy.png",
                                                          "energies.png"}
    log = (out / "run.log").read_text()
    assert "WARNING impactsph: figure of analysis 'broken_everyday': not drawn" in log


def test_a_taylor_bar_in_pieces_is_measured_on_its_largest_piece():
    """Fragmentation: a block of particles thrown off the bar leaves the length measured on
    the bar itself, with a note, and the body's measures count the pieces."""
    from impactsph import Simulation, load_case
    from impactsph.measures import run_measures
    from impactsph.problems import analyse

    sim = Simulation(load_case("taylor", ["bodies.0.geometry.count=[9, 29]",
                                          "time.max_steps=1", "output.figures=false"]))
    sim.run()
    whole = analyse("taylor", sim)
    s = sim.state
    top = s.position[:, 1] > 0.9 * s.position[:, 1].max()
    s.position[top, 1] += 0.05  # 5 cm up: a fragment
    broken = analyse("taylor", sim)
    assert broken["final_length_ratio"] < whole["final_length_ratio"]
    assert any("the bar is in 2 pieces" in n for n in broken["notes"])
    measures = run_measures(sim)
    assert measures["bodies"]["bar"]["pieces"] == 2
    assert measures["bodies"]["bar"]["largest_piece_mass_fraction"] == pytest.approx(
        1 - top.sum() / s.n)
    assert any("'bar' is in 2 pieces" in n for n in measures["notes"])


def test_connected_pieces_against_brute_force():
    from impactsph.measures import connected_pieces

    rng = np.random.default_rng(3)
    n = 300
    i, j = rng.integers(0, n, 200), rng.integers(0, n, 200)
    labels = connected_pieces(n, i, j)
    # brute force: propagate the minimum along the edges until nothing changes
    ref = np.arange(n)
    changed = True
    while changed:
        changed = False
        for a, b in zip(i, j, strict=True):
            m = min(ref[a], ref[b])
            if ref[a] != m or ref[b] != m:
                ref[a] = ref[b] = m
                changed = True
    assert np.array_equal(labels, ref)


# --- per-body measures, the energies figure and gauges -----------------------------------------

def test_projectile_on_plate_gets_the_per_body_measures_and_the_energies_figure(plate):
    summary = json.loads((plate / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["notes"] == []
    p, q = summary["bodies"]["projectile"], summary["bodies"]["plate"]
    assert p["particles"] == 52 and q["particles"] == 96
    # the projectile slowed down, the plate was pushed: momentum moved between them
    assert 0 < -p["final_velocity"][1] < 500 and q["final_velocity"][1] < 0
    assert p["final_speed"] == pytest.approx(np.linalg.norm(p["final_velocity"]))
    momentum = p["mass"] * p["final_velocity"][1] + q["mass"] * q["final_velocity"][1]
    assert momentum == pytest.approx(p["mass"] * -500.0, rel=1e-9)
    assert p["max_displacement"] >= p["final_max_displacement"] > 1e-3  # 500 m/s, 3 us
    assert 0 < q["max_displacement"] < p["max_displacement"]
    for b in (p, q):
        assert b["max_plastic_work_per_mass"] > 0 and b["plastic_work"] > 0
        assert b["pieces"] == 1
    assert {Path(f).name for f in summary["figures"]} == {"kinetic_energy.png",
                                                          "energies.png"}
    assert (plate / "energies.png").stat().st_size > 20_000
    # the history's per-body energies add up to the totals
    with open(plate / "history.csv") as fh:
        rows = list(csv.DictReader(fh))
    for r in (rows[0], rows[-1]):
        for what in ("kinetic_energy", "internal_energy", "plastic_work"):
            total = float(r[f"{what}_projectile"]) + float(r[f"{what}_plate"])
            assert total == pytest.approx(float(r[what]), rel=1e-12, abs=1e-12)
    assert float(rows[-1]["plastic_work"]) == pytest.approx(
        p["plastic_work"] + q["plastic_work"], rel=1e-12)


def test_gauges_record_fields_of_a_material_point(plate):
    with open(plate / "gauges.csv") as fh:
        rows = list(csv.DictReader(fh))
    with open(plate / "history.csv") as fh:
        steps = len(list(csv.DictReader(fh)))
    assert len(rows) == steps  # a row every step (history_every = 1), t = 0 included
    cols = list(rows[0])
    assert cols[:8] == ["time", "back_ux", "back_uy", "back_vx", "back_vy", "back_pressure",
                        "back_von_mises", "back_plastic_work"]
    # the default fields: every one but the strength state
    assert cols[8:] == ["nose_x", "nose_y", "nose_ux", "nose_uy", "nose_vx", "nose_vy",
                        "nose_density", "nose_pressure", "nose_specific_energy", "nose_sxx",
                        "nose_syy", "nose_szz", "nose_sxy", "nose_sxz", "nose_syz",
                        "nose_von_mises", "nose_plastic_work"]
    first, last = rows[0], rows[-1]
    assert float(first["nose_vy"]) == -500.0 and float(first["back_uy"]) == 0.0
    assert float(last["back_uy"]) < 0 and float(last["back_von_mises"]) > 0
    density = [float(r["nose_density"]) for r in rows]
    assert density[0] == 7850.0 and max(density) > 8000.0  # compressed at the contact
    summary = json.loads((plate / "summary.json").read_text())
    back = summary["gauges"]["back"]
    assert back["body"] == "plate"
    assert back["initial_position"] == pytest.approx([-0.00025, -0.00175], rel=1e-12)
    assert back["final_displacement"] == [float(last["back_ux"]), float(last["back_uy"])]
    uy = np.array([float(r["back_uy"]) for r in rows])
    ux = np.array([float(r["back_ux"]) for r in rows])
    assert back["max_displacement"] == pytest.approx(np.hypot(ux, uy).max(), rel=1e-12)
    nose = summary["gauges"]["nose"]  # from its position columns
    assert nose["final_displacement"][1] == pytest.approx(
        float(last["nose_uy"]), rel=1e-12)


def test_gauges_continue_across_a_restart(tmp_path):
    """A run stopped after 40 steps and restarted from its checkpoint ends with the
    uninterrupted run's gauges.csv, byte for byte, and the same per-body and gauge measures
    (the maximum displacement is carried by the checkpoint)."""
    from impactsph import load_case
    from impactsph.errors import RunInterrupted
    from impactsph.runner import run_case

    case_file = tmp_path / "plate.toml"
    case_file.write_text(PLATE)
    case = load_case(case_file, ["output.figures=false", "output.snapshot_times=[]"])
    whole = run_case(case, tmp_path / "whole")
    steps = []
    part = tmp_path / "part"
    with pytest.raises(RunInterrupted):
        run_case(case, part, callback=lambda sim: steps.append(sim.state.step),
                 stop=lambda: len(steps) >= 40)
    resumed = run_case(case, part, restart=part / "checkpoint.h5")
    for name in ("gauges.csv", "history.csv"):
        assert (part / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
    assert resumed["bodies"] == whole["bodies"]
    assert resumed["gauges"] == whole["gauges"]
    assert "restarted from" in (part / "run.log").read_text()


def test_old_case_files_keep_their_probes_and_a_gauge_is_checked(tmp_path):
    from impactsph.errors import CaseError
    from impactsph.loading import load_case

    case = load_case("bars")
    assert case.output.gauges == [] and case.output.probes[0].name == "mid_left"
    bad = 'output.gauges=[{name = "g", body = "nobody", position = [0.0]}]'
    with pytest.raises(CaseError, match=r"output.gauges.0.body = 'nobody' is not a body"):
        load_case("bars", [bad])
    two = ('output.gauges=[{name = "g", body = "left", position = [0.0]}, '
           '{name = "g", body = "right", position = [0.0]}]')
    with pytest.raises(CaseError, match=r"output.gauges.1.name = 'g' is used by two"):
        load_case("bars", [two])


# --- the sweep's metrics and run names ---------------------------------------------------------

def test_sweep_metric_plots_a_summary_value_and_names_the_runs(tmp_path):
    out = tmp_path / "sw"
    args = ["sweep", "taylor", "--grid", "materials.iron.yield_stress=6e8,9e8",
            "--set", "bodies.0.geometry.count=[7, 21]", "--set", "time.end=3e-6",
            "--metric", "final_length_ratio", "--metric", "bodies.bar.max_displacement",
            "--metric", "final_lenght_ratio", "--out", str(out), "--workers", "1"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (out / "runs").iterdir()) == [
        "yield_stress=6e+08", "yield_stress=9e+08"]
    with open(out / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["run"] for r in rows] == ["yield_stress=6e+08", "yield_stress=9e+08"]
    ratios = [float(r["final_length_ratio"]) for r in rows]
    assert ratios[0] < ratios[1] < 1.0  # a softer bar shortens more
    assert all(float(r["bodies.bar.max_displacement"]) > 0 for r in rows)
    for name in ("sweep.png", "sweep_final_length_ratio.png",
                 "sweep_bodies.bar.max_displacement.png"):
        assert (out / name).stat().st_size > 10_000, name
    assert not (out / "sweep_final_lenght_ratio.png").exists()
    result = json.loads((out / "sweep.json").read_text())
    assert result["notes"] == ["--metric final_lenght_ratio: no run's summary has a number "
                               "there; did you mean 'final_length_ratio', 'final_length' or "
                               "'initial_length'?"]
    assert "note: --metric final_lenght_ratio: no run's summary has a number" in res.output
    # run again: every run is reused from its named directory
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert all(r["reused"] for r in rows)
    assert [r["final_length_ratio"] for r in rows] == ratios


def test_run_names_are_readable_and_unique_and_old_sweeps_resume(tmp_path):
    from impactsph.sweep import parse_grid, run_dir_name, run_id, run_names

    _, runs = parse_grid(["viscosity.alpha1,viscosity.alpha2=0.1,0.3",
                          "bodies.0.velocity=[80.0],[-80.0]"])
    ovs = [[f"{k}={json.dumps(v)}" for k, v in kv] for kv in runs]
    assert run_names(runs, ovs) == [
        "alpha1=0.1_alpha2=0.1_velocity=80", "alpha1=0.1_alpha2=0.1_velocity=-80",
        "alpha1=0.3_alpha2=0.3_velocity=80", "alpha1=0.3_alpha2=0.3_velocity=-80"]
    assert run_names([[("materials.iron.yield_stress", 6e8)], [("time.end", 2.5e-6)]],
                     [["a"], ["b"]]) == ["yield_stress=6e+08", "end=2.5e-06"]
    # two keys with the same last part are named in full
    same = [[("bodies.0.velocity", [1.0, -2.0])], [("bodies.1.velocity", [1.0, -2.0])]]
    assert run_names(same, [["x"], ["y"]]) == ["bodies.0.velocity=1,-2",
                                                "bodies.1.velocity=1,-2"]
    # names that would be the same get a short hash of their overrides
    clash = [[("name", "a/b")], [("name", "a b")]]
    named = run_names(clash, [["name=a/b"], ["name=a b"]])
    assert named == [f"name=a-b-{run_id(['name=a/b'])[:6]}",
                     f"name=a-b-{run_id(['name=a b'])[:6]}"]
    long = run_names([[("k", "x" * 200)]], [["k=x"]])[0]
    assert long == "k=" + "x" * 78 + "-" + run_id(["k=x"])[:6]
    # an older sweep's directory (named by the hash) holding a summary is used
    (tmp_path / "runs" / run_id(["a=1"])).mkdir(parents=True)
    assert run_dir_name(tmp_path, "a=1", ["a=1"]) == "a=1"
    (tmp_path / "runs" / run_id(["a=1"]) / "summary.json").write_text("{}")
    assert run_dir_name(tmp_path, "a=1", ["a=1"]) == run_id(["a=1"])


# --- the command line: --version, did you mean, the log -----------------------------------------

def test_the_help_wraps_its_paragraphs_and_keeps_their_brackets():
    """The commands' help is their docstrings, each paragraph wrapped to the terminal (typer
    showed their source line breaks) and their brackets as written (rich markup dropped
    ``[materials.X]``)."""
    wide = {"COLUMNS": "200"}
    listing = runner.invoke(app, ["--help"], env=wide).output
    assert 'use one in a case with [materials.X] library = "NAME"' in listing
    assert "estimates of memory and run time, and warnings" in listing
    run_help = runner.invoke(app, ["run", "--help"], env=wide).output
    assert "and prints the command that continues it (exit code 130)" in run_help


def test_version():
    from impactsph._version import __version__

    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() == f"impactsph {__version__}"


def test_a_value_of_several_types_is_told_every_type_it_may_take():
    """A field that takes a number or ``"auto"`` (or a number or a list) says both in its one
    line, for the value given, not the first member's message and "1 more error"."""
    told = {
        "compute.threads=0": "compute.threads = 0: Input should be greater than or equal to 1 "
                             "or 'auto'",
        "compute.threads=two": "compute.threads = 'two': Input should be a valid integer or "
                               "'auto'",
        "kernel.max_stretch=5": "kernel.max_stretch = 5: Input should be less than or equal to "
                                "4 or 'auto'",
        "stabilisation.hourglass=-1": "stabilisation.hourglass = -1: Input should be greater "
                                      "than or equal to 0 or 'auto'",
        "stabilisation.hourglass=nan": "stabilisation.hourglass = nan: Input should be a "
                                       "finite number or 'auto'",  # (nan != nan)
        "bodies.0.clamped=5": "bodies.0.clamped = 5: Input should be a valid dictionary or "
                              "instance of Region or a valid list",  # a model member
        # a list: the list member's error, where it lies
        "bodies.0.geometry.spacing=[1,'x']": "bodies.0.geometry.spacing.1 = 'x': Input should "
                                             "be a valid number",
    }
    for setting, line in told.items():
        res = runner.invoke(app, ["check", "bars", "--set", setting])
        assert res.exit_code == 2, setting
        assert res.output.strip() == f"error: {line}"
    res = runner.invoke(app, ["check", "taylor", "--set", "bodies.0.geometry.spacing='x'"])
    assert res.output.strip() == ("error: bodies.0.geometry.spacing = 'x': Input should be a "
                                  "valid number or a valid list")
    # two fields wrong: the second is still counted
    res = runner.invoke(app, ["check", "bars", "--set", "compute.threads=0", "--set",
                              "kernel.max_stretch=5"])
    assert res.output.strip().endswith("or 'auto' (and 1 more error)")


def test_did_you_mean_for_a_misspelt_key(tmp_path):
    res = runner.invoke(app, ["check", "bars", "--set", "viscosity.alpah1=0.5"])
    assert res.exit_code == 2
    assert res.output.strip() == ("error: viscosity.alpah1: unknown key; did you mean "
                                  "'alpha1' or 'alpha2'?")
    from impactsph.loading import builtin_case_path

    path = tmp_path / "c.toml"
    path.write_text(builtin_case_path("bars").read_text().replace("[viscosity]",
                                                                  "[viscocity]"))
    res = runner.invoke(app, ["check", str(path)])
    assert res.output.strip() == "error: viscocity: unknown key; did you mean 'viscosity'?"
    # a misspelt required key is named before the "missing" it causes
    res = runner.invoke(app, ["check", "bars", "--set",
                              'output.probes.0={name = "m", body = "left", positon = [0.0]}'])
    assert res.output.strip() == ("error: output.probes.0.positon: unknown key; did you mean "
                                  "'position'? (and 1 more error)")
    res = runner.invoke(app, ["check", "taylor", "--set", "bodies.0.geometry.cont=[9, 29]"])
    assert res.output.strip() == "error: bodies.0.geometry.cont: unknown key; did you mean " \
        "'count'?"
    res = runner.invoke(app, ["check", "taylor", "--set", "materials.iron.mie_gruneisen.slop=1"])
    assert res.output.strip() == ("error: materials.iron.mie_gruneisen.slop: unknown key; did "
                                  "you mean 'slope'?")


# --- animate ------------------------------------------------------------------------------------

def _frames(path: Path) -> int:
    from PIL import Image

    with Image.open(path) as im:
        return im.n_frames


def test_animate_writes_a_frame_per_snapshot(plate, tmp_path):
    gif = tmp_path / "vm.gif"
    res = runner.invoke(app, ["animate", str(plate), "--field", "von_mises_stress",
                              "--out", str(gif)])
    assert res.exit_code == 0, res.output
    assert _frames(gif) == 4  # the 4 snapshots
    res = runner.invoke(app, ["animate", str(plate), "--field", "displacement_y",
                              "--out", str(tmp_path / "u.gif")])
    assert res.exit_code == 0 and _frames(tmp_path / "u.gif") == 4
    res = runner.invoke(app, ["animate", str(plate), "--field", "velocty"])
    assert res.exit_code == 2
    assert "--field 'velocty' is not a field of the snapshots; did you mean 'velocity'" \
        in res.output


def test_animate_1d_as_a_line_along_x_with_the_problem_field(tmp_path):
    from impactsph import load_case
    from impactsph.runner import run_case

    out = tmp_path / "bars"
    run_case(load_case("bars", ["time.end=3e-6", "output.figures=false",
                                "output.snapshot_times=[1e-6, 2e-6, 3e-6]"]), out)
    res = runner.invoke(app, ["animate", str(out), "--out", str(out / "a.gif")])
    assert res.exit_code == 0, res.output
    assert _frames(out / "a.gif") == 3
    from impactsph.animate import animate_run, choose_writer

    path, writer = choose_writer(None, out, "velocity_x")
    assert path.name in ("animation_velocity_x.mp4", "animation_velocity_x.gif")
    if writer == "pillow":  # no ffmpeg here: the default is a GIF of the problem's field
        assert animate_run(out).name == "animation_velocity_x.gif"


def test_animate_3d_draws_a_mid_plane_section(tmp_path):
    """A 3D run directory (written here without running: a case, a history and two
    snapshots of a 4 x 4 x 4 block): the section holds the particles within a spacing of
    the plane y = middle."""
    from impactsph.animate import _frames as section_frames
    from impactsph.animate import animate_run
    from impactsph.loading import validate_case
    from impactsph.output import load_run, write_case

    case = validate_case({
        "name": "cube", "dimension": 3,
        "materials": {"m": {"model": "elastic", "density": 1000.0, "youngs_modulus": 1e9}},
        "bodies": [{"name": "b", "material": "m", "velocity": [0.0, 0.0, -1.0],
                    "geometry": {"origin": [0.0] * 3, "size": [4e-3] * 3, "spacing": 1e-3}}],
        "time": {"end": 1e-6}})
    write_case(tmp_path, case)
    (tmp_path / "history.csv").write_text("time,kinetic_energy\n0.0,1.0\n")
    g = (np.arange(4) + 0.5) * 1e-3
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    arrays = {"times": np.array([0.0, 1e-6])}
    for k in range(2):
        arrays |= {f"s{k}_position": x + [0, 0, -1e-6 * k], f"s{k}_initial_position": x,
                   f"s{k}_velocity": np.tile([0.0, 0.0, -1.0], (64, 1)),
                   f"s{k}_smoothing_length": np.full(64, 1.2e-3),
                   f"s{k}_body": np.zeros(64, dtype=np.int32),
                   f"s{k}_density": np.full(64, 1000.0 + k)}
    np.savez(tmp_path / "snapshots.npz", **arrays)
    frames, unit, names = section_frames(load_run(tmp_path), case, "density", "y")
    assert names == ["x", "z"] and unit == "kg/m^3"
    assert len(frames) == 2 and frames[0]["x"].shape == (32, 2)  # the two middle layers
    path = animate_run(tmp_path, "density", tmp_path / "cube.gif")
    assert _frames(path) == 2


def test_run_directory_files_are_known_outputs(plate):
    from impactsph.rundir import _is_output

    for name in ("run.log", "gauges.csv", "energies.png", "animation_speed.gif"):
        assert _is_output(plate / name), name

