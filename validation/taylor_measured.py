"""Taylor cylinder impacts against measured final lengths and foot diameters: the 3D cylinder
of ``examples/taylor3d.toml`` (a free-slip rigid wall, the defaults) with the paper's AC
viscosity, made of a library material (Johnson-Cook strength, Mie-Gruneisen or linear EOS,
``impactsph materials``) with the size and speed of each test in
``validation/taylor_measured.toml``, at two resolutions (particles across the diameter).  Writes
``runs/validation/taylor-measured/taylor_measured.json`` and prints a Markdown table.

    .venv/bin/python validation/taylor_measured.py                      # the default tests
    .venv/bin/python validation/taylor_measured.py --across 10 20 --all --workers 2
    .venv/bin/python validation/taylor_measured.py --across 20 30 --quarter   # 2 symmetry planes
    .venv/bin/python validation/taylor_measured.py --across 20 40 80 --axisymmetric  # 2D r-z

Default tests: OFHC copper at 190 m/s (Johnson & Cook 1983, as read by Zerilli & Armstrong
1987) and 4340 steel at 208 m/s (Johnson & Cook 1983).  Johnson-Cook damage is switched off
(``damage = "none"``): these bars do not break, and the measured shapes are of whole bars.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from pathlib import Path

import numpy as np
from _args import positive_int

from impactsph.geometry import quarter_cylinder_case as quarter
from impactsph.loading import read_case_dict
from impactsph.output import load_run, write_study
from impactsph.sweep import run_many

HERE = Path(__file__).resolve().parent
DEFAULT = [("ofhc_copper", 190.0), ("steel_4340", 208.0)]


def _number(value: object) -> float:
    """A summary's measure as a float: NaN for one not taken (``null`` in summary.json)."""
    return float(value) if isinstance(value, int | float) else math.nan


def tests(select_all: bool) -> list[dict]:
    entries = tomllib.loads((HERE / "taylor_measured.toml").read_text())["test"]
    found = [t for t in entries if t.get("final_length") is not None]
    if select_all:
        return found
    return [t for t in found if (t["material"], t["velocity"]) in DEFAULT]


def axisymmetric(case: dict) -> dict:
    """The case's cylinder as its half-section in 2D axisymmetry (x the radius, y the axis;
    docs/modelling.md, "Axisymmetry"): ``across / 2`` particles across the radius, the same
    layers, the wall at y = 0."""
    g = case["bodies"][0]["geometry"]
    layers = round(g["length"] / g["spacing"])
    across = round(2.0 * g["radius"] / g["spacing"])
    case["dimension"] = 2
    case["two_dimensional"] = "axisymmetric"
    case["bodies"][0]["geometry"] = {"origin": [0.0, 0.0], "size": [g["radius"], g["length"]],
                                     "count": [max(1, across // 2), layers]}
    case["bodies"][0]["velocity"] = case["bodies"][0]["velocity"][1:]
    case["boundaries"] = [{"type": "wall", "point": [0.0, 0.0], "normal": [0.0, 1.0],
                           "slip": "free"}]
    return case


def case_of(test: dict, across: int, end: float) -> dict:
    base = read_case_dict(HERE.parent / "examples" / "taylor3d.toml")
    base["name"] = f"taylor-{test['material']}-{test['velocity']:.0f}"
    base["description"] = f"Taylor test: {test['source']}"
    base["materials"] = {"bar": {"library": test["material"], "damage": "none"}}
    body = base["bodies"][0]
    body["material"] = "bar"
    body["velocity"] = [0.0, 0.0, -float(test["velocity"])]
    geometry = body["geometry"]
    geometry["radius"] = test["diameter"] / 2.0
    geometry["length"] = test["length"]
    layers = round(test["length"] / (test["diameter"] / across))
    geometry["spacing"] = test["length"] / layers
    base["time"]["end"] = end
    base["output"] = {"snapshot_times": [end], "figures": False}
    # the paper's AC, with which docs/validation.md's rows were run (the example itself runs
    # AC's pairwise form since 2026-12-03); --set 'viscosity.scheme="..."' picks another
    base["viscosity"] = {"scheme": "ac"}
    # and the fixed kernel (the example's "auto" grows it where the bar spreads since
    # 2026-12-03); --set 'kernel.max_stretch="auto"' gives the defaults
    base["kernel"]["max_stretch"] = 1.0
    return base


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--across", nargs="+", type=positive_int, default=[10, 20],
                        help="particles across the diameter (default: 10 20)")
    parser.add_argument("--all", action="store_true", help="every test with measured values")
    parser.add_argument("--materials", nargs="+", default=None,
                        help="only the tests of these library materials")
    parser.add_argument("--tests", nargs="+", default=None, metavar="MATERIAL:VELOCITY",
                        help="only these tests (of every test with measured values), e.g. "
                        "ofhc_copper:210")
    parser.add_argument("--end", type=float, default=100e-6, help="end time (s)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("runs/validation/taylor-measured"))
    parser.add_argument("--set", dest="sets", action="append", default=[],
                        help="an override for every run (key=value), e.g. "
                        "'viscosity.scheme=\"av\"'")
    parser.add_argument("--quarter", action="store_true",
                        help="run the quarter with two symmetry planes (4x cheaper)")
    parser.add_argument("--axisymmetric", action="store_true",
                        help="run the half-section in 2D axisymmetry instead of the 3D cylinder")
    parser.add_argument("--report-only", action="store_true",
                        help="tabulate the runs already in --out, run nothing")
    args = parser.parse_args()
    wanted = None if args.tests is None else {
        (name.split(":")[0], float(name.split(":")[1])) for name in args.tests}
    chosen = [t for t in tests(args.all or wanted is not None)
              if (args.materials is None or t["material"] in args.materials)
              and (wanted is None or (t["material"], t["velocity"]) in wanted)]
    if not chosen:
        parser.error(f"no test with measured values matches --materials {args.materials} "
                     f"--tests {args.tests}")
    labels, names = [], []
    cases = []
    for test in chosen:
        for across in args.across:
            labels.append((test, across))
            case = case_of(test, across, args.end)
            if args.axisymmetric:
                case = axisymmetric(case)
            elif args.quarter:
                case = quarter(case, args.out / "particles")
            cases.append(case)
            names.append(f"{test['material']}-{test['velocity']:.0f}-x{across}"
                         + ("-quarter" if args.quarter else "")
                         + ("-axisymmetric" if args.axisymmetric else ""))
    # one base per test: run_many takes one base and override lists, so each case is its own
    rows = []
    for case, name in zip(cases, names, strict=True):
        if args.report_only:
            rows.append({"run": name, "status": "ok"})
        else:
            rows += run_many(case, [args.sets], args.out, workers=args.workers, names=[name])
    result = []
    for (test, across), row in zip(labels, rows, strict=True):
        summary = load_run(args.out / "runs" / row["run"]).get("summary", {})
        L0, D0 = test["length"], test["diameter"]
        # (a measure not taken is null in summary.json: NaN here)
        Lf = _number(summary.get("final_length_ratio")) * L0
        # the foot as the analysis measures it: its radius over the same measure of the bar at
        # t = 0 (each the outermost particle plus half a spacing), times the true diameter
        foot = _number(summary.get("footprint_radius_ratio")) * D0
        bar = summary.get("bodies", {}).get("bar", {})
        outline = {}
        if test.get("outline") and summary.get("profile") and "initial_radius" in summary:
            # the computed radius at the measured outline's heights, each over the measured
            # one less 1 (the profile's radius is over its initial measure, times R0)
            profile = np.array(summary["profile"])
            scale = (test["diameter"] / 2) / summary["initial_radius"]
            measured = np.array(test["outline"])
            computed = np.interp(measured[:, 1], profile[:, 0], profile[:, 1] * scale)
            errors = computed / measured[:, 0] - 1.0
            outline = {"outline_radius_error_max": float(np.max(np.abs(errors))),
                       "outline_radius_error_mean": float(np.mean(errors))}
        result.append({
            "material": test["material"], "velocity": test["velocity"], "across": across,
            "n_particles": summary.get("n_particles"), "status": row.get("status"),
            "final_length_mm": 1e3 * Lf, "measured_final_length_mm": 1e3 * test["final_length"],
            "final_length_error": Lf / test["final_length"] - 1.0,
            "foot_diameter_mm": 1e3 * foot,
            "measured_foot_diameter_mm": 1e3 * test["foot_diameter"],
            "foot_diameter_error": foot / test["foot_diameter"] - 1.0,
            "initial_diameter_mm": 1e3 * D0,
            "max_equivalent_plastic_strain": bar.get("max_equivalent_plastic_strain"),
            "max_temperature": bar.get("max_temperature"),
            "total_energy_relative_error": summary.get("total_energy_relative_error"),
            "wall_constraint_events": summary.get("wall_constraint_events"),
            "wall_seconds": summary.get("wall_seconds"), "source": test["source"],
            **outline})
    args.out.mkdir(parents=True, exist_ok=True)
    write_study(args.out / "taylor_measured.json", result)
    cols = ["material", "velocity", "across", "n_particles", "final_length_mm",
            "measured_final_length_mm", "final_length_error", "foot_diameter_mm",
            "measured_foot_diameter_mm", "foot_diameter_error", "max_equivalent_plastic_strain",
            "max_temperature", "total_energy_relative_error", "wall_constraint_events",
            "wall_seconds", "outline_radius_error_mean", "outline_radius_error_max"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in result:
        print("| " + " | ".join(
            (f"{r[c]:+.1%}" if c.endswith("_error") and c.startswith(("final", "foot"))
             else f"{r[c]:.4g}") if isinstance(r.get(c), float) else str(r.get(c))
            for c in cols) + " |")


if __name__ == "__main__":
    main()
