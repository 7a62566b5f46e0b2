"""The acceleration correction's width as a studied parameter (issue 15, docs/dissipation.md):
for h_c / dx from 0.5 to 1.2, each reading of eq 34, the lattice's weights and the surviving
fractions of a smooth and of the 2 dx viscous acceleration, then AC and its pairwise form on
the paper's bars and Taylor bar at each width.

    .venv/bin/python validation/correction_width.py --lattice-only     # the table, no runs
    .venv/bin/python validation/correction_width.py --problems bars taylor --workers 2

Writes runs/validation/correction-width/width.json and prints Markdown tables.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from impactsph.loading import read_case_dict
from impactsph.models.viscosity.correction import VARIANTS, surviving_fraction, weight_sum
from impactsph.output import load_run, write_study
from impactsph.sweep import run_many

WIDTHS = [0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2]  # h_c / dx
KEYS = {"bars": ["kinetic_energy_ratio_final", "velocity_profile_l1_error",
                 "velocity_profile_oscillation", "total_energy_relative_error"],
        "taylor": ["final_length_ratio", "footprint_half_width_ratio", "plastic_work",
                   "total_energy_relative_error", "momentum_drift"]}


def lattice_rows(h_over_dx: float) -> list[dict]:
    rows = []
    for width in WIDTHS:
        for dim in (1, 2, 3):
            own, others = weight_sum(dim, h_over_dx, width / h_over_dx)
            row = {"h_c/dx": width, "dim": dim, "w_ii": own, "sum_j w_ij": others}
            for variant in sorted(VARIANTS):
                for mode in ("uniform", "2dx"):
                    row[f"{variant} {mode}"] = surviving_fraction(variant, dim, h_over_dx,
                                                                  width / h_over_dx, mode)
            rows.append(row)
    return rows


def table(rows: list[dict], cols: list[str]) -> str:
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        lines.append("| " + " | ".join(f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c])
                                        for c in cols) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--problems", nargs="+", default=["bars", "taylor"],
                        choices=sorted(KEYS))
    parser.add_argument("--variants", nargs="+", default=sorted(VARIANTS),
                        choices=sorted(VARIANTS))
    parser.add_argument("--schemes", nargs="+", default=["ac", "ac_pairwise"])
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--lattice-only", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("runs/validation/correction-width"))
    args = parser.parse_args()
    lattice = lattice_rows(1.2)
    cols = ["h_c/dx", "dim", "w_ii", "sum_j w_ij",
            *[f"{v} {m}" for v in sorted(VARIANTS) for m in ("uniform", "2dx")]]
    print("Lattice (h = 1.2 dx; the fractions depend on h_c / dx only):\n")
    print(table(lattice, cols))
    result = {"lattice": lattice, "runs": []}
    if not args.lattice_only:
        for problem in args.problems:
            base = read_case_dict(problem)
            h_over_dx = float(base["kernel"]["h_over_dx"])
            labels, overrides = [], []
            for scheme in args.schemes:
                for variant in args.variants:
                    for width in WIDTHS:
                        labels.append((scheme, variant, width))
                        overrides.append([f'viscosity.scheme="{scheme}"',
                                          f'viscosity.correction="{variant}"',
                                          f"viscosity.correction_h_ratio={width / h_over_dx!r}",
                                          "output.figures=false"])
            out = args.out / problem
            rows = run_many(base, overrides, out, workers=args.workers)
            runs = []
            for (scheme, variant, width), row in zip(labels, rows, strict=True):
                summary = load_run(out / "runs" / row["run"]).get("summary", {})
                runs.append({"problem": problem, "scheme": scheme, "variant": variant,
                             "h_c/dx": width, "status": row.get("status"),
                             **{k: summary.get(k) for k in KEYS[problem]}})
            print(f"\n{problem}:\n")
            print(table(runs, ["scheme", "variant", "h_c/dx", *KEYS[problem], "status"]))
            result["runs"] += runs
    args.out.mkdir(parents=True, exist_ok=True)
    write_study(args.out / "width.json", result)


if __name__ == "__main__":
    main()
