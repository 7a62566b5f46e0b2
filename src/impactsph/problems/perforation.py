"""A projectile into a plate (``analysis = "perforation"``): body 0 the projectile (any
geometry), body 1 the plate (a block).  The measures of a finished run:

- ``impact_speed``: the projectile's initial speed (m/s); the impact direction is that of its
  initial velocity;
- ``residual_velocity``: its centre-of-mass velocity along that direction at the end (m/s),
  and ``residual_velocity_ratio``, over the impact speed;
- ``plate_thickness``: the plate block's size along the impact direction (the axis nearest to
  it);
- ``ejected_plate_mass_fraction``: the plate's mass moved more than one plate thickness along
  the impact direction (the plug and the debris);
- ``hole_diameter``: twice the smallest distance from the impact axis (the line through the
  projectile's initial centre of mass along the impact direction) of the plate particles that
  moved less than one thickness, at the end (m): the hole the projectile left in what remains
  of the plate (0 if the plate is whole at the axis);
- ``perforated``: whether the projectile's centre of mass is past the plate's rear face and
  plate mass was ejected.

The figure ``perforation.png`` is a section through the impact axis (particles within one
spacing of the plane through it), coloured by body and by the equivalent plastic strain.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .base import GeometryNeeds, ProblemKind


def impact_geometry(x0: np.ndarray, v0: np.ndarray, mass: np.ndarray, body: np.ndarray,
                    planes: list[tuple[np.ndarray, np.ndarray]] = ()) -> dict[str, Any]:
    """The impact direction, axis point and the plate's extent along it, from the initial
    state (body 0 the projectile, body 1 the plate); ``planes``: the symmetry planes
    ``(point, unit normal)`` of a half or quarter model, on which the axis lies."""
    proj, plate = body == 0, body == 1
    m = mass[proj]
    velocity = (m @ v0[proj]) / m.sum()
    centre = (m @ x0[proj]) / m.sum()
    for point, normal in planes:  # the whole model's axis: on every symmetry plane
        velocity = velocity - (velocity @ normal) * normal
        centre = centre - ((centre - point) @ normal) * normal
    speed = float(np.linalg.norm(velocity))
    direction = velocity / speed
    along_plate = x0[plate] @ direction
    return {"direction": direction, "centre": centre, "speed": speed,
            "front": float(along_plate.min()), "rear": float(along_plate.max())}


def perforation_measures(x0: np.ndarray, x: np.ndarray, v0: np.ndarray, v: np.ndarray,
                         mass: np.ndarray, body: np.ndarray, spacing: float,
                         planes: list[tuple[np.ndarray, np.ndarray]] = (),
                         material_mass: np.ndarray | None = None) -> dict[str, Any]:
    """The measures of the module docstring (``spacing``: the plate's particle spacing;
    ``planes`` as :func:`impact_geometry`'s; ``mass``: the inertia that weighs the velocities,
    ``material_mass``: the particles' own masses, which the ejected fraction counts, default
    ``mass``)."""
    g = impact_geometry(x0, v0, mass, body, planes)
    d, c = g["direction"], g["centre"]
    proj, plate = body == 0, body == 1
    thickness = g["rear"] - g["front"] + spacing
    m = mass[proj]
    residual = float(((m @ v[proj]) / m.sum()) @ d)
    moved = (x[plate] - x0[plate]) @ d
    ejected = moved > thickness
    mp = (mass if material_mass is None else material_mass)[plate]
    rel = x[plate] - c
    radial = np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)
    remaining = radial[~ejected]
    hole = 2.0 * float(remaining.min()) if ejected.any() and remaining.size else 0.0
    front_of_projectile = float(((m @ x[proj]) / m.sum()) @ d)
    return {"impact_speed": g["speed"], "residual_velocity": residual,
            "residual_velocity_ratio": residual / g["speed"],
            "plate_thickness": thickness,
            "ejected_plate_mass_fraction": float(mp[ejected].sum() / mp.sum()),
            "hole_diameter": hole,
            "perforated": bool(ejected.any() and front_of_projectile > g["rear"])}


class PerforationProblem(ProblemKind):
    name = "perforation"
    title = "a projectile into a plate: residual velocity, hole, ejected mass"
    geometry_needs = GeometryNeeds(bodies=2, types=("block", "disk", "sphere", "cylinder",
                                                    "file"))
    animation_field = "equivalent_plastic_strain"

    def metrics(self, sim: Any) -> dict[str, Any]:
        from ..initial import body_velocity
        from ..preflight import body_spacing

        s = sim.state
        spacing = body_spacing(sim.case.bodies[1].geometry)

        initial_velocity = np.empty_like(s.velocity)
        for b, body in enumerate(sim.case.bodies):
            rows = s.body == b
            initial_velocity[rows] = body_velocity(body.velocity, s.initial_position[rows])
        planes = [(np.asarray(b.point, float), np.asarray(b.normal, float)
                   / np.linalg.norm(b.normal)) for b in sim.case.boundaries
                  if b.type == "symmetry"]
        return perforation_measures(s.initial_position, s.position, initial_velocity,
                                    s.velocity, s.inertial_mass, s.body, spacing, planes,
                                    material_mass=s.mass)

    def summary_keys(self, case: Any) -> tuple[str, ...]:
        return ("residual_velocity", "residual_velocity_ratio", "hole_diameter",
                "ejected_plate_mass_fraction", "perforated")

    def table_keys(self, case: Any) -> tuple[str, ...]:
        return ("residual_velocity", "hole_diameter", "ejected_plate_mass_fraction")

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path) -> list[Path]:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        paths = []
        for run, label in zip(runs, labels, strict=True):
            snaps = run.get("snapshots") or []
            if not snaps:
                continue
            last = snaps[-1]
            fields = last["fields"] if "fields" in last else last
            x, x0 = fields["position"], fields["initial_position"]
            body = fields["body"]
            eps = fields.get("equivalent_plastic_strain")
            if eps is None:
                eps = np.zeros(x.shape[0])
            dim = x.shape[1]
            if dim == 3:  # the section through the axis: |y| within one spacing
                h = float(np.median(fields["smoothing_length"]))
                keep = np.abs(x0[:, 1] - np.median(x0[body == 0, 1])) < 0.5 * h
                px, py = x[keep, 0], x[keep, 2]
                b, e = body[keep], eps[keep]
                labels_xy = ("x (mm)", "z (mm)")
            else:
                px, py, b, e = x[:, 0], x[:, 1], body, eps
                labels_xy = ("x (mm)", "y (mm)")
            fig, axes = plt.subplots(1, 2, figsize=(11, 5), sharex=True, sharey=True)
            axes[0].scatter(1e3 * px, 1e3 * py, s=2, c=np.where(b == 0, "tab:red", "tab:blue"))
            axes[0].set_title(f"{label}: bodies at t = {1e6 * last.get('time', 0):.2f} us")
            sc = axes[1].scatter(1e3 * px, 1e3 * py, s=2, c=e, cmap="viridis",
                                 vmin=0.0, vmax=max(float(np.percentile(e, 99)), 1e-6))
            fig.colorbar(sc, ax=axes[1], label="equivalent plastic strain")
            axes[1].set_title("equivalent plastic strain")
            for ax in axes:
                ax.set_xlabel(labels_xy[0])
                ax.set_aspect("equal")
            axes[0].set_ylabel(labels_xy[1])
            path = out / ("perforation.png" if len(runs) == 1 else
                          f"perforation_{len(paths)}.png")
            fig.savefig(path, dpi=120, bbox_inches="tight")
            plt.close(fig)
            paths.append(path)
        return paths
