"""The 3D Taylor cylinder (``examples/taylor3d.toml``, the defaults) at several resolutions,
as a quarter with two symmetry planes (4 times cheaper; ``tests/test_symmetry.py``: it
equals the whole cylinder to round-off) or whole.  Writes
``runs/validation/taylor3d/taylor3d.json`` and prints a Markdown table.

    .venv/bin/python validation/taylor3d.py --factors 1 2 --quarter
    .venv/bin/python validation/taylor3d.py --factors 1 --set 'viscosity.scheme="av"'
    .venv/bin/python validation/taylor3d.py --factors 1 2 --quarter --arrangement rings

Factor k divides the spacing by k: x1 is the example's 0.368 mm (22,908 particles whole),
x2 0.184 mm (183,000 whole, 45,800 as a quarter).  The example's viscosity is AC's pairwise
form since 2026-12-03 (the paper's AC blows up at x2); ``--set 'viscosity.scheme="ac"'``
runs the paper's, as the rows of docs/validation.md marked AC were.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _args import positive_int  # noqa: E402
from taylor_measured import quarter  # noqa: E402

from impactsph.loading import read_case_dict  # noqa: E402
from impactsph.output import load_run, write_study  # noqa: E402
from impactsph.sweep import run_many  # noqa: E402

KEYS = ["final_length_ratio", "footprint_radius_ratio", "footprint_radius_ratio_fixed",
        "initial_radius", "plastic_work",
        "kinetic_energy_initial", "total_energy_relative_error", "momentum_drift",
        "wall_constraint_events", "n_steps", "wall_seconds"]


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--factors", nargs="+", type=positive_int, default=[1, 2])
    parser.add_argument("--quarter", action="store_true")
    parser.add_argument("--set", dest="sets", action="append", default=[],
                        help="an override for every run (key=value)")
    parser.add_argument("--arrangement", choices=("lattice", "rings"), default=None,
                        help="the cylinder's particles (bodies.0.geometry.arrangement; "
                        "default: the example's)")
    parser.add_argument("--out", type=Path, default=Path("runs/validation/taylor3d"))
    args = parser.parse_args()
    rows = []
    for factor in args.factors:
        case = read_case_dict(HERE.parent / "examples" / "taylor3d.toml")
        g = case["bodies"][0]["geometry"]
        g["spacing"] = g["spacing"] / factor
        if args.arrangement is not None:
            g["arrangement"] = args.arrangement
        arrangement = g.get("arrangement", "lattice")
        case["output"] = {"snapshot_times": [case["time"]["end"]], "figures": False}
        if args.quarter:
            case = quarter(case, args.out / "particles")
        name = (f"x{factor}" + ("-quarter" if args.quarter else "")
                + ("-rings" if arrangement == "rings" else ""))
        row = run_many(case, [args.sets], args.out, workers=1, names=[name])[0]
        summary = load_run(args.out / "runs" / row["run"]).get("summary", {})
        rows.append({"run": name, "n_particles": summary.get("n_particles"),
                     "plastic_work_over_ke0": (summary.get("plastic_work") or 0.0)
                     / max(summary.get("kinetic_energy_initial") or 1.0, 1e-300),
                     # the fixed-band radius in mm, beside the finite elements' (6.82 mm)
                     "fixed_radius_mm": 1e3 * (summary.get("footprint_radius_ratio_fixed") or 0.0)
                     * (summary.get("initial_radius") or 0.0),
                     **{k: summary.get(k) for k in KEYS}})
    args.out.mkdir(parents=True, exist_ok=True)
    write_study(args.out / "taylor3d.json", rows)
    cols = ["run", "n_particles", "final_length_ratio", "footprint_radius_ratio",
            "footprint_radius_ratio_fixed", "fixed_radius_mm", "plastic_work_over_ke0",
            "total_energy_relative_error", "momentum_drift",
            "wall_constraint_events", "n_steps", "wall_seconds"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c])
                                for c in cols) + " |")


if __name__ == "__main__":
    main()
