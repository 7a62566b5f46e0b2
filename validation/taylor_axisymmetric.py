"""The Taylor bar in 2D axisymmetry (the built-in case ``taylor_axisymmetric``) at several
resolutions, beside the 3D cylinder of ``examples/taylor3d.toml`` (docs/validation.md,
"Taylor bar in axisymmetry").  Prints a Markdown table and writes
``runs/validation/taylor_axisymmetric/taylor_axisymmetric.json``.

    .venv/bin/python validation/taylor_axisymmetric.py --factors 1 2 4
    .venv/bin/python validation/taylor_axisymmetric.py --set 'viscosity.scheme="ac_pairwise"'

Factor k divides the spacing by k: x1 is 10 x 69 particles (dr = 0.38 mm, dz = 0.368 mm,
the 3D example's spacing), x2 20 x 138, x4 40 x 276 (about 20 s and 2 min on 2 threads).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from _args import positive_int

from impactsph.loading import load_case
from impactsph.output import write_study
from impactsph.runner import run_case

KEYS = ["n_particles", "n_steps", "final_length_ratio", "footprint_radius_ratio",
        "footprint_radius_ratio_fixed", "plastic_work", "kinetic_energy_ratio_final",
        "total_energy_relative_error", "momentum_drift", "wall_seconds"]


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--factors", nargs="+", type=positive_int, default=[1, 2])
    parser.add_argument("--set", dest="sets", action="append", default=[],
                        help="an override for every run (key=value)")
    parser.add_argument("--out", type=Path, default=Path("runs/validation/taylor_axisymmetric"))
    args = parser.parse_args()
    rows = {}
    for k in args.factors:
        case = load_case("taylor_axisymmetric", [f"bodies.0.geometry.count=[{10 * k}, {69 * k}]",
                                   "output.snapshot_times=[50e-6]", *args.sets])
        summary = run_case(case, args.out / f"x{k}", figures=False, if_exists="overwrite")
        rows[f"x{k}"] = {key: summary.get(key) for key in KEYS}
    args.out.mkdir(parents=True, exist_ok=True)
    write_study(args.out / "taylor_axisymmetric.json", {"sets": args.sets, "runs": rows})
    print("| run | " + " | ".join(KEYS) + " |")
    print("|---" * (len(KEYS) + 1) + "|")
    for name, row in rows.items():
        cells = [f"{v:.4g}" if isinstance(v, float) else str(v) for v in row.values()]
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
