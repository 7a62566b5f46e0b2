"""Measures of any finished run, whatever its problem (``analysis = "none"`` included): per
body, per gauge, and the pieces a body is in.

``summary.json``'s ``bodies`` holds, per body (by name):

- ``particles``, ``mass`` (kg; kg/m per unit depth in 2D, kg/m^2 per unit section in 1D);
- ``max_displacement``: the largest displacement ``|x - x0|`` of any of its particles over
  the history's rows (every ``output.history_every`` steps), m;
- ``final_max_displacement``: the same at the end, m;
- ``centre_of_mass_displacement``: of its centre of mass, at the end (vector, m);
- ``final_velocity``: the velocity of its centre of mass at the end (vector, m/s; the
  residual velocity of a projectile), and ``final_speed`` its norm;
- ``kinetic_energy_final``, ``plastic_work`` (J, per unit depth or section as the energies);
- ``max_plastic_work_per_mass``: the largest specific plastic work of its particles (J/kg);
- ``max_<state>`` for each per-particle state of its material's strength model, e.g.
  ``max_equivalent_plastic_strain`` (none for the built-in models);
- ``pieces``: how many pieces it is in (particles of the body closer than the kernel support
  2h are one piece), and ``largest_piece_mass_fraction``.

``gauges`` holds, per gauge, :func:`impactsph.gauges.gauge_summary`.

Every measure is taken on its own: one that cannot be taken is left out with a note in the
summary's ``notes`` (never an exception at the end of a run).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

log = logging.getLogger("impactsph")


def attempt(notes: list[str], what: str, measure: Callable[[], Any], default: Any = None
            ) -> Any:
    """``measure()``, or, when it raises, ``default`` and a note ``WHAT: not measured
    (Error: message)`` (logged as a warning)."""
    try:
        return measure()
    except Exception as exc:  # noqa: BLE001 - a measure never stops a finished run
        note = f"{what}: not measured ({type(exc).__name__}: {exc})"
        notes.append(note)
        log.warning("%s", note)
        return default


def connected_pieces(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Labels of the connected components of the graph of ``n`` nodes with edges ``(i, j)``:
    ``labels[k]`` is the smallest node of ``k``'s component.  Vectorised: hooking of roots
    and pointer jumping, a few passes over the edges (no loop over nodes)."""
    label = np.arange(n)
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    while True:
        li, lj = label[i], label[j]
        differ = li != lj
        if not differ.any():
            return label
        li, lj = li[differ], lj[differ]
        low, high = np.minimum(li, lj), np.maximum(li, lj)
        np.minimum.at(label, high, low)  # hook each root under the smaller one
        while True:  # pointer jumping: every node straight to its root
            up = label[label]
            if np.array_equal(up, label):
                break
            label = up


def pairs_within(x: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The ordered pairs ``(i, j)``, ``i != j``, of the points ``x`` closer than ``radius``
    (particle numbers, from a neighbour list built for them)."""
    from .neighbours import NeighbourList

    nl = NeighbourList.build(np.ascontiguousarray(x), radius)
    p = np.repeat(np.arange(x.shape[0]), np.diff(nl.offsets))
    # the list is in cell order: sorted positions to particles
    i, j = nl.order[p], nl.order[nl.indices]
    other = i != j
    return i[other], j[other]


def pieces_of(x: np.ndarray, support: float) -> np.ndarray:
    """A label per particle at ``x``, the same for the particles of one piece: two particles
    closer than ``support`` are of one piece (the label is a piece's smallest index)."""
    n = x.shape[0]
    if n <= 1:
        return np.zeros(n, dtype=np.int64)
    return connected_pieces(n, *pairs_within(x, support))


def largest_piece(x: np.ndarray, mass: np.ndarray, support: float
                  ) -> tuple[int, np.ndarray, float]:
    """How many pieces the particles at ``x`` are in, the mask of the heaviest piece and its
    share of the mass."""
    labels = pieces_of(x, support)
    roots, inverse = np.unique(labels, return_inverse=True)
    piece_mass = np.bincount(inverse, weights=mass)
    k = int(np.argmax(piece_mass))
    return len(roots), inverse == k, float(piece_mass[k] / piece_mass.sum())


def body_measures(sim: Any, notes: list[str]) -> dict[str, dict[str, Any]]:
    """The per-body measures of the module docstring, by body name."""
    from .materials import TableLayout
    from .models.columns import DAMAGE

    s = sim.state
    out: dict[str, dict[str, Any]] = {}
    max_disp = getattr(sim, "max_displacement", None)
    for b, name in enumerate(sim.problem.body_names):
        members = np.flatnonzero(s.body == b)
        own = s.mass[members]  # the material: its amount, its plastic work, its pieces
        m = s.inertial_mass[members]  # what moves: a tip mass carried as inertia counts
        M = float(m.sum())
        material_mass = float(own.sum())
        x, x0, v = s.position[members], s.initial_position[members], s.velocity[members]
        u = np.linalg.norm(x - x0, axis=1)
        entry: dict[str, Any] = {"particles": int(members.size), "mass": material_mass}
        if M != material_mass:
            entry["added_mass"] = M - material_mass
        entry["max_displacement"] = float(max(max_disp[b], u.max())) if (
            max_disp is not None and b < len(max_disp)) else float(u.max())
        entry["final_max_displacement"] = float(u.max())
        entry["centre_of_mass_displacement"] = ((m @ (x - x0)) / M).tolist()
        vc = (m @ v) / M
        entry["final_velocity"] = vc.tolist()
        entry["final_speed"] = float(np.linalg.norm(vc))
        entry["kinetic_energy_final"] = float(0.5 * np.dot(m, np.einsum("ia,ia->i", v, v)))
        wp = s.plastic_work[members]
        entry["plastic_work"] = float(np.dot(own, wp))
        entry["max_plastic_work_per_mass"] = float(wp.max())
        materials = sim.problem.materials
        layout = TableLayout.registered()
        for k in np.unique(s.material[members]):
            sel = members[s.material[members] == k]
            for state_name, c in layout.state_names(materials[k]).items():
                value = float(s.material_state[sel, c].max())
                key = f"max_{state_name}"
                entry[key] = max(entry.get(key, value), value)
        entry["failed_mass_fraction"] = float(
            own[s.material_state[members, DAMAGE] >= 1.0].sum() / material_mass)

        def pieces(x: np.ndarray = x, m: np.ndarray = own, members: np.ndarray = members
                   ) -> dict[str, Any]:
            support = 2.0 * float(sim.h_reference[members].max())
            count, _, share = largest_piece(x, m, support)
            return {"pieces": count, "largest_piece_mass_fraction": share}

        entry.update(attempt(notes, f"bodies.{name}.pieces", pieces, {}))
        if entry.get("pieces", 1) > 1:
            share = 100 * entry["largest_piece_mass_fraction"]
            notes.append(f"body {name!r} is in {entry['pieces']} pieces (particles farther "
                         f"than 2h apart), the largest {share:.3g}% of its mass; its "
                         f"final_velocity is that of all of them")
        out[name] = entry
    return out


def run_measures(sim: Any) -> dict[str, Any]:
    """``bodies``, ``gauges`` (with gauges) and ``notes`` of a finished run (each measure
    guarded: :func:`attempt`)."""
    from .gauges import gauge_summary

    notes: list[str] = []
    out: dict[str, Any] = {"bodies": attempt(notes, "bodies", lambda: body_measures(sim, notes),
                                             {})}
    if sim.problem.gauges:
        out["gauges"] = attempt(notes, "gauges", lambda: gauge_summary(sim), {})
    out["notes"] = notes
    return out
