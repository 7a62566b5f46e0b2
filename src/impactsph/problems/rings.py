"""Two elastic rubber rings in collision (Monaghan 2000; Gray, Monaghan & Swift 2001, section
6.2): the built-in case ``rings`` (``analysis = "rings"``), the test of the tensile
instability in a body that bends, compresses and stretches at once, and a problem of the
dissipation lab (docs/dissipation.md).

Two rings (``geometry.type = "ring"``), inner radius 3 cm and outer radius 4 cm, 4 mm apart,
each moving towards the other at 0.059 c0 along x; the material is Gray et al.'s in SI
(docs/stabilisation.md, "Artificial stress": rho0 = 1200 kg/m^3, K = rho0 c0^2 with c0 = 100
m/s, mu = 0.22 rho0 c0^2).  They push on each other for about 12-13 ms and rebound.

Measures at the end of the run:

- ``restitution``: the speed at which the two bodies' centres of mass move apart along the
  line of their initial centres, over the speed at which they approached at t = 0 (1 for an
  elastic rebound that keeps all the kinetic energy of the approach in the rings' motion, 0
  for none; negative while they still approach);
- ``max_neighbour_gap_over_h``: the largest distance between two particles of one ring that
  were nearest neighbours (closer than 1.5 dx) at t = 0, over h: a ring is whole below 2.5
  (a tear, the tensile instability's failure, shows as a large value);
- ``min_distance_over_dx``: the smallest distance between two particles of one ring, over the
  spacing: the instability's clumping shows as a small value (0.65 at 5 particles through
  the wall with the artificial stress at epsilon = 0.3, 0.010 without it).

Both are taken at every snapshot (the built-in case has one each millisecond) and at the end,
and the worst is reported: a ring that clumps while the rings push and recovers after still
counts.  ``rings.png`` draws the rings at four of the snapshots.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .base import GeometryNeeds, ProblemKind

if TYPE_CHECKING:
    from ..config import Case

#: ``max_neighbour_gap_over_h`` above which a ring is taken to have torn
TORN_GAP_OVER_H = 2.5
#: ``min_distance_over_dx`` below which a ring is taken to have clumped
CLUMPED_DISTANCE_OVER_DX = 0.3


def min_distance_over_dx(x: np.ndarray, h: float, dx: float) -> float:
    """The smallest distance between two of the particles ``x``, over ``dx`` (pairs closer
    than 2h; 2h / dx if there are none)."""
    from ..measures import pairs_within

    i, j = pairs_within(x, 2.0 * h)
    d = np.linalg.norm(x[i] - x[j], axis=1)
    return float(d.min() / dx) if d.size else 2.0 * h / dx


def rings_metrics(sim: Any) -> dict[str, Any]:
    """The measures of the module docstring (a note where the rings tore or clumped)."""
    from ..measures import attempt, pairs_within

    s = sim.state
    notes: list[str] = []
    out: dict[str, Any] = {}
    first, second = s.body == 0, s.body == 1
    m = s.inertial_mass  # centre-of-mass velocities: any added mass moves with the ring

    def centre(sel: np.ndarray, field: np.ndarray) -> np.ndarray:
        return (m[sel] @ field[sel]) / m[sel].sum()

    def restitution() -> dict[str, float]:
        line = centre(second, s.initial_position) - centre(first, s.initial_position)
        line /= np.linalg.norm(line)
        v0 = [np.asarray(sim.case.bodies[k].velocity, dtype=float) for k in (0, 1)]
        approach = float((v0[0] - v0[1]) @ line)
        apart = float((centre(second, s.velocity) - centre(first, s.velocity)) @ line)
        return {"restitution": apart / approach if approach > 0 else float("nan"),
                "approach_speed": approach, "separation_speed": apart}

    out.update(attempt(notes, "restitution", restitution, {}))

    def integrity() -> dict[str, float]:
        states = [snap.fields["position"] for snap in sim.record.snapshots
                  if "position" in snap.fields and len(snap.fields["position"]) == s.n]
        gaps, closest = [], []
        for k, body in enumerate(sim.case.bodies[:2]):
            sel = s.body == k
            h = float(sim.h_reference[sel].max())
            dx = float(body.geometry.spacings()[0])
            i, j = pairs_within(s.initial_position[sel], 1.5 * dx)
            for x in [*states, s.position]:
                ring = x[sel]
                gaps.append(float(np.linalg.norm(ring[i] - ring[j], axis=1).max()) / h)
                closest.append(min_distance_over_dx(ring, h, dx))
        return {"max_neighbour_gap_over_h": max(gaps), "min_distance_over_dx": min(closest)}

    out.update(attempt(notes, "integrity", integrity, {}))
    if out.get("max_neighbour_gap_over_h", 0.0) > TORN_GAP_OVER_H:
        notes.append(f"a ring has torn: two initial neighbours are "
                     f"{out['max_neighbour_gap_over_h']:.3g} h apart (> {TORN_GAP_OVER_H})")
    if out.get("min_distance_over_dx", 1.0) < CLUMPED_DISTANCE_OVER_DX:
        notes.append(f"a ring has clumped: two of its particles are "
                     f"{out['min_distance_over_dx']:.3g} dx apart "
                     f"(< {CLUMPED_DISTANCE_OVER_DX})")
    if notes:
        out["notes"] = notes
    return out


class RingsProblem(ProblemKind):
    """Colliding rubber rings (``analysis = "rings"``): rebound and integrity."""

    name = "rings"
    title = "two rubber rings in collision: rebound, tears and clumps"
    geometry_needs = GeometryNeeds(bodies=2, types=("ring",))

    def metrics(self, sim: Any) -> dict[str, Any]:
        """See :func:`rings_metrics`."""
        return rings_metrics(sim)

    def summary_keys(self, case: Case) -> tuple[str, ...]:
        """Restitution and the rings' integrity."""
        return ("restitution", "max_neighbour_gap_over_h", "min_distance_over_dx")

    def table_keys(self, case: Case) -> tuple[str, ...]:
        """As :meth:`summary_keys`."""
        return self.summary_keys(case)

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path
                ) -> list[Path]:
        """``rings.png``: the first run's rings at four of its snapshots, coloured by body."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        snaps = runs[0].get("snapshots", []) if runs else []
        if not snaps:
            return []
        pick = [snaps[k] for k in np.unique(np.linspace(0, len(snaps) - 1, 4).round()
                                            .astype(int))]
        fig, axes = plt.subplots(1, len(pick), figsize=(3.2 * len(pick), 3.0), squeeze=False)
        for ax, snap in zip(axes[0], pick, strict=True):
            x, body = snap["position"], snap["body"]
            for k, colour in ((0, "tab:blue"), (1, "tab:red")):
                sel = body == k
                ax.scatter(x[sel, 0] * 1e2, x[sel, 1] * 1e2, s=1.5, c=colour, lw=0)
            ax.set_aspect("equal")
            ax.set_title(f"t = {snap['time'] * 1e3:.3g} ms", fontsize=9)
            ax.set_xlabel("x (cm)")
        axes[0][0].set_ylabel("y (cm)")
        fig.suptitle(f"rubber rings: {labels[0] if labels else ''}", fontsize=10)
        fig.tight_layout()
        path = Path(out) / "rings.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return [path]
