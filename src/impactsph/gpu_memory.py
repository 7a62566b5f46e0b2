"""The GPU memory of a run with its state on the device, before any work.

:class:`impactsph.gpu_step.ResidentStep` holds every array of a run on the GPU: the state,
the step's start copies, the rate outputs, the packed records, the extended rows of the
walls' ghosts, the neighbour list and the build's buffers, the block sums.  Their sizes
follow from a few counts (particles, ghosts, neighbour-list entries, the build's cells) and
from what the case switches on (walls, symmetry planes, a correction, a switch, the hourglass
control, SSP-RK3, the compatible energy update, the stretch, ...).  :class:`DeviceLayout`
holds the switches, :meth:`DeviceLayout.parts` the bytes, array group by array group, each
term the size of an allocation of :class:`~impactsph.gpu_step.ResidentStep` (its
``_allocate``, ``_rows``, ``_packed``, ``upload`` and the builds' ``_buffer``\\ s).

:func:`impactsph.preflight.preflight` uses it to refuse a run that would not fit in the
GPU's free memory, with a one-line error that names the field, before any particle is
placed; ``tests/test_gpu_step.py`` holds it to the allocations the device runs of
``tests/test_gpu.py`` make in numba's CUDA simulator (each array counted once), so that an
array added to the step without a term here fails a test.

:func:`arrays_of` walks what a run holds, each array once: the device's allocations (the
summary's ``device_memory_bytes``, :meth:`ResidentStep.allocated`) or the host's
(``benchmarks/bench_memory.py``).

No CUDA import (the preflight of a case without a GPU reads it too).
"""

from __future__ import annotations

import math
import types
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

#: The device builds' kept buffers grow by 1/BUFFER_MARGIN more than they need (the list's
#: indices are most of them: about 290 B a particle in 3D, 1/8 of it was 37 B;
#: :meth:`impactsph.gpu_step.ResidentStep._buffer`).
BUFFER_MARGIN = 32
#: Entries of a device prefix sum that one thread adds serially (the chunks' sums are summed
#: the same way, recursively: :func:`impactsph.gpu_step.prefix_sum`).
SCAN_CHUNK = 256
#: the books, the survey's record, the staleness tests' two slots, the bad-value code
_BOOKS_BYTES = 17 * 8 + 7 * 8 + 2 * 8 + 8


def _margin(rows: float) -> float:
    """A kept buffer's rows for ``rows`` (:meth:`ResidentStep._buffer`)."""
    return max(rows + rows // BUFFER_MARGIN, 1)


@dataclass(frozen=True)
class DeviceLayout:
    """What sets the sizes of a device run's arrays, besides its counts.

    ``dim``; ``strength_width``: the material state's columns; ``record_columns`` and
    ``record_bytes``: the packed records' columns (:func:`impactsph.gpu.record_columns`) and
    bytes a number (8, or 4 with ``compute.record_precision = "float32"``); ``carried``: the
    passes' copy of the common material state (its columns, ``PASS_CARRIED``) with a
    viscosity switch; ``walls``: rigid walls or symmetry planes (ghost rows; ``planes``: some
    of them symmetry planes, ``n_walls`` in all, ``layer``: the walls' penalty layer,
    ``wall_friction``: a wall with Coulomb friction); ``contact``: several bodies or walls
    (the contact force); ``bodies``; ``corrected``: a viscosity scheme with a correction;
    ``switched``: with a switch; ``hourglass``: the hourglass control; ``ssp``: SSP-RK3;
    ``step_means``: its step's mean acceleration is kept (clamps or driven regions);
    ``compatible``: the compatible energy update; ``stretch``: ``kernel.max_stretch`` > 1;
    ``added_inertia``: a tip mass carried as added inertia; ``state_kept``: how many
    of the material state's columns the step's start copy keeps
    (:func:`impactsph.integrate.material_state_kept`: those a model changes; None: all
    ``strength_width``); ``threads_per_block``."""

    dim: int
    strength_width: int
    record_columns: int
    record_bytes: int = 8
    carried: int = 0
    walls: bool = False
    planes: bool = False
    n_walls: int = 0
    layer: bool = False
    wall_friction: bool = False
    contact: bool = False
    bodies: int = 1
    corrected: bool = False
    switched: bool = False
    hourglass: bool = False
    ssp: bool = False
    step_means: bool = False
    compatible: bool = False
    stretch: bool = False
    added_inertia: bool = False
    state_kept: int | None = None
    threads_per_block: int = 128

    @classmethod
    def of_case(cls, case: Any, threads_per_block: int = 128) -> DeviceLayout:
        """The layout of a validated case's device run (its ``kernel.max_stretch``
        resolved; the axisymmetric axis is one of its ``boundaries``)."""
        from .boundaries import SYMMETRY, walls_of
        from .models import VISCOSITY
        from .models.columns import PASS_CARRIED
        from .physics.options import PassOptions
        from .preflight import state_kept, state_width

        dim = case.dimension
        scheme = VISCOSITY[case.viscosity.scheme]
        walls = walls_of(case.boundaries, dim)
        n_walls = len(walls)
        planes = bool(n_walls and (walls.kinds == SYMMETRY).any())
        rigid = bool(n_walls and (walls.kinds != SYMMETRY).any())
        options = PassOptions.of_case(case)
        columns = options.record_layout(dim)
        corrected = scheme.correction is not None
        switched = scheme.switch is not None
        return cls(
            dim=dim, strength_width=state_width(case),
            record_columns=columns["columns" if corrected or switched else "u"],
            record_bytes=4 if options.record_precision == "float32" else 8,
            carried=PASS_CARRIED if switched else 0,
            walls=bool(n_walls), planes=planes, n_walls=n_walls,
            layer=bool(n_walls) and case.contact.wall_layer > 0.0 and rigid,
            wall_friction=bool(n_walls and (walls.friction > 0.0).any()),
            contact=len(case.bodies) > 1 or bool(n_walls), bodies=len(case.bodies),
            corrected=corrected, switched=switched,
            hourglass=case.stabilisation.hourglass > 0.0,
            ssp=case.time.integrator == "ssp_rk3",
            step_means=any(b.clamped is not None or b.driven for b in case.bodies),
            compatible=case.time.energy_update == "compatible",
            stretch=float(case.kernel.max_stretch) > 1.0,
            added_inertia=any(b.tip_mass is not None
                              and b.tip_mass.carried_as == "added_inertia"
                              for b in case.bodies),
            state_kept=state_kept(case), threads_per_block=threads_per_block)

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def parts(self, n: int, ghosts: int = 0, entries: float = 0.0, cells: float = 0.0,
              *, table_bytes: int = 0, clamped: int = 0, driven: int = 0,
              regions: int = 0, probes: int = 0, gauges: int = 0, built: bool = True,
              capacity: int | None = None) -> dict[str, float]:
        """The device's bytes for ``n`` particles, ``ghosts`` ghost rows, ``entries``
        neighbour-list entries and ``cells`` cells of the build's grid, by group:

        - ``state``: the integrated fields (position, velocity, density, energy, the 3 x 3
          deviator, plastic work, material state, the hourglass acceleration), the constant
          ones (mass, h, material, body, clamped, initial position), the inertia and the
          inertia fraction with added inertia, a switch's factors and memories (4), the
          smoothing lengths at t = 0 with the stretch;
        - ``step``: the step's start copy (the deviator's six components) and SSP-RK3's
          second one, its mean acceleration and mean contact force;
        - ``outputs``: the rate outputs (density, acceleration, energy and heating rates, pair
          count, the six-component stress rate; the contact force, the correction's and the
          hourglass control's where used) and the compatible update's work pass's (with the
          step's mean velocity of every row);
        - ``records``: the packed records, the list's reference positions (float32) and
          with the hourglass control the rows' velocity gradients, each for the rows'
          capacity (the particles; with walls, the rows and ghosts with 1/8 more and 16);
        - ``rows``: with walls, the extended rows (position, velocity, density, energy, the
          3 x 3 deviator, the passes' material state, mass, h, material, body); without,
          a switch's passes' copy of the material state;
        - ``walls``: the constraint's scratch, the penalty layer's and the walls' friction
          forces, the ghost search's counts and ends, the ghosts' sources and walls, and with
          symmetry planes the rows' positions, ends and places in the records;
        - ``list``: the neighbour list (order, offsets, indices), the build's sort keys and
          sorted positions (in the rate outputs' room without ghosts), the cells' counts,
          fills and ends, the prefix sums' chunk totals, and the stretch's rows;
        - ``small``: the block sums (survey, totals, bodies, the constraint, the clamps, the
          driven regions), the books and counters, the material table, the walls' planes,
          the clamped and driven rows, the probes' and gauges' rows and values.

        ``probes`` and ``gauges``: the output's probes and gauges (each a row and its
        values).  ``built``: after a neighbour build on the device (every run that rebuilds its list
        once): its kept buffers, with their 1/32 margin (what a buffer reached at an earlier
        build is not counted: a list that shrank still holds its largest size); else the
        host's list and ghosts as the run handed them over.  ``table_bytes``, ``clamped``,
        ``driven`` and ``regions``: the material table, the clamped and driven particles and
        the driven regions.  ``capacity``: with walls, the rows the extended arrays were
        made for (they are made again, with 1/8 more and 16, only when the rows outgrow
        them); by default those of ``n + ghosts`` rows."""
        d, w = self.dim, self.strength_width
        hg = d if self.hourglass else 0
        rows = n + ghosts
        if not self.walls:
            capacity = n
        elif capacity is None:  # (as allocated for the rows at t = 0)
            capacity = rows + rows // 8 + 16
        blocks = max(1, math.ceil(n / self.threads_per_block))
        integrated = 16 * d + 8 + 8 + 72 + 8 + 8 * w + 8 * hg
        # the deviator's six components; of the material state the columns a model changes
        kept = w if self.state_kept is None else self.state_kept
        start = integrated - 72 + 48 - 8 * (w - kept)
        parts: dict[str, float] = {}
        parts["state"] = n * (integrated + 8 + 8 + 4 + 4 + 1 + 8 * d
                              + (16 if self.added_inertia else 0)
                              + (32 if self.switched else 0)
                              + (8 if self.stretch else 0))
        parts["step"] = n * (start * (2 if self.ssp else 1)
                             + (8 * d if self.ssp and self.step_means else 0)
                             + (8 * d if self.ssp and self.bodies > 1 else 0))
        outputs = 8 + 8 * d + 8 + 8 + 4 + 48  # (the pair count in int32, as the CPU's)
        parts["outputs"] = n * (outputs + (8 * d if self.contact else 0)
                                + (16 if self.corrected else 0) + 8 * hg
                                + (outputs + 8 if self.compatible else 0))
        if self.compatible:  # the step's mean velocity, ghosts' rows included
            parts["outputs"] += 8 * d * _margin(rows)
        parts["records"] = capacity * (self.record_columns * self.record_bytes + 4 * d
                                       + 8 * d * d * (1 if self.hourglass else 0))
        carried = self.carried if self.switched else w
        if self.walls:
            parts["rows"] = capacity * (16 * d + 8 + 8 + 72 + 8 * carried + 8 + 8 + 4 + 4)
        else:
            parts["rows"] = n * 8 * self.carried if self.switched else 0
        walls = 0.0
        if self.walls:
            walls += n * 32 + (8 * d * n if self.layer else 0) \
                + (8 * d * n if self.wall_friction else 0)
            if built:  # the ghost search's counts and ends; its kept sources and walls
                walls += 2 * 8 * _margin(n) + 2 * 8 * _margin(ghosts)
            else:  # the host's ghosts, as handed over
                walls += 2 * 8 * ghosts
            if self.planes:  # each row's place in the records (and the search's rows)
                walls += 8 * _margin(rows)
                if built:
                    walls += 8 * d * _margin(rows) + 8 * _margin(rows)
        parts["walls"] = walls
        if built:
            listed = 4 * _margin(rows) + 8 * _margin(rows + 1) + 4 * _margin(entries) \
                + 3 * 8 * _margin(cells) + 3 * 8 * d  # (and the grid's bounds and shape)
            if ghosts:  # the sort keys and sorted positions outgrow the rate outputs' room
                listed += 8 * _margin(rows) + 8 * d * _margin(rows)
            chunks = math.ceil(max(rows, cells) / SCAN_CHUNK)  # each depth's chunk totals
            while True:
                listed += 8 * _margin(chunks)
                if chunks <= 1:
                    break
                chunks = math.ceil(chunks / SCAN_CHUNK)
            if self.stretch:  # its rows and the largest h
                listed += (16 * d + 16) * _margin(rows) + 8
        else:  # the host's list, as handed over (its offsets int32 where they fit)
            listed = 4 * rows + (4 if entries < 2**31 else 8) * (rows + 1) + 4 * entries
        parts["list"] = listed
        block_sums = blocks * (48 + 56 + 8 * (4 + d) + (32 if self.walls else 0))
        block_sums += 24 * max(1, math.ceil(clamped / self.threads_per_block))
        block_sums += 24 * (regions + math.ceil(driven / self.threads_per_block))
        parts["small"] = (block_sums + _BOOKS_BYTES + 8 * (4 + d) * max(self.bodies, 1)
                          + 8 * d + table_bytes + 8 * clamped + 8 * driven
                          + 24 * max(regions, 1) + 8
                          + self.n_walls * (16 * d + 1 + 8)
                          + probes * (8 + 8 * d) + gauges * (8 + 8 * (2 * d + 12 + w)))
        return parts

    def bytes(self, n: int, ghosts: int = 0, entries: float = 0.0, cells: float = 0.0,
              **small: int) -> float:
        """The sum of :meth:`parts`."""
        return float(sum(self.parts(n, ghosts, entries, cells, **small).values()))

    def host_path_parts(self, n: int, ghosts: int = 0, entries: float = 0.0, *,
                        table_bytes: int = 0, count_bytes: int = 4) -> dict[str, float]:
        """The device's bytes of a run whose rates alone are on the GPU
        (``compute.resident = false``: :class:`impactsph.gpu.GpuRates`'s arrays, each
        evaluation's state copied up and its rates down), for ``n`` particles, ``ghosts``
        ghost rows and ``entries`` list entries, by group: ``state`` (the rows' position,
        velocity, density, energy, the 3 x 3 deviator, the passes' material state, mass, h,
        material, body; with the hourglass control the particles' acceleration), ``list``
        (order, offsets, indices, the host's: offsets int32 where they fit), ``records``
        (the packed records, and the velocity gradients with the hourglass control) and
        ``outputs`` (the rate outputs for every row, the contact force, the correction's,
        the switch's and the hourglass control's where the run has them; ``count_bytes``:
        the pair count's, the host buffer's type)."""
        d, w = self.dim, self.strength_width
        rows = n + ghosts
        carried = self.carried if self.switched else w
        return {
            "state": rows * (16 * d + 8 + 8 + 72 + 8 * carried + 8 + 8 + 4 + 4)
            + (8 * d * n if self.hourglass else 0) + table_bytes,
            "list": 4 * rows + (4 if entries < 2**31 else 8) * (rows + 1) + 4 * entries,
            "records": rows * (self.record_columns * self.record_bytes
                               + (8 * d * d if self.hourglass else 0)),
            "outputs": rows * (8 + 8 * d + 8 + 8 + count_bytes + 48
                               + (8 * d if self.contact else 0)
                               + (16 if self.corrected else 0)
                               + (16 if self.switched else 0)
                               + (8 * d if self.hourglass else 0))}


# -- what a run holds (benchmarks/bench_memory.py; the device's, tests/test_gpu_step.py) ------
#: objects whose insides are not the run's arrays
SKIPPED = (str, bytes, int, float, complex, bool, type, types.ModuleType, types.FunctionType,
           types.BuiltinFunctionType, types.MethodType)


def _base(array: np.ndarray) -> np.ndarray:
    while isinstance(array.base, np.ndarray):
        array = array.base
    return array


def device_allocation(array: object) -> tuple[int, int] | None:
    """``(key, bytes)`` of the device allocation a CUDA array (or a view of one) lives in:
    a GPU's memory pointer's owner, or the simulator's numpy base; None for other objects."""
    name = type(array).__name__
    if name == "FakeCUDAArray":  # numba's CUDA simulator: a numpy array inside
        base = _base(array._ary)
        return id(base), base.nbytes
    if name in ("DeviceNDArray", "DeviceRecord", "MappedNDArray"):
        pointer = array.gpu_data
        if pointer is None:  # (an empty array without a pointer)
            return None
        owner = getattr(pointer, "owner", None) or pointer
        return id(owner), int(owner.size)
    return None


def arrays_of(root: object, name: str = "sim", depth: int = 14,
              device: bool = False) -> dict[int, tuple[int, str]]:
    """``{id(base): (bytes, path)}`` for every array reachable from ``root`` through
    attributes, dict values and list or tuple items (the first path that reaches it): the
    host's numpy arrays, or with ``device`` the CUDA arrays (a GPU's or the simulator's)."""
    found: dict[int, tuple[int, str]] = {}
    seen: set[int] = set()
    stack = [(root, name, 0)]
    while stack:
        obj, path, level = stack.pop()
        if id(obj) in seen or level > depth or isinstance(obj, SKIPPED):
            continue
        seen.add(id(obj))
        allocation = device_allocation(obj)
        if allocation is not None:
            if device:
                found.setdefault(allocation[0], (allocation[1], path))
            continue
        if isinstance(obj, np.ndarray):
            if device:
                continue
            base = _base(obj)
            found.setdefault(id(base), (base.nbytes, path))
            continue
        if type(obj) is dict:
            stack.extend((v, f"{path}[{k!r}]", level + 1) for k, v in obj.items())
        elif type(obj) in (list, tuple):
            stack.extend((v, f"{path}[{k}]", level + 1) for k, v in enumerate(obj))
        else:
            attributes = getattr(obj, "__dict__", None)
            if type(attributes) is dict:
                stack.extend((v, f"{path}.{k}", level + 1) for k, v in attributes.items())
            for slot in getattr(type(obj), "__slots__", ()):
                if hasattr(obj, slot):
                    stack.append((getattr(obj, slot), f"{path}.{slot}", level + 1))
    return found
