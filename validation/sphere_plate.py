"""The steel sphere into an aluminium plate of ``examples/sphere_plate3d.toml`` at several
spacings, whole or as a quarter with two symmetry planes through the impact axis (the plate
a quarter block, the sphere's quarter read from a file).  Writes
``runs/validation/sphere-plate/sphere_plate.json`` and prints a Markdown table.

    .venv/bin/python validation/sphere_plate.py --spacings 0.5e-3 0.25e-3 --quarter
"""

from __future__ import annotations

import argparse
from pathlib import Path

from impactsph.geometry import quarter_file_geometry, quarter_planes, sphere_particles
from impactsph.loading import read_case_dict
from impactsph.output import load_run, write_study
from impactsph.sweep import run_many

HERE = Path(__file__).resolve().parent
KEYS = ["n_particles", "residual_velocity", "residual_velocity_ratio", "hole_diameter",
        "ejected_plate_mass_fraction", "perforated", "total_energy_relative_error", "n_steps",
        "wall_seconds"]


def quarter(case: dict, folder: Path) -> dict:
    """The quarter x > 0, y > 0: the sphere's particles in a file, the plate a quarter block,
    two symmetry planes through the axis."""
    sphere = case["bodies"][0]["geometry"]
    particles = sphere_particles(sphere["centre"], sphere["radius"], sphere["spacing"])
    case["bodies"][0]["geometry"] = quarter_file_geometry(
        particles, folder / f"sphere-{sphere['spacing']:.4e}-quarter.npz")
    plate = case["bodies"][1]["geometry"]
    plate["size"] = [plate["size"][0] / 2, plate["size"][1] / 2, plate["size"][2]]
    plate["origin"] = [0.0, 0.0, plate["origin"][2]]
    case["boundaries"] = quarter_planes()
    return case


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--spacings", nargs="+", type=float, default=[0.5e-3])
    parser.add_argument("--quarter", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("runs/validation/sphere-plate"))
    args = parser.parse_args()
    rows = []
    for spacing in args.spacings:
        case = read_case_dict(HERE.parent / "examples" / "sphere_plate3d.toml")
        for body in case["bodies"]:
            body["geometry"]["spacing"] = spacing
        case["output"] = {"snapshot_times": [case["time"]["end"]], "figures": False}
        if args.quarter:
            case = quarter(case, args.out / "particles")
        name = f"dx{spacing * 1e3:g}mm" + ("-quarter" if args.quarter else "")
        row = run_many(case, [[]], args.out, workers=1, names=[name])[0]
        summary = load_run(args.out / "runs" / row["run"]).get("summary", {})
        rows.append({"run": name, **{k: summary.get(k) for k in KEYS}})
    args.out.mkdir(parents=True, exist_ok=True)
    write_study(args.out / "sphere_plate.json", rows)
    cols = ["run", *KEYS]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c])
                                for c in cols) + " |")


if __name__ == "__main__":
    main()
