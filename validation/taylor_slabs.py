"""Where the Taylor bar's material ends up: the volume of the deformed bar in slabs of fixed
height above the wall, for SPH runs and for the finite-element reference, side by side.

The footprint measures (``footprint_*_ratio``) read the outermost particle's centre plus half
a spacing. Where a foot spreads in 3D, its rim ring is stretched round the circumference (a
foot twice the bar's radius doubles the distance between the rim's particles along it), and
the outermost centre then says little about where the material is. The volume of a slab
does not depend on how the particles are spread within it, and it converges as the
resolution rises where the shape does (docs/validation.md, "Taylor bar in 3D").

    .venv/bin/python validation/taylor_slabs.py RUN_DIR [RUN_DIR ...] --fem FEM.json
    .venv/bin/python validation/taylor_slabs.py RUNS... --edges 0 1 2 4 8 30 (mm)

Each ``RUN_DIR`` is a finished run of a Taylor case: plane strain (``taylor``, the volume
per unit depth, m^2), axisymmetric (``taylor_axisymmetric``) or 3D (``examples/taylor3d.toml``,
whole or a quarter with symmetry planes; the volume of the whole bar). The particles' volumes
are ``m / rho`` (axisymmetric: ``2 pi r m / rho``, its mass being per radian and its density
``rho r``, per radian and per unit area of the r-z plane), binned by the height of their
centres above the wall, which these cases put at 0. ``--fem`` reads a result of
``validation/taylor_fem.py`` (``--case taylor`` for plane strain, ``--case
taylor_axisymmetric`` for the cylinder): its final outline, clipped to each slab, gives the
area (plane strain: twice the half's) or the volume of revolution.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

#: the slabs' edges above the wall (mm) unless ``--edges`` says otherwise
EDGES_MM = (0.0, 1.0, 2.0, 4.0, 8.0, 30.0)


def clip_below(polygon: np.ndarray, level: float, keep_below: bool) -> np.ndarray:
    """The part of ``polygon`` (points ``(r, z)`` in order, closed implicitly) with ``z <=
    level`` (or ``z >= level``): one Sutherland-Hodgman pass."""
    out = []
    n = len(polygon)
    for k in range(n):
        p, q = polygon[k], polygon[(k + 1) % n]
        p_in = (p[1] <= level) if keep_below else (p[1] >= level)
        q_in = (q[1] <= level) if keep_below else (q[1] >= level)
        if p_in:
            out.append(p)
        if p_in != q_in:
            t = (level - p[1]) / (q[1] - p[1])
            out.append(p + t * (q - p))
    return np.array(out).reshape(-1, 2)


def polygon_moments(polygon: np.ndarray) -> tuple[float, float]:
    """The area of a simple polygon and its first moment about the axis ``r = 0``, ``int r
    dA`` (Green's theorem; either orientation)."""
    if len(polygon) < 3:
        return 0.0, 0.0
    r, z = polygon[:, 0], polygon[:, 1]
    r2, z2 = np.roll(r, -1), np.roll(z, -1)
    cross = r * z2 - r2 * z
    area = 0.5 * cross.sum()
    moment = (cross * (r + r2)).sum() / 6.0
    sign = 1.0 if area >= 0 else -1.0
    return sign * area, sign * moment


def outline_slab_volumes(outline: np.ndarray, edges: np.ndarray,
                         axisymmetric: bool) -> np.ndarray:
    """The volume of the bar whose half-section has the outline ``outline`` (``(r, z)``, the
    axis at ``r = 0``) between each pair of ``edges`` (m): ``2 pi int r dA`` in axisymmetry,
    twice the half's area (per unit depth) in plane strain."""
    out = []
    for low, high in zip(edges[:-1], edges[1:], strict=True):
        piece = clip_below(clip_below(outline, high, True), low, False)
        area, moment = polygon_moments(piece)
        out.append(2.0 * math.pi * moment if axisymmetric else 2.0 * area)
    return np.array(out)


def particle_slab_volumes(x: np.ndarray, volume: np.ndarray, axis: int,
                          edges: np.ndarray) -> np.ndarray:
    """The particles' ``volume`` summed in the slabs between ``edges`` by the height of their
    centres along ``axis``: the lowest slab takes everything below it too (a centre pressed
    just under the wall), and nothing above the top edge is counted, as the finite-element
    outline is clipped there (until 2026-12-08 the top slab took the rest of the bar:
    ``--edges 0 1 2`` gave its 1-2 mm slab 875% more than the outline's)."""
    upper = np.asarray(edges)[1:]
    which = np.searchsorted(upper, x[:, axis], side="right")
    kept = which < len(upper)
    return np.bincount(which[kept], weights=volume[kept], minlength=len(edges) - 1)


def run_slab_volumes(run: Path, edges: np.ndarray) -> tuple[np.ndarray, dict]:
    """The final snapshot's slab volumes of a finished Taylor run, with what it is."""
    case = json.loads((run / "case.json").read_text())["case"]
    snapshots = np.load(run / "snapshots.npz")
    last = len(snapshots["times"]) - 1
    x = snapshots[f"s{last}_position"]
    mass, density = snapshots[f"s{last}_mass"], snapshots[f"s{last}_density"]
    dim = case["dimension"]
    axisymmetric = dim == 2 and case.get("two_dimensional") == "axisymmetric"
    if axisymmetric:
        volume = 2.0 * math.pi * x[:, 0] * mass / density
    else:
        volume = mass / density
    planes = sum(1 for b in case.get("boundaries", []) if b.get("type") == "symmetry")
    if not axisymmetric:
        volume = volume * 2.0**planes
    axis = dim - 1
    info = {"run": run.name, "dimension": dim, "axisymmetric": axisymmetric,
            "particles": int(len(x)), "time": float(snapshots["times"][last]),
            "symmetry_planes": planes}
    return particle_slab_volumes(x, volume, axis, edges), info


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--fem", type=Path, action="append", default=[],
                        help="a validation/taylor_fem.py result (.json); may repeat")
    parser.add_argument("--edges", type=float, nargs="+", default=list(EDGES_MM),
                        help="the slabs' edges above the wall (mm)")
    args = parser.parse_args()
    edges = np.array(args.edges) * 1e-3
    rows = []  # (label, volumes, unit: m^3 -> mm^3, or plane strain's m^2 -> mm^2)
    for run in args.runs:
        volumes, info = run_slab_volumes(run, edges)
        plane = info["dimension"] == 2 and not info["axisymmetric"]
        label = "axisymmetric" if info["axisymmetric"] else f"{info['dimension']}D"
        rows.append((f"{run.name} ({label}, {info['particles']} particles)", volumes,
                     1e6 if plane else 1e9))
    for path in args.fem:
        result = json.loads(path.read_text())
        axisymmetric = bool(result.get("axisymmetric"))
        volumes = outline_slab_volumes(np.array(result["boundary_final"]), edges, axisymmetric)
        rows.append((f"{path.name} (finite elements, {result['n_across']} across)", volumes,
                     1e9 if axisymmetric else 1e6))
    reference = rows[-1][1] if args.fem else None
    heads = [f"{a:g}-{b:g} mm" for a, b in zip(args.edges[:-1], args.edges[1:], strict=True)]
    print("| run | " + " | ".join(heads) + " | total |")
    print("|---|" + "---|" * (len(heads) + 1))
    for name, volumes, unit in rows:
        cells = []
        for k, value in enumerate(volumes):
            cell = f"{value * unit:.1f}"
            if reference is not None and volumes is not reference and reference[k] > 0:
                cell += f" ({100 * (value / reference[k] - 1):+.1f}%)"
            cells.append(cell)
        print(f"| {name} | " + " | ".join(cells) + f" | {volumes.sum() * unit:.1f} |")
    print("(mm^3; plane strain: mm^2, the volume per unit depth; in brackets against the "
          "last finite-element result)")


if __name__ == "__main__":
    main()
