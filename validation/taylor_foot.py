"""The plane-strain Taylor bar's foot, snapshot by snapshot (docs/validation.md, "Why the
plane-strain footprint moves so much"): the footprint as the Taylor analysis defines it (the
particles within one spacing of the wall), the same in its fixed band
(``footprint_half_width_ratio_fixed``: lower surfaces within 0.05 B/2 of the wall), the same
with particle centres in a band of a given height (``--band``), the widest
section of the bar, and the mean vertical speed of the foot's rim (the particles beyond
``--rim`` half-widths from the axis).

    .venv/bin/python validation/taylor_foot.py RUN_DIR [RUN_DIR ...] [--band 0.18e-3]
    .venv/bin/python validation/taylor_foot.py RUN_DIR ... --fem FEM_DIR/taylor-64.json
    .venv/bin/python validation/taylor_foot.py RUN_DIR ... --figure foot.png

With ``--fem`` (a result of ``validation/taylor_fem.py --out FEM_DIR``, whose final outline
it reads) it also prints the height of the foot's lower surface above the wall at the end
of each run, at radii from 4 to 9.5 mm, beside the finite-element one: for the particles, the lowest
centre within one spacing of that distance from the axis, less half a spacing (on a surface
that rises at a slope s this reads low by up to s times a spacing; a window of half a spacing
would not, but reads a hole in the foot's lowest row, where the tensile instability opens
them, as a bump); for the finite elements, the bottom row of nodes interpolated.

Each ``RUN_DIR`` is a finished run of the built-in ``taylor`` case or a variant of it (its
``snapshots.npz``), e.g. the runs of ``validation/resolution.py taylor``.
"""

from __future__ import annotations

import argparse
import json
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
        measures = bar_measures(x0, x, 1, [across, along], 0.0)
        rows.append({
            "particles": len(x), "t_us": float(z["times"][n]) * 1e6,
            "footprint": measures["footprint_half_width_ratio"],
            "footprint_fixed": measures["footprint_half_width_ratio_fixed"],
            "footprint_in_band": (float(lateral[in_band].max() + across / 2) / half0
                                  if band >= 0.99 * across and in_band.any() else float("nan")),
            "widest": float(lateral.max() + across / 2) / half0,
            "rim_vertical_speed": float(v[outer, 1].mean()) if outer.any() else float("nan"),
        })
    return rows


#: where the lower surface is compared (m from the axis)
RADII = np.arange(4.0e-3, 9.6e-3, 0.5e-3)


def lower_surface(run: Path) -> np.ndarray:
    """The foot's lower surface at :data:`RADII` at the run's last snapshot (m above the
    wall; nan where no particle is that far out)."""
    z = np.load(run / "snapshots.npz")
    n = len(z["times"]) - 1
    bar = z[f"s{n}_body"] == 0
    x, x0 = z[f"s{n}_position"][bar], z[f"s{n}_initial_position"][bar]
    across, along = spacing_of(x0, 0), spacing_of(x0, 1)
    r = np.abs(x[:, 0] - x0[:, 0].mean())
    out = np.full(RADII.shape, np.nan)
    for k, radius in enumerate(RADII):
        near = np.abs(r - radius) < across
        if near.any():
            out[k] = x[near, 1].min() - along / 2
    return out


def fem_lower_surface(path: Path) -> np.ndarray:
    """The finite-element bar's lower surface (its bottom row of nodes) at :data:`RADII`."""
    result = json.loads(path.read_text())
    bottom = np.array(result["boundary_final"])[: result["n_across"] + 1]
    return np.interp(RADII, bottom[:, 0], bottom[:, 1], right=np.nan)


def foot_figure(runs: list[Path], path: Path, height: float = 4e-3) -> Path:
    """The foot of each run at its last snapshot, a panel each: the bar's particles within
    ``height`` of the wall, coloured by their initial height above it (the colour scale
    spans the foot's particles; the chains and holes
    of the tensile instability show as columns of one colour; docs/validation.md, "The
    plane-strain foot's holes are the tensile instability")."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(runs), 1, figsize=(8.0, 2.2 * len(runs) + 0.6),
                             squeeze=False, constrained_layout=True)
    for ax, run in zip(axes[:, 0], runs, strict=True):
        z = np.load(run / "snapshots.npz")
        n = len(z["times"]) - 1
        bar = z[f"s{n}_body"] == 0
        x, x0 = z[f"s{n}_position"][bar], z[f"s{n}_initial_position"][bar]
        foot = x[:, 1] < height
        dots = ax.scatter(x[foot, 0] * 1e3, x[foot, 1] * 1e3, c=x0[foot, 1] * 1e3, s=4,
                          cmap="viridis", vmin=0.0, vmax=float(x0[foot, 1].max()) * 1e3)
        ax.set_aspect("equal")
        ax.set_title(f"{run.name}: t = {float(z['times'][n]) * 1e6:.0f} us", fontsize=9)
        ax.set_ylabel("height (mm)")
        fig.colorbar(dots, ax=ax, label="initial height (mm)", shrink=0.9)
    axes[-1, 0].set_xlabel("x (mm)")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--band", type=float, default=0.18e-3,
                    help="height of the fixed band above the wall (m; default 0.18 mm, the "
                         "x2 spacing); not shown for a run whose spacing is larger")
    ap.add_argument("--rim", type=float, default=1.6,
                    help="the rim: particles beyond this many initial half-widths")
    ap.add_argument("--fem", type=Path, default=None,
                    help="a finite-element result (validation/taylor_fem.py's JSON) to "
                         "compare the foot's lower surface with")
    ap.add_argument("--figure", type=Path, default=None,
                    help="draw each run's foot at its last snapshot, coloured by the "
                         "particles' initial height, into this PNG")
    args = ap.parse_args()
    if args.figure is not None:
        print(f"figure: {foot_figure(args.runs, args.figure)}")
    print("| run | particles | t (us) | footprint | fixed (0.05 B/2) | centres in the band | "
          "widest | rim speed (m/s) |")
    print("|---|---|---|---|---|---|---|---|")
    for run in args.runs:
        for r in foot_rows(run, args.band, args.rim):
            print(f"| {run.name} | {r['particles']} | {r['t_us']:.0f} | {r['footprint']:.3f} | "
                  f"{r['footprint_fixed']:.3f} | {r['footprint_in_band']:.3f} | "
                  f"{r['widest']:.3f} | "
                  f"{r['rim_vertical_speed']:+.1f} |")

    if args.fem is not None:
        fem = fem_lower_surface(args.fem)
        print("\n| r (mm) | " + " | ".join(run.name for run in args.runs)
              + f" | finite elements ({args.fem.name}) |")
        print("|---" * (len(args.runs) + 2) + "|")
        surfaces = [lower_surface(run) for run in args.runs]
        for k, radius in enumerate(RADII):
            print(f"| {radius * 1e3:.1f} | " + " | ".join(f"{s[k] * 1e3:.3f}" for s in surfaces)
                  + f" | {fem[k] * 1e3:.3f} |")


if __name__ == "__main__":
    main()
