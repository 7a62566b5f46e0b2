"""The dissipation lab (:mod:`impactsph.lab`, ``impactsph lab``): its grid and its table."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from impactsph.cli import app
from impactsph.lab import PROBLEMS, SCHEMES, plan

runner = CliRunner()


def test_every_scheme_has_the_same_parameters_on_every_problem():
    """The grid: one run per (problem, scheme); the fixed schemes' overrides are the same on
    every problem, and h_c = dx means one spacing whatever the problem's h/dx (1.2 for the
    bars, 1.3 for the Taylor bar)."""
    runs = plan(list(PROBLEMS), list(SCHEMES))
    assert len(runs) == len(PROBLEMS) * len(SCHEMES)
    by = {(p, s): ov for p, s, _, ov in runs}
    for scheme in SCHEMES:
        viscosity = {p: [o for o in by[(p, scheme)] if o.startswith("viscosity.")]
                     for p in PROBLEMS}
        if "h_c = dx" in scheme:
            assert "viscosity.correction_h_ratio=0.8333333333333334" in viscosity["bars"]
            assert "viscosity.correction_h_ratio=0.7692307692307692" in viscosity["taylor"]
        else:
            assert len({tuple(v) for v in viscosity.values()}) == 1, scheme
    with pytest.raises(ValueError, match=r"scheme 'AV \(2, 2\)': one of"):
        plan(["bars"], ["AV (2, 2)"])


def test_lab_runs_and_tabulates(tmp_path):
    """Two schemes on the bars past the profile's snapshot (5.75 us): lab.json has a row per
    run with the problem's measures, the energy error, the drift and the cost per step;
    lab.md a table; --report-only tabulates the same runs again without running.  (Two AV
    schemes: one compiled module for the worker; the switches have their own tests.)  A
    second problem (the plates) runs on the same cluster with the same schemes' overrides:
    its runs are its own, not taken for the bars'."""
    out = tmp_path / "lab"
    args = ["lab", "--problem", "bars", "--problem", "plates", "--scheme", "AV (1, 1)",
            "--scheme", "AV (0.3, 0.3)", "--set", "time.end=6e-6", "--workers", "1",
            "--out", str(out)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    record = json.loads((out / "lab.json").read_text())
    assert record["provenance"]["impactsph"] and "command" in record
    every = record["rows"]
    assert [(r["problem"], r["scheme"]) for r in every] == [
        ("bars", "AV (1, 1)"), ("bars", "AV (0.3, 0.3)"), ("plates", "AV (1, 1)"),
        ("plates", "AV (0.3, 0.3)")]
    plates = [r for r in every if r["problem"] == "plates"]
    assert all(r["status"] == "ok" for r in plates)
    assert (out / "runs" / "plates--AV_1_1_" / "summary.json").is_file()
    rows = [r for r in every if r["problem"] == "bars"]
    for r in rows:
        assert r["status"] == "ok"
        assert 0 < r["kinetic_energy_ratio_final"] < 1
        assert r["velocity_profile_l1_error"] > 0
        assert r["total_energy_relative_error"] < 1e-3
        assert r["momentum_drift"] < 1e-12 and r["ms_per_step"] > 0
    assert "| AV (0.3, 0.3) |" in (out / "lab.md").read_text()
    again = runner.invoke(app, [*args, "--report-only"])
    assert again.exit_code == 0, again.output
    rows_again = json.loads((out / "lab.json").read_text())["rows"]
    assert [r.get("kinetic_energy_ratio_final") for r in rows_again] == \
        [r.get("kinetic_energy_ratio_final") for r in every]
    assert [r["status"] for r in rows_again] == [r["status"] for r in every]  # ("ok")
    # a scheme not run has no row (it had a row of blanks); nothing run at all is refused
    again = runner.invoke(app, [*args, "--scheme", "Balsara (1, 1)", "--report-only"])
    assert again.exit_code == 0, again.output
    assert len(json.loads((out / "lab.json").read_text())["rows"]) == 4
    empty = runner.invoke(app, ["lab", "--report-only", "--out", str(tmp_path / "none"),
                                "--problem", "bars"])
    assert empty.exit_code == 2 and "holds no run of these problems" in empty.output
    bad = runner.invoke(app, ["lab", "--problem", "slabs", "--out", str(tmp_path / "x")])
    assert bad.exit_code == 2
    assert "problem 'slabs': one of bars, plates, taylor" in bad.output


def test_the_long_problems_are_twice_the_resolution_and_run_only_when_named():
    """``cantilever-x2`` and ``taylor3d-x2`` are the x1 problems at half the spacing (4 and 8
    times the particles); a plain ``impactsph lab`` leaves them out."""
    from impactsph.lab import DEFAULT_PROBLEMS, LONG
    from impactsph.loading import load_case
    from impactsph.problem import build_problem

    assert set(LONG) <= set(PROBLEMS) and not set(LONG) & set(DEFAULT_PROBLEMS)
    assert {p for p, *_ in plan(DEFAULT_PROBLEMS, ["AV (1, 1)"])} == set(DEFAULT_PROBLEMS)
    counts = {}
    for problem in ("cantilever", "cantilever-x2"):
        (_, _, case, overrides), = plan([problem], ["AV (1, 1)"])
        counts[problem] = build_problem(load_case(case, overrides)).state.n
    assert counts["cantilever-x2"] == 4 * counts["cantilever"] == 4 * 1020
    spacing = {}
    for problem in ("taylor3d", "taylor3d-x2"):
        (_, _, case, overrides), = plan([problem], ["AV (1, 1)"])
        spacing[problem] = load_case(case, overrides).bodies[0].geometry.spacing
    assert spacing["taylor3d-x2"] == pytest.approx(spacing["taylor3d"] / 2)


def test_the_3d_cylinder_at_x2_runs_as_its_quarter(tmp_path):
    """The lab's taylor3d-x2 starts from the quarter of the x2 cylinder (two symmetry planes
    through the axis, the particles in a file): a quarter of the whole one's particles, the
    wall kept; validated as a case with the problem's and a scheme's overrides."""
    from impactsph.geometry import read_particle_file
    from impactsph.lab import base_case
    from impactsph.loading import apply_overrides, validate_case

    base = base_case("taylor3d-x2", tmp_path)
    g = base["bodies"][0]["geometry"]
    assert g["type"] == "file" and g["spacing"] == pytest.approx(25.4e-3 / 138)
    n = read_particle_file(g["path"], 3)[0].shape[0]
    assert n == 46230  # the whole cylinder at this spacing: 184,920
    kinds = [b["type"] for b in base["boundaries"]]
    assert kinds.count("symmetry") == 2 and "wall" in kinds
    (_, _, _, overrides), = plan(["taylor3d-x2"], ["AV (1, 1)"])
    case = validate_case(apply_overrides(base, overrides))
    assert case.contact.traction == "normal_stress"
    whole = base_case("taylor3d", tmp_path)
    assert whole["bodies"][0]["geometry"]["type"] == "cylinder"


def test_taylor_rows_carry_the_length_error_against_the_finite_element_reference():
    """A Taylor problem's row has ``final_length_error``: its length ratio over the
    finite-element reference of lab.REFERENCE_LENGTH_RATIO, less 1 (none when the run gave
    no length); the other problems have no such column."""
    from impactsph.lab import REFERENCE_LENGTH_RATIO, markdown, row_of

    row = row_of("taylor-axi", "S", {"final_length_ratio": 0.8137, "n_steps": 4,
                                     "wall_seconds": 1.0, "t_end": 50e-6}, "ok")
    assert row["final_length_error"] == pytest.approx(0.8137 / 0.8123 - 1.0, rel=1e-12)
    # a run shortened with --set time.end: its length is not the reference's at 50 us
    assert row_of("taylor-axi", "S", {"final_length_ratio": 0.9, "t_end": 10e-6},
                  "ok")["final_length_error"] is None
    assert REFERENCE_LENGTH_RATIO["taylor3d"] == REFERENCE_LENGTH_RATIO["taylor-axi"]
    assert row_of("taylor", "S", {}, "failed")["final_length_error"] is None
    assert "final_length_error" not in row_of("bars", "S", {}, "ok")
    assert "| final_length_ratio | final_length_error |" in markdown([row])
