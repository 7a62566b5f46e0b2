"""Example 2: the Taylor bar on a rigid wall.

The paper's section 5.2 (parameters in its Table 3, figures 10-13); the runs measured in
``docs/validation.md`` (Example 2, and the Taylor bar in 3D).

Measures at the end of the run: the final length over the initial one, ``L_f / L_0``, with
the length taken as the span of the particles along the bar plus one spacing (so that it is
``L_0`` at t = 0); the half-width of the footprint on the wall over ``B/2`` (the particles
within one spacing of the wall, plus half a spacing); plastic work and kinetic energy kept.
One-dimensional theories (Taylor; Wilkins & Guinan) put ``L_f / L_0`` at about 0.75-0.87 for
this bar (the band of ``docs/validation.md``, Example 2).

In axisymmetry (x the radius) the half-width is the footprint's radius, also given as
``footprint_radius_ratio``.  In 3D (a cylinder, ``examples/taylor3d.toml``) the footprint is a
radius, measured the same way: the largest distance from the bar's axis among the particles within
one spacing of the wall, plus half a spacing, over the same measure of the whole bar at t = 0
(``footprint_radius_ratio``; 1 at t = 0, as the 2D ratio).  The axis is the line through the initial
centroid along the cylinder's ``axis``.  The footprint is also split into eight 45-degree sectors
about the axis, centred on the lateral coordinate axes and their diagonals;
``footprint_radius_ratio_min_sector`` is the smallest of their radii, so it equals
``footprint_radius_ratio`` for a round footprint and falls below it where the foot spreads unevenly.

The footprint as defined above looks in a band of one spacing, so the band's height halves
with every doubling of the resolution, and a foot whose rim curls up off the wall (as the
plane-strain bar's does, in finite elements too: docs/validation.md) has a footprint that
moves with the resolution for that reason alone.  ``footprint_half_width_ratio_fixed`` (in 3D
``footprint_radius_ratio_fixed``) is the same measure in a band of fixed height: the particles
whose lower surface (their centre less half a spacing) is within ``footprint_lift`` of the
wall, ``footprint_lift`` = :data:`FOOT_LIFT` times the initial half-width or radius (of its
lowest surface, once the bar has left the wall).  At the paper's resolution (x1: half a
spacing along the bar, 0.19 mm) the two bands are the same to 0.5%.

``profile``: the mushroom, ``[height, half-width or radius]`` in 20 slices of the final bar
(:func:`bar_profile`), to set beside a measured outline (``validation/taylor_measured.py``).
On a half or quarter model (symmetry planes) the axis is taken on the planes.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..geometry import AXES
from .base import GeometryNeeds, ProblemKind

if TYPE_CHECKING:
    from ..config import Case

#: The band of one-dimensional theory for L_f / L_0 (Taylor; Wilkins & Guinan: see the module
#: docstring).
LENGTH_RATIO_BAND = (0.75, 0.87)

#: The fixed band of the footprint ``*_fixed``: the height of the foot's lower surface above
#: the wall, over the bar's initial half-width (or radius), within which it counts as the
#: footprint (see the module docstring).
FOOT_LIFT = 0.05


def bar_measures(x0: np.ndarray, x: np.ndarray, axis: int, spacing: list[float],
                 wall_level: float, centre: np.ndarray | None = None) -> dict[str, float]:
    """Length ratio and footprint half-width ratio of a bar along ``axis`` standing on a wall
    at ``wall_level`` (initial positions ``x0``, current ``x``); ``centre``: the axis's
    lateral coordinates (default: the mean of ``x0``'s)."""
    along = spacing[axis]
    L0 = x0[:, axis].max() - x0[:, axis].min() + along
    Lf = x[:, axis].max() - x[:, axis].min() + along
    lateral = [a for a in range(x.shape[1]) if a != axis]
    if centre is None:
        centre = x0[:, lateral].mean(axis=0)
    half0 = np.max(np.linalg.norm(x0[:, lateral] - centre, axis=1)) + 0.5 * spacing[lateral[0]]
    across = spacing[lateral[0]]
    distance = np.linalg.norm(x[:, lateral] - centre, axis=1)
    foot = x[:, axis] < foot_level(x, axis, along, wall_level)
    half = np.max(distance[foot]) + 0.5 * across
    lift = FOOT_LIFT * half0
    fixed = x[:, axis] < foot_level(x, axis, along, wall_level, lift)
    half_fixed = np.max(distance[fixed]) + 0.5 * across
    return {"final_length_ratio": float(Lf / L0), "footprint_half_width_ratio": float(half / half0),
            "footprint_half_width_ratio_fixed": float(half_fixed / half0),
            "footprint_lift": float(lift),
            "final_length": float(Lf), "initial_length": float(L0),
            "lift_off": lift_off(x, axis, along, wall_level)}


def foot_level(x: np.ndarray, axis: int, along: float, wall_level: float,
               lift: float | None = None) -> float:
    """The level below which particles are the bar's foot: one spacing above the wall, or,
    for a bar that has rebounded off it (no particle within one spacing of the wall), half a
    spacing above its lowest particle.  With ``lift`` (the fixed band): the particles whose
    lower surfaces (centres less half a spacing) are within ``lift`` of the wall or, once the
    bar's lowest surface has left the wall, of that surface."""
    lowest = float(x[:, axis].min())
    if lift is not None:
        return max(wall_level, lowest - 0.5 * along) + lift + 0.5 * along
    return wall_level + along if lowest < wall_level + along else lowest + 0.5 * along


def lift_off(x: np.ndarray, axis: int, along: float, wall_level: float) -> float:
    """How far the bar's lowest particle is above half a spacing over the wall (m): 0 or
    less while the bar stands on it, positive once it has rebounded."""
    return float(x[:, axis].min() - wall_level - 0.5 * along)


#: Sectors of the footprint in 3D: 8 of 45 degrees, centred on the axes and the diagonals.
N_SECTORS = 8


def cylinder_measures(x0: np.ndarray, x: np.ndarray, axis: int, spacing: list[float],
                      wall_level: float, centre: np.ndarray | None = None
                      ) -> dict[str, float]:
    """Length ratio and footprint radius ratio of a 3D bar (a cylinder) along ``axis``
    standing on a wall at ``wall_level`` (initial positions ``x0``, current ``x``): the 3D
    counterpart of :func:`bar_measures`, the half-width replaced by the distance from the
    axis (see the module docstring).  ``spacing``: per axis, as for :func:`bar_measures`;
    ``centre`` as there."""
    along = spacing[axis]
    L0 = x0[:, axis].max() - x0[:, axis].min() + along
    Lf = x[:, axis].max() - x[:, axis].min() + along
    lateral = [a for a in range(3) if a != axis]
    across = spacing[lateral[0]]
    if centre is None:
        centre = x0[:, lateral].mean(axis=0)
    R0 = float(np.max(np.linalg.norm(x0[:, lateral] - centre, axis=1))) + 0.5 * across
    d = x[x[:, axis] < foot_level(x, axis, along, wall_level)][:, lateral] - centre
    r = np.hypot(d[:, 0], d[:, 1])
    Rf = float(r.max()) + 0.5 * across
    lift = FOOT_LIFT * R0
    fixed = x[x[:, axis] < foot_level(x, axis, along, wall_level, lift)][:, lateral] - centre
    Rf_fixed = float(np.hypot(fixed[:, 0], fixed[:, 1]).max()) + 0.5 * across
    sector = np.rint(np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi / N_SECTORS)).astype(int)
    sector %= N_SECTORS
    by_sector = np.zeros(N_SECTORS)
    np.maximum.at(by_sector, sector, r + 0.5 * across)
    return {"final_length_ratio": float(Lf / L0), "footprint_radius_ratio": Rf / R0,
            "footprint_radius_ratio_min_sector": float(by_sector.min()) / R0,
            "footprint_radius_ratio_fixed": Rf_fixed / R0, "footprint_lift": lift,
            "footprint_radius": Rf, "initial_radius": R0,
            "final_length": float(Lf), "initial_length": float(L0),
            "lift_off": lift_off(x, axis, along, wall_level)}


def bar_profile(x: np.ndarray, axis: int, spacing: list[float], centre: np.ndarray,
                bins: int = 20) -> list[list[float]]:
    """The mushroom profile of a bar along ``axis``: ``[height above its lowest particle,
    half-width or radius]`` (m) at the middle of ``bins`` equal slices of its length, each the
    largest distance of a slice's particles from the axis plus half a spacing (the measure of
    the footprint, taken all along the bar)."""
    along = spacing[axis]
    lateral = [a for a in range(x.shape[1]) if a != axis]
    across = spacing[lateral[0]]
    z = x[:, axis] - x[:, axis].min()
    length = float(z.max()) + along
    r = np.linalg.norm(x[:, lateral] - centre, axis=1)
    edges = np.linspace(0.0, length, bins + 1)
    out = []
    for k in range(bins):
        sel = (z >= edges[k] - 0.5 * along) & (z < edges[k + 1] - 0.5 * along)
        if sel.any():
            out.append([float(0.5 * (edges[k] + edges[k + 1])),
                        float(r[sel].max() + 0.5 * across)])
    return out


def bar_axis(case: Any) -> int:
    """The axis the bar stands along: a cylinder's own axis, else the last one."""
    geometry = case.bodies[0].geometry
    return AXES.index(geometry.axis) if geometry.type == "cylinder" else case.dimension - 1


def bar_wall(case: Any, axis: int) -> float:
    """Where the (first) wall, the bar's, cuts ``axis``; 0 without walls."""
    walls = [b for b in case.boundaries if b.type == "wall"]
    return walls[0].point[axis] if walls else 0.0


def bar_centre(case: Any, x0: np.ndarray, axis: int) -> np.ndarray:
    """The bar axis's lateral coordinates: the mean of the initial positions, except across a
    symmetry plane (a half or quarter model), where the axis lies on the plane."""
    lateral = [a for a in range(x0.shape[1]) if a != axis]
    centre = x0[:, lateral].mean(axis=0)
    for plane in case.boundaries:
        if plane.type != "symmetry":
            continue
        normal = np.asarray(plane.normal, dtype=float)
        normal /= np.linalg.norm(normal)
        for k, a in enumerate(lateral):
            if abs(abs(normal[a]) - 1.0) < 1e-12:  # a plane across this lateral axis
                centre[k] = plane.point[a]
    return centre


def taylor_metrics(sim: Any) -> dict[str, Any]:
    """Example 2's measures (see the module docstring) of the bar (the first body), taken
    whatever became of it, with a note (``notes``) where the bar has rebounded off the wall
    or broken: a bar in pieces is measured on its largest piece."""
    from ..measures import attempt, largest_piece

    body = sim.case.bodies[0]
    axis = bar_axis(sim.case)
    wall = bar_wall(sim.case, axis)
    s = sim.state
    members = np.flatnonzero(s.body == 0)
    x0, x = s.initial_position[members], s.position[members]
    spacing = body.geometry.spacings()
    notes: list[str] = []
    out: dict[str, Any] = {}
    support = 2.0 * float(sim.h_reference[members].max())
    pieces, piece, share = attempt(notes, "pieces", lambda: largest_piece(
        x, s.mass[members], support), (1, np.ones(len(members), dtype=bool), 1.0))
    if pieces > 1:
        x = x[piece]
        notes.append(f"the bar is in {pieces} pieces (particles farther than 2h apart): its "
                     f"length and footprint are measured on the largest piece "
                     f"({100 * share:.3g}% of its mass)")
    measures = cylinder_measures if sim.case.dimension == 3 else bar_measures
    centre = bar_centre(sim.case, x0, axis)
    out.update(attempt(notes, "final_length_ratio and footprint", lambda: measures(
        x0, x, axis, spacing, wall, centre), {}))
    if getattr(sim.case, "two_dimensional", "") == "axisymmetric" \
            and "footprint_half_width_ratio" in out:  # the half-width is the radius
        out["footprint_radius_ratio"] = out["footprint_half_width_ratio"]
        out["footprint_radius_ratio_fixed"] = out["footprint_half_width_ratio_fixed"]
    out.update(attempt(notes, "profile", lambda: {"profile": bar_profile(
        x, axis, spacing, centre)}, {}))
    if "final_length_ratio" in out:
        lo, hi = LENGTH_RATIO_BAND
        out["length_ratio_in_1d_band"] = bool(lo <= out["final_length_ratio"] <= hi)
    if out.get("lift_off", 0.0) > 0.0:
        notes.append(f"the bar has rebounded off the wall (lift_off = "
                     f"{out['lift_off'] * 1e3:.3g} mm; no particle within one spacing of the "
                     f"wall): its footprint is measured at its lowest particles (within half "
                     f"a spacing of the lowest; the fixed band's from its lowest surface), not "
                     f"on the wall")
    out["mass_total"] = float(s.mass.sum())
    if notes:
        out["notes"] = notes
    return out


# --- figures ---------------------------------------------------------------------------------

def bar_views_figure(runs: list[dict[str, Any]], path: Path, title: str, *, axis: int,
                     wall_level: float, spacing: float) -> Path:
    """A 3D bar standing on a wall along ``axis`` (the Taylor bar as a cylinder), one row per
    run: the mid-plane section (the particles within one ``spacing`` of the plane through the
    axis and the first lateral axis), every particle's distance from the axis against its
    height (an r-z projection), and the footprint seen from below (the particles within one
    spacing of the wall) with the circles of radius ``R0`` and ``Rf`` (dashed, solid).
    ``runs``: dicts with ``label``, ``x`` (n, 3), ``centre`` (the axis's two lateral
    coordinates), ``R0`` and ``Rf`` (m)."""
    from ..plotting import plt, save_figure

    lateral = [a for a in range(3) if a != axis]
    names = ["xyz"[a] for a in lateral] + ["xyz"[axis]]
    n = len(runs)
    fig, axes = plt.subplots(n, 3, figsize=(11, 4.6 * n), squeeze=False,
                             gridspec_kw={"width_ratios": [1, 0.6, 1]})
    t = np.linspace(0, 2 * np.pi, 361)
    for k, (row, r) in enumerate(zip(axes, runs, strict=True)):
        x = np.asarray(r["x"])
        a = x[:, lateral[0]] - r["centre"][0]
        b = x[:, lateral[1]] - r["centre"][1]
        z = x[:, axis] - wall_level
        mid = np.abs(b) < spacing
        row[0].scatter(a[mid] * 1e3, z[mid] * 1e3, s=2, color=f"C{k}")
        row[0].set_xlabel(f"{names[0]} (mm)")
        row[0].set_ylabel(f"{names[2]} above the wall (mm)")
        row[0].set_title(f"{r['label']}: section |{names[1]}| < dx", fontsize=9)
        row[1].scatter(np.hypot(a, b) * 1e3, z * 1e3, s=0.5, color=f"C{k}", alpha=0.3)
        row[1].set_xlabel("distance from the axis r (mm)")
        row[1].set_title("r-z projection, every particle", fontsize=9)
        foot = z < spacing
        row[2].scatter(a[foot] * 1e3, b[foot] * 1e3, s=3, color=f"C{k}")
        for radius, style, what in ((r["R0"], "k--", "R0"), (r["Rf"], "k-", "Rf")):
            row[2].plot(radius * 1e3 * np.cos(t), radius * 1e3 * np.sin(t), style, lw=0.8,
                        label=f"{what} = {radius * 1e3:.3g} mm")
        row[2].set_xlabel(f"{names[0]} (mm)")
        row[2].set_ylabel(f"{names[1]} (mm)")
        row[2].set_title(f"footprint: {names[2]} < dx, Rf/R0 = {r['Rf'] / r['R0']:.3f}",
                         fontsize=9)
        row[2].legend(fontsize=8, loc="upper right")
        for ax in row:
            ax.set_aspect("equal")
            ax.grid(alpha=0.3)
        row[1].set_xlim(left=0)
        row[1].sharey(row[0])
    fig.suptitle(title)
    return save_figure(fig, path)


def taylor_shapes_figure(shapes: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Deformed bars (dicts with ``label``, ``x``, ``x0`` and ``case``, as
    :func:`impactsph.figures.deformed_shapes` gives them), side by side: the particles in the
    plane in 2D (:func:`impactsph.plotting.shapes_figure`, paper Figs 11, 13), and for a 3D
    bar its section, r-z projection and footprint (:func:`bar_views_figure`), a row per run."""
    from ..plotting import shapes_figure

    first = shapes[0]["case"]
    if first.dimension != 3:
        return shapes_figure(shapes, path, title, separate=True)
    views = []
    for s in shapes:
        case = s["case"]
        axis = bar_axis(case)
        x0 = np.asarray(s["x0"])
        m = cylinder_measures(x0, np.asarray(s["x"]), axis, case.bodies[0].geometry.spacings(),
                              bar_wall(case, axis))
        views.append({"label": s["label"], "x": s["x"],
                      "centre": x0[:, [a for a in range(3) if a != axis]].mean(axis=0),
                      "R0": m["initial_radius"], "Rf": m["footprint_radius"]})
    axis = bar_axis(first)
    return bar_views_figure(views, path, title, axis=axis, wall_level=bar_wall(first, axis),
                            spacing=first.bodies[0].geometry.spacings()[axis])


# --- the paper's figures and table -----------------------------------------------------------

def taylor_runs() -> dict[str, list[str]]:
    """Label -> overrides of the runs of Figs 11-13."""
    from ..paper import AV_SETS, DEFAULT_AC, ac, av

    return {**AV_SETS, "AV (0.5, 0.5)": av(0.5, 0.5), f"AC {DEFAULT_AC}": ac(DEFAULT_AC)}


def taylor_paper(base: dict[str, Any], out: Path, workers: int | None = None,
                 scheduler: str | None = None) -> dict[str, Any]:
    """The paper's figures of Example 2 (see :mod:`impactsph.paper`): ``fig11_shapes_av.png``
    (AV1, AV2, AV3 at 50 us), ``fig12_kinetic_energy.png`` (AV1, AV2, AV3, AV (0.5, 0.5),
    AC), ``fig13_shapes.png`` (AV (0.5, 0.5) against AC), and the table of the problem's
    measures for every run (:func:`impactsph.paper.measure_keys`)."""
    from ..paper import AV_SETS, DEFAULT_AC, shapes_paper

    av, ref, ac = list(AV_SETS), "AV (0.5, 0.5)", f"AC {DEFAULT_AC}"
    return shapes_paper(
        base, out, taylor_runs(),
        [("fig11_shapes_av", av, "Taylor bar at 50 us: AV1, AV2, AV3"),
         ("fig13_shapes", [ref, ac], "Taylor bar at 50 us: AV (0.5, 0.5) and AC")],
        taylor_shapes_figure,
        ("fig12_kinetic_energy", [*av, ref, ac], "Kinetic energy: taylor"),
        workers=workers, scheduler=scheduler)

# --- the problem -----------------------------------------------------------------------------

class TaylorProblem(ProblemKind):
    """Example 2 (``analysis = "taylor"``): the Taylor bar's length and footprint."""

    name = "taylor"
    title = "Example 2: the Taylor bar on a rigid wall, final length and footprint"
    # the measures use the lattice's spacings
    geometry_needs = GeometryNeeds(bodies=1, types=("block", "disk", "cylinder", "file"))
    animation_field = "plastic_work"

    def metrics(self, sim: Any) -> dict[str, Any]:
        """:func:`taylor_metrics`."""
        return taylor_metrics(sim)

    def _footprint(self, case: Case) -> str:
        return "footprint_radius_ratio" if case.dimension == 3 else "footprint_half_width_ratio"

    def summary_keys(self, case: Case) -> tuple[str, ...]:
        """Length ratio (and whether it is in the 1D band), footprint ratio (in a band of one
        spacing and of fixed height), plastic work."""
        extra = ("footprint_radius_ratio_min_sector",) if case.dimension == 3 else ()
        return ("final_length_ratio", "length_ratio_in_1d_band", self._footprint(case),
                f"{self._footprint(case)}_fixed", *extra, "plastic_work")

    def table_keys(self, case: Case) -> tuple[str, ...]:
        """Length ratio, footprint ratio (a half-width in 2D, a radius in 3D), plastic
        work."""
        return ("final_length_ratio", self._footprint(case), "plastic_work")

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path
                ) -> list[Path]:
        """``deformed_shape.png``: the bars at the latest snapshot time they share
        (:func:`taylor_shapes_figure`); without a snapshot, a note says why it is not drawn."""
        from ..figures import deformed_shapes

        shapes, when = deformed_shapes(runs, labels)  # (ValueError without a snapshot)
        name = shapes[0]["case"].name
        return [taylor_shapes_figure(shapes, Path(out) / "deformed_shape.png",
                                     f"{name}: shape at {when}")]

    def paper(self, base: dict[str, Any], out: Path, *, workers: int | None = None,
              scheduler: str | None = None) -> dict[str, Any]:
        """:func:`taylor_paper`: Figs 11-13 and the table."""
        return taylor_paper(base, out, workers, scheduler)
