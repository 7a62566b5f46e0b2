"""``impactsph plot DIR`` redraws a run's figures from its files; ``impactsph compare DIR ...``
overlays several runs (the kinetic energy always, the case's figures for runs of one case)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from impactsph.cli import app

runner = CliRunner()

# the bars case needs its snapshot at 5.75 us: end a little later
SHORT_BARS = ["--set", "time.end=6.5e-6", "--quiet"]
FIGURE = 5_000  # bytes: a PNG with axes and curves is larger than this


def invoke(args: list[str]):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


def figures_of(output: str) -> list[str]:
    return [ln.split("figure: ", 1)[1] for ln in output.splitlines() if ln.startswith("figure: ")]


def refused(args: list[str]) -> str:
    res = runner.invoke(app, [str(a) for a in args])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert "Traceback" not in res.output
    return lines[0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Short runs: the bars with AV (0.3, 0.3) (figures drawn) and with AC (no figures, so no
    reference run), a coarse Taylor bar with two snapshots, and a small 2D disk case."""
    root = tmp_path_factory.mktemp("runs")
    invoke(["run", "bars", *SHORT_BARS, "--out", root / "av"])
    invoke(["run", "bars", *SHORT_BARS, "--set", "viscosity.scheme=ac",
            "--set", "output.figures=false", "--out", root / "ac"])
    invoke(["run", "taylor", "--quiet", "--set", "bodies.0.geometry.count=[7, 22]",
            "--set", "time.end=3e-6", "--set", "output.snapshot_times=[1.5e-6, 3e-6]",
            "--set", "output.figures=false", "--out", root / "taylor"])
    case = root / "disk.toml"
    case.write_text(
        'name = "disk"\ndimension = 2\n[materials.steel]\nmodel = "elastic"\n'
        'density = 7800.0\nyoungs_modulus = 2e11\n[[bodies]]\nname = "disk"\n'
        'material = "steel"\nvelocity = [10.0, 0.0]\n[bodies.geometry]\ntype = "disk"\n'
        'centre = [0.0, 0.0]\nradius = 0.004\nspacing = 0.001\n[time]\nend = 1e-5\n'
        'max_steps = 5\n[output]\nsnapshot_times = [1e-9]\n')
    invoke(["run", case, "--quiet", "--out", root / "disk"])
    return root


def test_plot_redraws_a_runs_figures_in_place(runs):
    names = ("kinetic_energy.png", "energies.png", "velocity_profile.png", "mid_velocity.png")
    for name in names:
        assert not (runs / "ac" / name).exists()  # the run drew none
    res = invoke(["plot", runs / "ac"])
    drawn = figures_of(res.output)
    assert drawn == [str(runs / "ac" / name) for name in names]
    for name in names:
        assert (runs / "ac" / name).stat().st_size > FIGURE


def test_plot_writes_elsewhere_with_out(runs, tmp_path):
    res = invoke(["plot", runs / "av", "--out", tmp_path / "figs"])
    drawn = figures_of(res.output)
    assert {p.rsplit("/", 1)[1] for p in drawn} == {"kinetic_energy.png", "energies.png",
                                                     "velocity_profile.png", "mid_velocity.png"}
    assert all(p.startswith(str(tmp_path / "figs")) for p in drawn)


def test_plot_draws_the_shapes_of_the_taylor_bar(runs, tmp_path):
    drawn = figures_of(invoke(["plot", runs / "taylor", "--out", tmp_path]).output)
    assert [p.rsplit("/", 1)[1] for p in drawn] == ["kinetic_energy.png", "energies.png",
                                                     "deformed_shape.png"]


def test_plot_refuses_what_is_not_a_run_directory(runs, tmp_path):
    line = refused(["plot", tmp_path / "nowhere"])
    assert "is not a run directory" in line and "does not exist" in line
    line = refused(["plot", tmp_path])
    assert "is not a run directory" in line and "case.json" in line
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "case.json").write_text("{not json")
    (broken / "history.csv").write_text((runs / "av" / "history.csv").read_text())
    assert "cannot read the run" in refused(["plot", broken])
    (broken / "case.json").write_text(json.dumps({"case": {"name": "x"}}))
    assert refused(["plot", broken]).startswith(f"error: {broken / 'case.json'}: ")
    assert not (broken / "kinetic_energy.png").exists()


def test_compare_overlays_the_bars_with_theory(runs, tmp_path):
    out = tmp_path / "cmp"
    res = invoke(["compare", runs / "av", runs / "ac", "--out", out, "--labels", "AV,AC"])
    drawn = figures_of(res.output)
    assert [p.rsplit("/", 1)[1] for p in drawn] == ["kinetic_energy.png", "energies.png",
                                                     "velocity_profile.png", "mid_velocity.png"]
    for p in drawn:
        assert p.startswith(str(out)) and (out / p.rsplit("/", 1)[1]).stat().st_size > FIGURE
    assert "note:" not in res.output


def test_compare_of_different_cases_overlays_the_kinetic_energy_only(runs, tmp_path):
    res = invoke(["compare", runs / "av", runs / "taylor", runs / "disk", "--out", tmp_path])
    assert figures_of(res.output) == [str(tmp_path / "kinetic_energy.png"),
                                      str(tmp_path / "energies.png")]
    assert "note: the runs are of different cases" in res.output
    assert not (tmp_path / "velocity_profile.png").exists()


def test_compare_taylor_runs_draws_the_shapes(runs, tmp_path):
    res = invoke(["compare", runs / "taylor", runs / "taylor", "--out", tmp_path,
                  "--labels", "one, two"])
    assert [p.rsplit("/", 1)[1] for p in figures_of(res.output)] == [
        "kinetic_energy.png", "energies.png", "deformed_shape.png"]


def test_compare_refuses_bad_input(runs, tmp_path):
    line = refused(["compare", runs / "av", runs / "ac", "--labels", "one", "--out", tmp_path])
    assert line == "error: --labels gives 1 label for 2 runs"
    line = refused(["compare", runs / "av", tmp_path / "nowhere", "--out", tmp_path / "o"])
    assert "nowhere is not a run directory" in line
    assert not (tmp_path / "o").exists()


def test_a_run_without_snapshots_says_why_it_has_no_shape_and_no_animation(tmp_path):
    """The Taylor bar shortened below its first snapshot time: the preflight warns, the run
    ends with a note that the deformed shape is not drawn (not a figure left out in
    silence), and ``animate`` says that the snapshot times lie after the run's end."""
    out = tmp_path / "short"
    res = runner.invoke(app, ["run", "taylor", "--set", "bodies.0.geometry.count=[4, 12]",
                              "--set", "time.end=1e-6", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert ("warning: output.snapshot_times = [1e-05, 2e-05, 3e-05, 4e-05, 5e-05]: 5 of 5 "
            "after time.end = 1e-06: no snapshot is taken then") in res.output
    notes = json.loads((out / "summary.json").read_text())["notes"]
    assert any("deformed_shape.png needs a snapshot" in note for note in notes), notes
    assert not (out / "deformed_shape.png").exists()
    line = refused(["animate", out])
    assert "its output.snapshot_times (1e-05, 2e-05, 3e-05, 4e-05, 5e-05 s) all lie after " \
           "its end, time.end = 1e-06 s" in line, line


def test_animate_says_a_run_stopped_before_its_first_snapshot(tmp_path):
    """An unstable run that stopped before its first snapshot time has no snapshots either:
    animate says so, not that the snapshot times lie after the case's end."""
    out = tmp_path / "u"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), "--set",
                              "time.courant=1.0", "--set", "viscosity.alpha1=0", "--set",
                              "viscosity.alpha2=0", "--set", "output.snapshot_times=[1e-4]",
                              "--set", "time.end=2e-4"])
    assert res.exit_code == 3, res.output  # unstable
    line = refused(["animate", out])
    assert "the run stopped at t = " in line and "(unstable), before its first snapshot " \
           "time, 0.0001 s" in line, line


def test_plot_says_when_a_run_it_draws_did_not_finish(runs, tmp_path):
    """A run interrupted in its reference run has that run's curves ending part-way:
    ``plot`` drew them without a word (an audit, 2026-12-08)."""
    import shutil

    run = tmp_path / "av"
    shutil.copytree(runs / "ac", run)
    shutil.copytree(runs / "ac", run / "reference")
    summary = json.loads((run / "reference" / "summary.json").read_text())
    summary["status"] = "interrupted"
    (run / "reference" / "summary.json").write_text(json.dumps(summary))
    res = invoke(["plot", run])
    ends = float((run / "reference" / "history.csv").read_text().splitlines()[-1]
                 .split(",")[0])
    assert (f"note: its reference run ({run / 'reference'}) is interrupted: its history ends "
            f"at t = {ends:.6g} s, and its curves there") in res.output
    assert "note: the run (" not in res.output  # the run itself finished
    # a run whose process was killed says "running" and t = 0 until its first checkpoint:
    # its history says how far it went
    summary.update(status="running", t_end=0.0)
    (run / "reference" / "summary.json").write_text(json.dumps(summary))
    res = invoke(["plot", run])
    assert f"is not finished: its history ends at t = {ends:.6g} s" in res.output
    res = runner.invoke(app, ["animate", str(run), "--fps", "0"])
    assert res.exit_code == 2 and "error: --fps 0: a number of frames per second > 0" in \
        res.output


def test_side_by_side_shapes_are_drawn_at_one_scale(tmp_path, monkeypatch):
    """Two deformed shapes side by side (the paper's Figs 11 and 13) at the same millimetres
    per pixel: with only y shared each panel's width set its own scale, 12.8 against 14.3
    px/mm, which exaggerated the AV-against-AC length difference (an audit, 2026-12-08)."""
    import numpy as np

    import impactsph.plotting as plotting

    rng = np.random.default_rng(0)
    runs = [{"label": "A", "x": np.c_[rng.uniform(-5, 5, 300), rng.uniform(0, 20, 300)] * 1e-3},
            {"label": "B", "x": np.c_[rng.uniform(-8, 8, 300), rng.uniform(0, 18, 300)] * 1e-3}]
    drawn = {}
    save = plotting.save_figure
    monkeypatch.setattr(plotting, "save_figure",
                        lambda fig, path: drawn.setdefault("fig", fig) and save(fig, path))
    plotting.shapes_figure(runs, tmp_path / "shapes.png", "t", separate=True)
    fig = drawn["fig"]
    fig.canvas.draw()
    scales = [(ax.get_window_extent().width / np.ptp(ax.get_xlim()),
               ax.get_window_extent().height / np.ptp(ax.get_ylim())) for ax in fig.axes]
    assert np.allclose(scales, scales[0], rtol=1e-9)
