"""The cost in accuracy of records in float32 (``compute.record_precision = "float32"``):
the paper's bars (1D, against 1D bar theory) and Taylor bar (2D) at two resolutions, each run
with float64 and with float32 records, the problems' measures side by side, how far the
records' precision moves each one and how far the resolution does.  Writes
``runs/validation/record-precision/record_precision.json`` and prints Markdown tables.

    .venv/bin/python validation/record_precision.py [--cases bars taylor] [--workers 2]
        [--factors 1 2]

The claim it tests (docs/gpu.md, "Records in float32"): at each resolution the precision
moves every measure much less than the resolution does, so a float32 run's answer is the
float64 run's to within the discretisation's own uncertainty; beside it, how far a change in
the 12th digit of the velocities moves each measure in float64 (round-off's own reach) and in
float32 (the float32 run's own reach: where it is as large as float32's change from float64,
that change is the run's sensitivity, not the records' error).  The
bars run with the paper's AV (0.3, 0.3) and with AC; the Taylor bar with AC (its plastic flow
amplifies any difference in the particles' paths, so its measures are where float32 shows
first).  About 8 minutes on two cores (the Taylor bar at twice the resolution is most of
it).  A run already in ``--out`` with the same configuration is reused
(:func:`impactsph.sweep.run_many`): remove the folder to measure a change of the code.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from _args import positive_int

from impactsph.loading import read_case_dict
from impactsph.output import load_run, write_study
from impactsph.sweep import run_many

KEYS = {
    "bars": ["velocity_profile_l1_error", "velocity_profile_oscillation",
             "mid_velocity_l1_error", "contact_time_us", "total_energy_relative_error"],
    "taylor": ["final_length_ratio", "footprint_half_width_ratio",
               "footprint_half_width_ratio_fixed", "plastic_work",
               "total_energy_relative_error"],
}
SCHEMES = {
    "bars": {"AV (0.3, 0.3)": ['viscosity.scheme="av"', "viscosity.alpha1=0.3",
                               "viscosity.alpha2=0.3"],
             "AC": ['viscosity.scheme="ac"']},
    "taylor": {"AC": ['viscosity.scheme="ac"']},
}
#: the runs of each (scheme, resolution): float64 and float32 records, and each with every
#: body's velocity 1e-12 larger (relative), which shows how far round-off alone moves a measure
#: (the Taylor bar's plastic flow amplifies any difference: at the paper's resolution a
#: change of the impact speed in its 12th digit moves its length by 1e-4 to 3e-4), in float64
#: and in float32 (where a difference of float32's size may cross a threshold, a yield or a
#: list's reach, that the nudge does not)
PRECISIONS = ("float64", "float32", "float64, v + 1e-12", "float32, v + 1e-12")


def nudged(base: dict) -> list[str]:
    """Overrides that make every body's velocity larger by 1e-12 of itself."""
    return [f"bodies.{k}.velocity={json.dumps([v * (1.0 + 1e-12) for v in body['velocity']])}"
            for k, body in enumerate(base["bodies"])]


def refined(base: dict, factor: int) -> list[str]:
    """Overrides that divide every body's spacing by ``factor`` (a count: multiply it)."""
    out = []
    for k, body in enumerate(base["bodies"]):
        geometry = body["geometry"]
        if "count" in geometry:
            count = [c * factor for c in geometry["count"]]
            out.append(f"bodies.{k}.geometry.count={json.dumps(count)}")
        else:
            out.append(f"bodies.{k}.geometry.spacing={geometry['spacing'] / factor!r}")
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--cases", nargs="+", default=sorted(KEYS), choices=sorted(KEYS))
    parser.add_argument("--factors", nargs="+", type=positive_int, default=[1, 2],
                        help="particle-count multipliers per direction (default: 1 2)")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--out", type=Path, default=Path("runs/validation/record-precision"))
    args = parser.parse_args(argv)
    result = []
    for case in args.cases:
        base = read_case_dict(case)
        labels, overrides = [], []
        for scheme, ov in SCHEMES[case].items():
            for factor in args.factors:
                for run in PRECISIONS:
                    labels.append((scheme, factor, run))
                    overrides.append([*ov, *refined(base, factor), "output.figures=false",
                                      f'compute.record_precision="{run.split(",")[0]}"',
                                      *(nudged(base) if "1e-12" in run else [])])
        out = args.out / case
        rows = run_many(base, overrides, out, workers=args.workers)
        for (scheme, factor, run), row in zip(labels, rows, strict=True):
            summary = load_run(out / "runs" / row["run"]).get("summary", {})
            result.append({"case": case, "scheme": scheme, "resolution": factor,
                           "precision": run, "status": row.get("status"),
                           "n_particles": summary.get("n_particles"),
                           "steps": summary.get("n_steps"),
                           "wall_seconds": summary.get("wall_seconds"),
                           **{k: summary.get(k) for k in KEYS[case]}})
    args.out.mkdir(parents=True, exist_ok=True)
    write_study(args.out / "record_precision.json", result)
    for case in args.cases:
        rows = [r for r in result if r["case"] == case]
        cols = ["scheme", "resolution", "precision", "n_particles", "steps", *KEYS[case]]
        print(f"\n{case}\n\n| " + " | ".join(cols) + " |\n|" + "---|" * len(cols))
        for r in rows:
            print("| " + " | ".join(f"{r[c]:.6g}" if isinstance(r[c], float) else str(r[c])
                                    for c in cols) + " |")
        print("\nrelative change of each measure from float64 at each resolution: to float32 "
              "records, and to float64 with the velocities 1e-12 larger (round-off's own "
              "reach); and of float64 from one resolution to the next")
        for scheme in SCHEMES[case]:
            of = {(r["resolution"], r["precision"]): r for r in rows if r["scheme"] == scheme}
            for k in KEYS[case]:
                parts = []
                for factor in args.factors:
                    a = of[(factor, "float64")].get(k)
                    for run, label in ((PRECISIONS[1], "float32"), (PRECISIONS[2], "nudged"),
                                       (PRECISIONS[3], "float32 nudged")):
                        b = of[(factor, run)].get(k)
                        if isinstance(a, float) and isinstance(b, float) and a:
                            parts.append(f"x{factor} {label} {(b - a) / abs(a):+.2e}")
                for f1, f2 in zip(args.factors, args.factors[1:], strict=False):
                    a, b = of[(f1, "float64")].get(k), of[(f2, "float64")].get(k)
                    if isinstance(a, float) and isinstance(b, float) and a:
                        parts.append(f"x{f1} -> x{f2} resolution {(b - a) / abs(a):+.2e}")
                print(f"- {scheme}, {k}: " + ", ".join(parts))


if __name__ == "__main__":
    main()
