"""The dissipation lab (docs/dissipation.md): every viscosity scheme, each with one fixed set of
parameters, on every problem, in one table.

``impactsph lab`` runs the grid on Dask (:func:`impactsph.sweep.run_many`), one run per
(scheme, problem), into ``OUT/runs/PROBLEM--SCHEME``, and writes ``OUT/lab.json`` (a row per
run: the problem's measures, the energy error, the momentum drift, the cost per step) and
``OUT/lab.md`` (a table per problem).  The schemes' parameters are fixed here, the same on
every problem: the lab compares schemes, it does not tune them.

A scheme that depends on the kernel's width (the correction kernel at ``h_c = dx``) is given
as a function of the problem's case, so that it means the same on every problem.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from .errors import CaseError
from .geometry import quarter_cylinder_case
from .loading import apply_overrides, read_case_dict
from .output import atomic_write_text, load_run, write_study

Overrides = Callable[[dict[str, Any]], list[str]]


def _fixed(*overrides: str) -> Overrides:
    return lambda case: list(overrides)


def _h_c_is_dx(scheme: str) -> Overrides:
    """AC or its pairwise form with the correction kernel's ``h_c`` one particle spacing."""
    def overrides(case: dict[str, Any]) -> list[str]:
        h_over_dx = float(case.get("kernel", {}).get("h_over_dx", 1.2))
        return [f'viscosity.scheme="{scheme}"', f"viscosity.correction_h_ratio={1 / h_over_dx!r}"]
    return overrides


#: the schemes, by the name the table shows, with their fixed parameters
SCHEMES: dict[str, Overrides] = {
    "AV (1, 1)": _fixed('viscosity.scheme="av"', "viscosity.alpha1=1.0", "viscosity.alpha2=1.0"),
    "AV (0.3, 0.3)": _fixed('viscosity.scheme="av"', "viscosity.alpha1=0.3",
                            "viscosity.alpha2=0.3"),
    "AC (paper)": _fixed('viscosity.scheme="ac"'),
    "AC, h_c = dx": _h_c_is_dx("ac"),
    "AC, h_c = h": _fixed('viscosity.scheme="ac"', "viscosity.correction_h_ratio=1.0"),
    "AC pairwise": _fixed('viscosity.scheme="ac_pairwise"'),
    "AC pairwise, h_c = dx": _h_c_is_dx("ac_pairwise"),
    "AC pairwise, h_c = h": _fixed('viscosity.scheme="ac_pairwise"',
                                   "viscosity.correction_h_ratio=1.0"),
    "AC optimised": _fixed('viscosity.scheme="ac_optimised"'),
    "Balsara (1, 1)": _fixed('viscosity.scheme="balsara"', "viscosity.alpha1=1.0",
                             "viscosity.alpha2=1.0"),
    "Morris-Monaghan (1, 2)": _fixed('viscosity.scheme="morris_monaghan"',
                                     "viscosity.alpha1=1.0", "viscosity.alpha2=2.0"),
    "Cullen-Dehnen (1, 2)": _fixed('viscosity.scheme="cullen_dehnen"', "viscosity.alpha1=1.0",
                                   "viscosity.alpha2=2.0"),
    "Reconstruction (1, 1)": _fixed('viscosity.scheme="reconstruction"', "viscosity.alpha1=1.0",
                                    "viscosity.alpha2=1.0"),
    "Reconstruction (1, 1), minmod": _fixed('viscosity.scheme="reconstruction"',
                                            "viscosity.alpha1=1.0", "viscosity.alpha2=1.0",
                                            'viscosity.limiter="minmod"'),
}

#: the wall of the Taylor bars: the normal-stress contact and the penalty layer that hold a
#: wall (docs/stabilisation.md), so that the schemes are compared without particles reaching
#: the plane (the built-in case keeps the paper's pressure-only wall)
WALL = ['contact.traction="normal_stress"', "contact.wall_layer=0.25"]
#: the problems: a built-in case, its overrides, and the measures the table shows
PROBLEMS: dict[str, tuple[str, list[str], list[str]]] = {
    "bars": ("bars", [], ["kinetic_energy_ratio_final", "velocity_profile_l1_error",
                          "velocity_profile_oscillation"]),
    "plates": ("plates", [], ["velocity_profile_l1_error", "velocity_profile_oscillation",
                              "plateau_velocity_error", "precursor_speed_error",
                              "plastic_speed_error"]),
    "taylor": ("taylor", WALL, ["final_length_ratio", "final_length_error",
                                "footprint_half_width_ratio", "plastic_work"]),
    "taylor-x2": ("taylor", [*WALL, "bodies.0.geometry.count=[42, 134]"],
                  ["final_length_ratio", "final_length_error", "footprint_half_width_ratio",
                   "plastic_work"]),
    # the cylinder (the Taylor bar in 3D) in axisymmetry: its length within 2% of the 3D
    # cylinder's at x1 and x2 (docs/validation.md), at a fiftieth of the cost
    "taylor-axi": ("taylor_axisymmetric", WALL, ["final_length_ratio", "final_length_error",
                                                 "footprint_radius_ratio", "plastic_work"]),
    "taylor-axi-x2": ("taylor_axisymmetric", [*WALL, "bodies.0.geometry.count=[20, 138]"],
                      ["final_length_ratio", "final_length_error", "footprint_radius_ratio",
                       "plastic_work"]),
    # the cylinder itself (22,908 particles, 2-4 min a run on 2 cores; at x2, 180,000
    # particles and twice the steps, it is not part of the lab: docs/dissipation.md)
    "taylor3d": ("taylor3d", WALL, ["final_length_ratio", "final_length_error",
                                    "footprint_radius_ratio", "plastic_work"]),
    "cantilever": ("cantilever", [], ["tip_deflection", "plastic_work",
                                      "kinetic_energy_ratio_final"]),
    # twice the particles each way and twice the steps: 30-70 min a run on one core of this
    # machine (docs/dissipation.md); run when named, not by default
    "cantilever-x2": ("cantilever", ["bodies.0.geometry.count=[408, 10]"],
                      ["tip_deflection", "plastic_work", "kinetic_energy_ratio_final"]),
    # the cylinder at half the spacing, as its quarter with two symmetry planes (QUARTERED:
    # 46,230 particles, the whole one's 184,920; equal to round-off, tests/test_symmetry.py),
    # 30-60 min a run on one core here; run when named
    "taylor3d-x2": ("taylor3d", [*WALL, f"bodies.0.geometry.spacing={25.4e-3 / 138!r}"],
                    ["final_length_ratio", "final_length_error", "footprint_radius_ratio",
                     "plastic_work"]),
    # Gray, Monaghan & Swift's rubber rings (elastic; the artificial stress keeps them whole)
    "rings": ("rings", [], ["restitution", "max_neighbour_gap_over_h", "min_distance_over_dx",
                            "kinetic_energy_ratio_final"]),
}
#: L_f / L_0 of the Taylor bars by converged explicit finite elements of the same model
#: (``validation/taylor_fem.py``: mean-dilatation Q4, the package's return map and
#: Mie-Gruneisen pressure, a bulk viscosity on the volumetric rate only, the same
#: frictionless wall; docs/validation.md): the plane-strain bar, 64 elements across its
#: half-width (``taylor_fem.py 8 16 32 64``: 0.8131, 0.8110, 0.8103, 0.8100), and the
#: cylinder in axisymmetry, which is also the 3D cylinder's continuum answer (``taylor_fem.py
#: 8 16 32 --case taylor_axisymmetric``: 0.8130, 0.8125, 0.8123).  ``final_length_error`` is
#: a run's ``final_length_ratio`` over this, less 1.
REFERENCE_LENGTH_RATIO = {"taylor": 0.8100, "taylor-x2": 0.8100, "taylor-axi": 0.8123,
                          "taylor-axi-x2": 0.8123, "taylor3d": 0.8123, "taylor3d-x2": 0.8123}
#: the problems run as the quarter of their cylinder
#: (:func:`impactsph.geometry.quarter_cylinder_case`; the geometry's overrides applied first,
#: the particles written under OUT/particles)
QUARTERED = ("taylor3d-x2",)
#: the problems a plain ``impactsph lab`` leaves out (each run hours on this machine): they
#: run when named with ``--problem``
LONG = ("cantilever-x2", "taylor3d-x2")
#: the problems a plain ``impactsph lab`` runs
DEFAULT_PROBLEMS = [p for p in PROBLEMS if p not in LONG]
#: what every row shows besides the problem's measures
COMMON = ["total_energy_relative_error", "momentum_drift", "wall_constraint_events",
          "ms_per_step"]


def plan(problems: list[str], schemes: list[str], extra: list[str] | None = None
         ) -> list[tuple[str, str, str, list[str]]]:
    """``(problem, scheme, case, overrides)`` of every run of the grid."""
    for name in problems:
        if name not in PROBLEMS:
            raise ValueError(f"problem {name!r}: one of {', '.join(PROBLEMS)}")
    for name in schemes:
        if name not in SCHEMES:
            raise ValueError(f"scheme {name!r}: one of {', '.join(map(repr, SCHEMES))}")
    runs = []
    for problem in problems:
        case, overrides, _ = PROBLEMS[problem]
        base = read_case_dict(case)
        for scheme in schemes:
            runs.append((problem, scheme, case, [*overrides, *SCHEMES[scheme](base),
                                                 "output.figures=false", *(extra or [])]))
    return runs


def run_name(problem: str, scheme: str) -> str:
    """The run directory's name: ``PROBLEM--SCHEME`` in file-name characters."""
    keep = "".join(c if c.isalnum() or c in "-._" else "_" for c in scheme)
    return f"{problem}--{keep}".replace("__", "_")


def row_of(problem: str, scheme: str, summary: dict[str, Any], status: str | None
           ) -> dict[str, Any]:
    """One row of the table from a run's summary (``status``: the sweep's, else the
    summary's in the sweep's words: ``ok`` for a finished run).  ``final_length_error`` is
    measured only for a run that reached the reference's time, the built-in case's end (a
    run shortened with ``--set time.end`` had been compared with the length at 50 us)."""
    steps = summary.get("n_steps") or 0
    if status is None and summary:
        status = ("ok" if summary.get("status") == "finished" and not summary.get("failure")
                  else summary.get("status"))
    row = {"problem": problem, "scheme": scheme, "status": status,
           "ms_per_step": (1e3 * summary["wall_seconds"] / steps
                           if steps and summary.get("wall_seconds") else None)}
    for key in [*PROBLEMS[problem][2], *COMMON]:
        if key != "ms_per_step":
            row[key] = summary.get(key)
    if "final_length_error" in row:
        ratio, t_end = summary.get("final_length_ratio"), summary.get("t_end")
        reference_end = float(read_case_dict(PROBLEMS[problem][0])["time"]["end"])
        reached = t_end is not None and abs(t_end - reference_end) <= 1e-9 * reference_end
        row["final_length_error"] = (ratio / REFERENCE_LENGTH_RATIO[problem] - 1.0
                                     if ratio is not None and reached else None)
    return row


def base_case(problem: str, out: Path) -> dict[str, Any]:
    """The case dict a problem's runs start from: its built-in case, or for a problem of
    QUARTERED that case with the problem's geometry overrides applied and cut to the quarter
    of its cylinder (the particle file under ``out/particles``)."""
    case, overrides, _ = PROBLEMS[problem]
    base = read_case_dict(case)
    if problem in QUARTERED:
        geometry = [o for o in overrides if o.startswith("bodies.0.geometry.")]
        base = quarter_cylinder_case(apply_overrides(base, geometry), out / "particles")
    return base


def run_lab(out: Path | str, problems: list[str] | None = None,
            schemes: list[str] | None = None, *, workers: int | None = None,
            scheduler: str | None = None, extra: list[str] | None = None,
            report_only: bool = False) -> list[dict[str, Any]]:
    """Run (or, ``report_only``, tabulate) the grid into ``out``; returns the rows."""
    from .sweep import run_many

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise CaseError(f"--out {out} is a file, not a directory")
    runs = plan(problems or DEFAULT_PROBLEMS, schemes or list(SCHEMES), extra)
    statuses: dict[str, str | None] = {}
    if not report_only:  # every run on one cluster, so that several problems run side by side
        bases = {problem: base_case(problem, out) for problem, _, _, _ in runs}
        names = [run_name(problem, scheme) for problem, scheme, _, _ in runs]
        result = run_many([bases[problem] for problem, _, _, _ in runs], [r[3] for r in runs],
                          out, workers=workers, scheduler=scheduler, names=names)
        for name, r in zip(names, result, strict=True):
            statuses[name] = r.get("status")
    rows = []
    for problem, scheme, _, _ in runs:
        name = run_name(problem, scheme)
        path = out / "runs" / name
        if report_only and not (path / "case.json").exists():
            continue  # (not run: no row, rather than a row of blanks)
        summary = load_run(path).get("summary", {}) if (path / "case.json").exists() else {}
        rows.append(row_of(problem, scheme, summary, statuses.get(name)))
    if report_only and not rows:
        raise CaseError(f"--report-only: {out} holds no run of these problems and schemes "
                        f"(runs/PROBLEM--SCHEME); run the lab first")
    # with what made it: the versions and the command (its --set, --problem, --scheme)
    write_study(out / "lab.json", {"rows": rows})
    atomic_write_text(out / "lab.md", markdown(rows))
    return rows


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "" if value is None else str(value)


def markdown(rows: list[dict[str, Any]]) -> str:
    """A table per problem: a row per scheme."""
    lines = []
    for problem in dict.fromkeys(r["problem"] for r in rows):
        cols = ["scheme", *PROBLEMS[problem][2], *COMMON, "status"]
        lines += [f"### {problem}", "", "| " + " | ".join(cols) + " |",
                  "|" + "---|" * len(cols)]
        for r in rows:
            if r["problem"] == problem:
                lines.append("| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
        lines.append("")
    return "\n".join(lines)
