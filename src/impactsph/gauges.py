"""Gauges: material points whose fields are recorded every step (``[[output.gauges]]``).

A gauge is a probe (``[[output.probes]]``, the velocity only) that records any field of the
particle state: the particle of its body nearest to its position at t = 0 is chosen as a
probe's is (:func:`impactsph.problem.nearest_particle`) and followed as it moves, so a gauge
is a material point (a penetration or a deflection at a gauge is its displacement).  A row of
``gauges.csv`` is taken with the probes' sample, every step, from one gather over the gauges'
particles (no loop over particles).

Columns (``NAME`` the gauge's name; ``x``, ``y``, ``z`` up to the dimension):

========================  ==============================================  ========
field                     columns                                         unit
========================  ==============================================  ========
``position``              ``NAME_x``, ``NAME_y``, ``NAME_z``              m
``displacement``          ``NAME_ux``, ``NAME_uy``, ``NAME_uz``           m
``velocity``              ``NAME_vx``, ``NAME_vy``, ``NAME_vz``           m/s
``density``               ``NAME_density``                                kg/m^3
``pressure``              ``NAME_pressure``                               Pa
``specific_energy``       ``NAME_specific_energy``                        J/kg
``deviatoric_stress``     ``NAME_sxx``, ``_syy``, ``_szz``, ``_sxy``,     Pa
                          ``_sxz``, ``_syz``
``von_mises_stress``      ``NAME_von_mises``                              Pa
``plastic_work``          ``NAME_plastic_work``                           J/kg
``material_state``        ``NAME_<state>`` per state of its material:     -, 1/s,
                          ``equivalent_plastic_strain``,                  K, -, then
                          ``plastic_strain_rate``, ``temperature``,       as the
                          ``damage``, then its models' own                model says
========================  ==============================================  ========
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from .materials import carried_pressure
from .models.columns import DAMAGE

#: the stress components written, as (row, column) of the 3x3 deviator
STRESS_COMPONENTS = (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("xz", 0, 2),
                     ("yz", 1, 2))

#: the unit of each gauge field's columns
UNITS = {"position": "m", "displacement": "m", "velocity": "m/s", "density": "kg/m^3",
         "pressure": "Pa", "specific_energy": "J/kg", "deviatoric_stress": "Pa",
         "von_mises_stress": "Pa", "plastic_work": "J/kg", "material_state": ""}


def field_columns(field: str, dim: int, state_names: tuple[str, ...] = ()) -> list[str]:
    """The column suffixes of one gauge field (``NAME_`` + suffix is the column)."""
    axes = "xyz"[:dim]
    if field == "position":
        return list(axes)
    if field == "displacement":
        return [f"u{a}" for a in axes]
    if field == "velocity":
        return [f"v{a}" for a in axes]
    if field == "deviatoric_stress":
        return [f"s{c}" for c, _, _ in STRESS_COMPONENTS]
    if field == "von_mises_stress":
        return ["von_mises"]
    if field == "material_state":
        return list(state_names)
    return [field]


@dataclass
class Gauges:
    """The gauges of a run: their particles and columns, and :meth:`sample_rows`, one row
    (of :meth:`rows_of` a host state, or of the device's rows)."""

    names: list[str]
    indices: np.ndarray  #: (k,) the particle of each gauge
    columns: list[str]  #: ``time`` and every gauge's columns
    select: np.ndarray  #: positions of the columns in the flattened (k, T) table of values
    needs_pressure: bool
    width: int  #: T, the values gathered per gauge

    @classmethod
    def of(cls, case: Any, problem: Any) -> Gauges | None:
        """The gauges of ``case`` (None without any), their particles chosen in
        ``problem`` (:class:`impactsph.problem.Problem`)."""
        from .materials import TableLayout

        if not problem.gauges:
            return None
        s = problem.state
        dim = s.dim
        width_state = s.material_state.shape[1]
        # the gathered table: position, displacement, velocity (dim each), density,
        # pressure, specific energy, 6 stress components, von Mises, plastic work, state
        offsets: dict[str, int] = {}
        at = 0
        for field, size in (("position", dim), ("displacement", dim), ("velocity", dim),
                            ("density", 1), ("pressure", 1), ("specific_energy", 1),
                            ("deviatoric_stress", 6), ("von_mises_stress", 1),
                            ("plastic_work", 1), ("material_state", width_state)):
            offsets[field] = at
            at += size
        names = list(problem.gauges)
        columns, select = ["time"], []
        needs_pressure = False
        by_name = {g.name: g for g in case.output.gauges}
        for k, name in enumerate(names):
            i = problem.gauges[name]
            state_columns = TableLayout.registered().state_names(problem.materials[s.material[i]])
            for field in by_name[name].fields:
                suffixes = field_columns(field, dim, tuple(state_columns))
                columns += [f"{name}_{c}" for c in suffixes]
                if field == "material_state":
                    select += [k * at + offsets[field] + c for c in state_columns.values()]
                else:
                    select += [k * at + offsets[field] + c for c in range(len(suffixes))]
                needs_pressure |= field == "pressure"
        return cls(names, np.array([problem.gauges[n] for n in names], dtype=np.int64),
                   columns, np.array(select, dtype=np.int64), needs_pressure, at)

    def rows_of(self, state: Any) -> SimpleNamespace:
        """The integrated fields of the gauges' particles in ``state`` (a
        :class:`~impactsph.state.ParticleState`), as :meth:`sample_rows` takes them (the
        whole step on the GPU takes the same rows from the device:
        :meth:`impactsph.gpu_step.ResidentStep.gauge_rows`)."""
        i = self.indices
        return SimpleNamespace(position=state.position[i], velocity=state.velocity[i],
                               density=state.density[i],
                               specific_energy=state.specific_energy[i],
                               deviatoric_stress=state.deviatoric_stress[i],
                               plastic_work=state.plastic_work[i],
                               material_state=state.material_state[i])

    def sample_rows(self, time: float, rows: SimpleNamespace, initial_position: np.ndarray,
                    material: np.ndarray, table: np.ndarray) -> np.ndarray:
        """The row at ``time`` from the gauges' particles' fields ``rows`` (:meth:`rows_of`),
        their ``initial_position`` and ``material`` (one row each) and the materials'
        ``table``: the time, then every gauge's values."""
        from .models.columns import THICKNESS_RATIO
        from .models.strength.von_mises import von_mises_stress
        from .physics.rates import pressures

        k = self.indices.shape[0]
        x = rows.position
        S = rows.deviatoric_stress
        state = rows.material_state
        # (the material density as ParticleState.material_density: over the thickness ratio)
        pressure = (pressures(rows.density / state[:, THICKNESS_RATIO], rows.specific_energy,
                              material, table, x.shape[1]) if self.needs_pressure
                    else np.zeros(k))
        pressure = carried_pressure(pressure, state[:, DAMAGE])
        values = np.concatenate([
            x, x - initial_position, rows.velocity, rows.density[:, None], pressure[:, None],
            rows.specific_energy[:, None],
            np.stack([S[:, a, b] for _, a, b in STRESS_COMPONENTS], axis=1),
            von_mises_stress(S)[:, None], rows.plastic_work[:, None], state], axis=1)
        return np.concatenate([[time], values.ravel()[self.select]])


def gauge_rows(columns: list[str], rows: list[np.ndarray], start: int = 0
               ) -> list[dict[str, Any]]:
    """The rows of ``gauges.csv`` from the ``start``-th on, as dicts of floats."""
    return [dict(zip(columns, map(float, row), strict=True)) for row in rows[start:]]


def gauge_summary(sim: Any) -> dict[str, dict[str, Any]]:
    """Per gauge: its particle, body and initial position, its final displacement (vector,
    m), and the largest ``|u|`` over the recorded rows with the displacement of that row
    (m): the penetration or deflection at the gauge."""
    out: dict[str, dict[str, Any]] = {}
    s = sim.state
    gauges = getattr(sim, "gauges", None)
    rows = np.array(sim.record.gauges) if sim.record.gauges else None
    for name, i in sim.problem.gauges.items():
        u = s.position[i] - s.initial_position[i]
        entry: dict[str, Any] = {
            "index": int(i), **sim.problem.input_number(i),
            "body": sim.problem.body_names[s.body[i]],
            "initial_position": s.initial_position[i].tolist(),
            "final_displacement": u.tolist()}
        history = None
        if gauges is not None and rows is not None:
            axes = "xyz"[: s.dim]
            for stem, offset in (("u", False), ("", True)):
                cols = [f"{name}_{stem}{a}" for a in axes]
                if all(c in gauges.columns for c in cols):
                    history = rows[:, [gauges.columns.index(c) for c in cols]]
                    if offset:
                        history = history - s.initial_position[i]
                    break
        if history is None:
            history = u[None, :]
        size = np.linalg.norm(history, axis=1)
        k = int(np.argmax(size))
        entry["max_displacement"] = float(size[k])
        entry["displacement_at_max"] = history[k].tolist()
        out[name] = entry
    return out
