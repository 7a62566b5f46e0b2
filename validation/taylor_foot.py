"""The plane-strain Taylor bar's foot, snapshot by snapshot (docs/validation.md, "Why the
plane-strain footprint moves so much"): the footprint as the Taylor analysis defines it (the
particles within one spacing of the wall), the same in a band of fixed height, the widest
section of the bar, and the mean vertical speed of the foot's rim (the particles beyond
``--rim`` half-widths from the axis).

    .venv/bin/python validation/taylor_foot.py RUN_DIR [RUN_DIR ...] [--band 0.18e-3]

Each ``RUN_DIR`` is a finished run of the built-in ``taylor`` case or a variant of it (its
``snapshots.npz``), e.g. the runs of ``validation/resolution.py taylor``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from impactsph.problems.taylor import bar_measures


def spacing_of(x0: np.ndarray, axis: int) -> float:
    """The lattice spacing along ``axis`` of the initial positions."""
    levels = np.unique(np.round(x0[:, axis], 9))
    return float(levels[1] - levels[0])


def foot_rows(run: Path, band: float, rim: float) -> list[dict[str, float]]:
    """One row per snapshot after the first two (the foot has formed by then)."""
    z = np.load(run / "snapshots.npz")
    rows = []
    for n in range(2, len(z["times"])):
        bar = z[f"s{n}_body"] == 0
        x, x0 = z[f"s{n}_position"][bar], z[f"s{n}_initial_position"][bar]
        v = z[f"s{n}_velocity"][bar]
        across, along = spacing_of(x0, 0), spacing_of(x0, 1)
        centre = x0[:, 0].mean()
        half0 = (np.ptp(x0[:, 0]) + across) / 2
        lateral = np.abs(x[:, 0] - centre)
        in_band = x[:, 1] < band
        outer = lateral > rim * half0
        rows.append({
            "particles": len(x), "t_us": float(z["times"][n]) * 1e6,
            "footprint": bar_measures(x0, x, 1, [across, along], 0.0)[
                "footprint_half_width_ratio"],
            "footprint_in_band": (float(lateral[in_band].max() + across / 2) / half0
                                  if band >= 0.99 * across and in_band.any() else float("nan")),
            "widest": float(lateral.max() + across / 2) / half0,
            "rim_vertical_speed": float(v[outer, 1].mean()) if outer.any() else float("nan"),
        })
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--band", type=float, default=0.18e-3,
                    help="height of the fixed band above the wall (m; default 0.18 mm, the "
                         "x2 spacing); not shown for a run whose spacing is larger")
    ap.add_argument("--rim", type=float, default=1.6,
                    help="the rim: particles beyond this many initial half-widths")
    args = ap.parse_args()
    print("| run | particles | t (us) | footprint | in the fixed band | widest | rim speed "
          "(m/s) |")
    print("|---|---|---|---|---|---|---|")
    for run in args.runs:
        for r in foot_rows(run, args.band, args.rim):
            print(f"| {run.name} | {r['particles']} | {r['t_us']:.0f} | {r['footprint']:.3f} | "
                  f"{r['footprint_in_band']:.3f} | {r['widest']:.3f} | "
                  f"{r['rim_vertical_speed']:+.1f} |")


if __name__ == "__main__":
    main()
