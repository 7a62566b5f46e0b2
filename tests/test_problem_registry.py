"""Problems as modules: a problem registered from outside the package (here, from this test
file) is usable as ``analysis = "NAME"`` in a case file; its metric lands in summary.json,
its figure is drawn, ``impactsph run`` prints its summary keys and a sweep tabulates its
columns.  An unknown name is refused with one line naming ``analysis``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import impactsph
from impactsph.cli import app
from impactsph.config import CaseError
from impactsph.loading import load_case
from impactsph.problems import (
    GeometryNeeds,
    ProblemKind,
    analyse,
    get_problem,
    problem_names,
    register_problem,
    unregister_problem,
)

runner = CliRunner()

V = 20.0  # m/s, the block's speed towards the wall
T_END = 1e-6  # s


class Toy(ProblemKind):
    """A block thrown at a wall: the largest displacement of a particle."""

    name = "toy"
    title = "a block thrown at a wall: the largest particle displacement"
    geometry_needs = GeometryNeeds(bodies=1, types=("block",))

    def metrics(self, sim: Any) -> dict[str, Any]:
        d = np.linalg.norm(sim.state.position - sim.state.initial_position, axis=1)
        return {"max_displacement": float(d.max())}

    def summary_keys(self, case: Any) -> tuple[str, ...]:
        return ("max_displacement",)

    def table_keys(self, case: Any) -> tuple[str, ...]:
        return ("max_displacement",)

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path) -> list[Path]:
        from impactsph.plotting import plt, save_figure

        fig, ax = plt.subplots()
        for lab, r in zip(labels, runs, strict=True):
            ax.plot(r["history"]["time"], r["history"]["kinetic_energy"], label=lab)
        ax.legend()
        return [save_figure(fig, Path(out) / "toy.png")]


@pytest.fixture(autouse=True)
def toy():
    register_problem(Toy)
    yield
    unregister_problem("toy")


def write_case(folder: Path, analysis: str = "toy", geometry: str | None = None) -> Path:
    """A 2D elastic block of 8 x 8 particles moving onto a wall at y = 0."""
    geometry = geometry or ('origin = [-0.002, 0.0]\nsize = [0.004, 0.004]\n'
                            'spacing = 0.0005\n')
    path = folder / f"{analysis}.toml"
    path.write_text(
        f'name = "block"\ndimension = 2\nanalysis = "{analysis}"\n'
        '[materials.steel]\nmodel = "elastic"\ndensity = 7800.0\nyoungs_modulus = 2e11\n'
        f'[[bodies]]\nname = "block"\nmaterial = "steel"\nvelocity = [0.0, {-V}]\n'
        f'[bodies.geometry]\n{geometry}'
        '[[boundaries]]\ntype = "wall"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n'
        f'[time]\nend = {T_END}\n')
    return path


def test_a_registered_problem_runs_from_a_case_file(tmp_path):
    assert "toy" in problem_names()
    case = load_case(write_case(tmp_path))
    assert case.analysis == "toy"
    out = tmp_path / "run"
    summary = impactsph.run_case(case, out)  # figures on (the case's default)
    written = json.loads((out / "summary.json").read_text())
    assert written["max_displacement"] == summary["max_displacement"]
    # the block moves at V towards the wall and is stopped by it: it moves less than V t
    assert 0 < written["max_displacement"] < V * T_END
    assert written["figures"] == [str(out / "kinetic_energy.png"), str(out / "energies.png"),
                                  str(out / "toy.png")]
    assert (out / "toy.png").stat().st_size > 5_000


def test_run_prints_the_problems_summary_keys(tmp_path):
    res = runner.invoke(app, ["run", str(write_case(tmp_path)), "--quiet",
                              "--set", "output.figures=false", "--out", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output
    start = res.output.index("{\n")
    shown = json.loads(res.output[start: res.output.index("\n}", start) + 2])
    assert shown["max_displacement"] > 0
    assert "contact_time_us" not in shown


def test_a_sweep_and_the_paper_use_the_problem(tmp_path):
    from impactsph.paper import paper_figures
    from impactsph.sweep import table_keys

    case = load_case(write_case(tmp_path))
    keys = table_keys(case)
    assert keys[:2] == ("kinetic_energy_ratio_final", "max_displacement")
    assert "velocity_profile_oscillation" not in keys
    assert get_problem("toy").sweep_criterion is None  # a sweep reports its table only
    with pytest.raises(ValueError, match="analysis = 'toy' has no paper figures; the problems "
                                         "that have: bars, taylor, cantilever"):
        paper_figures(str(write_case(tmp_path)), tmp_path / "paper")
    assert not (tmp_path / "paper").exists()


def test_an_unknown_analysis_is_refused_in_one_line(tmp_path):
    path = write_case(tmp_path, analysis="toy_box")
    with pytest.raises(CaseError) as info:
        load_case(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("analysis = 'toy_box': ")
    for name in ("none", "bars", "taylor", "cantilever", "toy"):
        assert repr(name) in message
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 2
    assert res.output.strip() == f"error: {message}"
    unregister_problem("toy")  # the registry, not a fixed list, decides
    with pytest.raises(CaseError, match="^analysis = 'toy': Input should be "):
        load_case(write_case(tmp_path))


def test_the_problems_geometry_needs_are_checked(tmp_path):
    disk = 'type = "disk"\ncentre = [0.0, 0.003]\nradius = 0.002\nspacing = 0.0005\n'
    with pytest.raises(CaseError, match="^bodies.0.geometry: analysis = 'toy' needs type = "
                                        "'block', not 'disk'$"):
        load_case(write_case(tmp_path, geometry=disk))
    assert load_case(write_case(tmp_path, analysis="none", geometry=disk)).analysis == "none"


def test_registration_rules():
    assert problem_names()[:4] == ("none", "bars", "taylor", "cantilever")
    with pytest.raises(ValueError, match="already registered"):
        register_problem(Toy)
    again = Toy()
    assert register_problem(again, replace=True) is again
    assert get_problem("toy") is again
    none = type("Nothing", (ProblemKind,), {"name": "none"})
    with pytest.raises(ValueError, match="'none' is already registered"):
        register_problem(none, replace=True)
    with pytest.raises(ValueError, match="must be a Python identifier"):
        register_problem(type("Bad", (ProblemKind,), {"name": "two words"}))
    with pytest.raises(TypeError, match="not a ProblemKind"):
        register_problem(object())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="no problem named 'nothing'; registered: none, bars"):
        get_problem("nothing")
    assert analyse("none", None) == {}
    assert not get_problem("toy").has_paper and get_problem("bars").has_paper
