"""ParaView output: one VTK XML unstructured-grid file (``.vtu``) of particles (vertex cells)
per snapshot, written with meshio, and a ``.pvd`` collection that indexes them by time.

Point data: velocity (m/s, 3 components), density (kg/m^3), pressure (Pa; a damaged particle's
tension reduced by ``1 - D``), deviatoric stress (Pa, 9 components, row-major; undamaged, as
integrated), von Mises stress (Pa, of the damaged deviator ``(1 - D) S``: what the particle
carries), plastic flag (1 where the particle yielded in the last step), specific internal
energy (J/kg), body id, plastic work (J/kg), equivalent plastic strain (-), plastic strain
rate (1/s), temperature (K), damage (-); in a renumbered run (``compute.particle_order``) each
particle's input number (``input_index``).  In 1D and 2D the missing coordinates are written as
zero.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from .atomic import atomic_path, write_text
from .materials import carried_von_mises
from .models.columns import COMMON_STATE, DAMAGE, PLASTIC_STRAIN_RATE


def particle_fields(sim: Any) -> dict[str, np.ndarray]:
    """The point data of the current state."""
    s = sim.state
    n = s.n
    vel = np.zeros((n, 3))
    vel[:, : s.dim] = s.velocity
    damage = s.material_state[:, DAMAGE]
    vm = carried_von_mises(s.deviatoric_stress, damage)
    plastic = s.material_state[:, PLASTIC_STRAIN_RATE] > 0.0
    renumbered = sim.problem.input_index
    return {
        "velocity": vel,
        "density": s.density.copy(),
        "pressure": sim.solver.pressure(sim.state)[:n],
        "deviatoric_stress": s.deviatoric_stress.reshape(n, 9).copy(),
        "von_mises_stress": vm,
        "plastic": plastic.astype(np.int32),
        "specific_internal_energy": s.specific_energy.copy(),
        "body": s.body.astype(np.int32),
        "plastic_work": s.plastic_work.copy(),
        **{name: s.material_state[:, k].copy() for k, name in enumerate(COMMON_STATE)},
        "viscosity_factor": s.viscosity_factor.copy(),
        # a renumbered run (compute.particle_order): each particle's number as placed
        **({} if renumbered is None else {"input_index": renumbered.astype(np.int64)}),
    }


class VTKSeries:
    """A growing time series of particle snapshots in ``directory``."""

    def __init__(self, directory: Path, name: str = "particles", binary: bool = True) -> None:
        self.binary = binary
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.name = name
        self.entries: list[tuple[float, str]] = []

    def resume(self, time: float) -> None:
        """Continue the series of an earlier run: keep its entries up to ``time``."""
        import xml.etree.ElementTree as ET

        index = self.directory / f"{self.name}.pvd"
        if index.exists():
            root = ET.parse(index).getroot()
            self.entries = [(float(d.get("timestep")), d.get("file"))
                            for d in root.iter("DataSet") if float(d.get("timestep")) <= time]

    def write(self, sim: Any) -> Path:
        """Write the current state and rewrite the index."""
        s = sim.state
        points = np.zeros((s.n, 3))
        points[:, : s.dim] = s.position
        cells = [("vertex", np.arange(s.n, dtype=np.int64).reshape(-1, 1))]
        mesh = meshio.Mesh(points, cells, point_data=particle_fields(sim))
        fname = f"{self.name}_{len(self.entries):05d}.vtu"
        path = self.directory / fname
        with atomic_path(path) as tmp:
            meshio.write(tmp, mesh, file_format="vtu", binary=self.binary)
        self.entries.append((s.time, fname))
        self._write_index()
        return path

    def _write_index(self) -> None:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        for t, fname in self.entries:
            lines.append(f'    <DataSet timestep="{t!r}" group="" part="0" '
                         f"file={quoteattr(fname)}/>")
        lines += ["  </Collection>", "</VTKFile>", ""]
        write_text(self.directory / f"{self.name}.pvd", "\n".join(lines))
