"""Example 3: the Parkes cantilever.

The paper's section 5.3 (parameters in its Table 4, figures 14-17); the runs measured in
``docs/validation.md`` (Example 3), the tip mass's initial speed in ``docs/case-files.md``
(TipMass).

Measures at the end of the run: the tip deflection, the mean displacement across the beam of
the particles carrying the tip mass (m), and its ratio to the length L; the plastic work; and
``max_neighbour_gap_over_h``, the largest distance between two particles that were neighbours
at t = 0 (within the kernel support 2h), over h.  It is about 2.6 in an intact beam and grows
where the particles separate: numerical fracture (the paper's Fig 16) shows as a large value.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .base import GeometryNeeds, ProblemKind

if TYPE_CHECKING:
    from ..config import Case


def max_neighbour_gap_over_h(x0: np.ndarray, x: np.ndarray, h: float) -> float:
    """Largest current distance between initial neighbours (closer than 2h at t = 0), over
    h."""
    from ..measures import pairs_within

    i, j = pairs_within(x0, 2.0 * h)
    return float(np.max(np.linalg.norm(x[i] - x[j], axis=1)) / h)


#: ``max_neighbour_gap_over_h`` above which the beam is taken to have come apart (about 2.6
#: in an intact beam; 366 where the paper's Fig 16 fractures)
FRACTURE_GAP_OVER_H = 5.0


def cantilever_metrics(sim: Any) -> dict[str, Any]:
    """Example 3's measures (see the module docstring), each taken on its own: one that
    cannot be taken is left out with a note (``notes``)."""
    from ..measures import attempt

    body = sim.case.bodies[0]
    s = sim.state
    out: dict[str, Any] = {}
    notes: list[str] = []
    members = s.body == 0
    if body.tip_mass is not None:

        def tip() -> dict[str, Any]:
            from ..geometry import inside

            region = body.tip_mass.region
            tip = members & inside(s.initial_position, region.origin, region.size)
            transverse = int(np.argmax(np.abs(body.tip_mass.velocity)))
            disp = s.position[tip, transverse] - s.initial_position[tip, transverse]
            length = float(s.initial_position[tip, 0].max()
                           + 0.5 * body.geometry.spacings()[0])
            deflection = float(abs(disp.mean()))
            return {"tip_deflection": deflection, "tip_deflection_ratio": deflection / length,
                    "tip_initial_speed": sim.problem.info.get("tip_initial_speed")}

        out.update(attempt(notes, "tip_deflection", tip, {}))
    else:
        notes.append("tip_deflection: not measured, the beam has no tip_mass")
    out.update(attempt(notes, "max_neighbour_gap_over_h", lambda: {
        "max_neighbour_gap_over_h": max_neighbour_gap_over_h(
            s.initial_position[members], s.position[members],
            float(sim.h_reference[members].max()))}, {}))
    gap = out.get("max_neighbour_gap_over_h")
    if gap is not None and gap > FRACTURE_GAP_OVER_H:
        notes.append(f"the beam has come apart (numerical fracture: two initial neighbours "
                     f"are {gap:.3g} h apart); tip_deflection is the mean of the tip "
                     f"particles wherever they went")
    if notes:
        out["notes"] = notes
    return out


# --- figures ---------------------------------------------------------------------------------

def cantilever_shapes_figure(shapes: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Deformed beams overlaid (paper Figs 15-17; dicts with ``label`` and ``x``)."""
    from ..plotting import shapes_figure

    return shapes_figure(shapes, path, title, separate=False)


# --- the paper's figures and table -----------------------------------------------------------

#: The paper's numerical experiment (Fig 16): alpha1 below the optimum, alpha2 = 0.
LOW_ALPHA1 = (0.05, 0.075, 0.1)


def cantilever_runs() -> dict[str, list[str]]:
    """Label -> overrides of the runs of Figs 15-17."""
    from ..paper import AV_SETS, DEFAULT_AC, ac, av

    runs = dict(AV_SETS)
    runs |= {f"AV ({a:g}, 0)": av(a, 0.0) for a in LOW_ALPHA1}
    runs["AV (0.1, 0.1)"] = av(0.1, 0.1)
    runs[f"AC {DEFAULT_AC}"] = ac(DEFAULT_AC)
    return runs


def cantilever_paper(base: dict[str, Any], out: Path, workers: int | None = None,
                     scheduler: str | None = None) -> dict[str, Any]:
    """The paper's figures of Example 3 (see :mod:`impactsph.paper`): ``fig15_shapes_av.png``
    (AV1, AV2, AV3 at 15.8 ms), ``fig16_low_viscosity.png`` (alpha1 = 0.05, 0.075, 0.1 with
    alpha2 = 0), ``fig17_shapes.png`` (AV (0.1, 0.1) against AC), ``kinetic_energy.png``, and
    the table of the problem's measures for every run (:func:`impactsph.paper.measure_keys`)."""
    from ..paper import AV_SETS, DEFAULT_AC, shapes_paper

    av, ref, ac = list(AV_SETS), "AV (0.1, 0.1)", f"AC {DEFAULT_AC}"
    return shapes_paper(
        base, out, cantilever_runs(),
        [("fig15_shapes_av", av, "Cantilever at 15.8 ms: AV1, AV2, AV3"),
         ("fig16_low_viscosity", [f"AV ({a:g}, 0)" for a in LOW_ALPHA1],
          "Cantilever at 15.8 ms: alpha2 = 0"),
         ("fig17_shapes", [ref, ac], "Cantilever at 15.8 ms: AV (0.1, 0.1) and AC")],
        cantilever_shapes_figure,
        ("kinetic_energy", [*av, ref, ac], "Kinetic energy: cantilever"),
        workers=workers, scheduler=scheduler)

# --- the problem -----------------------------------------------------------------------------

class CantileverProblem(ProblemKind):
    """Example 3 (``analysis = "cantilever"``): the tip deflection and the beam's integrity."""

    name = "cantilever"
    title = "Example 3: the Parkes cantilever, tip deflection and numerical fracture"
    # the measures use the lattice's spacings
    geometry_needs = GeometryNeeds(bodies=1, types=("block", "disk", "cylinder"))
    animation_field = "displacement"

    def metrics(self, sim: Any) -> dict[str, Any]:
        """:func:`cantilever_metrics`."""
        return cantilever_metrics(sim)

    def summary_keys(self, case: Case) -> tuple[str, ...]:
        """Tip deflection (and over the length), plastic work, largest neighbour gap."""
        return ("tip_deflection", "tip_deflection_ratio", "plastic_work",
                "max_neighbour_gap_over_h")

    def table_keys(self, case: Case) -> tuple[str, ...]:
        """As :meth:`summary_keys`."""
        return self.summary_keys(case)

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path
                ) -> list[Path]:
        """``deformed_shape.png``: the beams at the latest snapshot time they share, overlaid,
        when they have snapshots; without one, a note says why it is not drawn."""
        from ..figures import deformed_shapes

        shapes, when = deformed_shapes(runs, labels)  # (ValueError without a snapshot)
        name = shapes[0]["case"].name
        return [cantilever_shapes_figure(shapes, Path(out) / "deformed_shape.png",
                                         f"{name}: shape at {when}")]

    def paper(self, base: dict[str, Any], out: Path, *, workers: int | None = None,
              scheduler: str | None = None) -> dict[str, Any]:
        """:func:`cantilever_paper`: Figs 15-17 and the table."""
        return cantilever_paper(base, out, workers, scheduler)
