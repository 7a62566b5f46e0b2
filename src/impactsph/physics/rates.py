"""The rate passes on the CPU (numba threads): :class:`CpuRates` runs the passes of
:mod:`.passes`, bound to the registered models and the run's dimension
(:mod:`impactsph.codegen`), and fills a :class:`RateBuffers`.

:class:`impactsph.gpu.GpuRates` is the other backend: the same bodies as CUDA kernels, the
same ``evaluate`` and the same results to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import ModuleType
from typing import Any

import numba as nb
import numpy as np

from .. import codegen
from ..models import VISCOSITY
from . import passes as _template
from .chunked import run_chunked, threads_for
from .options import PassOptions
from .records import record_columns


def compiled_passes(dim: int, simulated: bool = False,
                    options: PassOptions | str | None = None) -> ModuleType:
    """The generated passes module for ``dim``, the registered models and the compile-time
    ``options`` (:class:`~impactsph.physics.options.PassOptions`, or a gradient-correction
    mode by name)."""
    return codegen.load(_template, dim, simulated, options)


def chunk_size(n: int) -> int:
    """Particles per parallel work item: about eight items per thread (so that the threads
    share the work evenly even for a thousand particles), 16 to 512.  Each particle's sums
    are the same whatever the chunking."""
    return int(min(512, max(16, n // (8 * nb.get_num_threads()))))


@dataclass(frozen=True)
class ViscositySettings:
    """A run's viscosity scheme as the passes take it: its kind code (position in the
    registry), the four floats of its pair term and, for a scheme with a correction, the four
    of the correction (None otherwise)."""

    kind: int
    pair: tuple[float, float, float, float]
    correction: tuple[float, float, float, float] | None = None
    switch: tuple[float, float, float, float] | None = None
    #: the pair term takes the reconstructed velocity jump (passes compiled with
    #: ``PassOptions(velocity_reconstruction=True)``)
    reconstruction: bool = False
    #: how far the correction reads its neighbours, a fraction of the support (the correction
    #: pass reads each row's inner entries where the list has an inner list that reaches so
    #: far: ``NeighbourList.within``)
    correction_reach: float = 1.0
    #: the same for the switch pass
    switch_reach: float = 1.0

    @property
    def inner_reach(self) -> float:
        """The reach of the neighbour list's inner list that the passes read: the shorter
        of the correction's and the switch's (1: none needed)."""
        reach = 1.0
        if self.correction is not None:
            reach = min(reach, self.correction_reach)
        if self.switch is not None:
            reach = min(reach, self.switch_reach)
        return reach

    @classmethod
    def of(cls, viscosity: Any) -> ViscositySettings:
        """From a ``[viscosity]`` table (anything with ``.scheme`` and the scheme's
        parameters as attributes)."""
        scheme = VISCOSITY[viscosity.scheme]
        correction = (tuple(float(c) for c in scheme.correction_parameters(viscosity))
                      if scheme.correction is not None else None)
        switch = (tuple(float(c) for c in scheme.switch_parameters(viscosity))
                  if scheme.switch is not None else None)
        # (a reach without its pass is ignored by inner_reach)
        reach = (float(scheme.correction_reach(viscosity))
                 if scheme.correction_reach is not None else 1.0)
        switch_reach = (float(scheme.switch_reach(viscosity))
                        if scheme.switch_reach is not None else 1.0)
        return cls(VISCOSITY.index(scheme.name),
                   tuple(float(c) for c in scheme.pair_parameters(viscosity)), correction,
                   switch, bool(scheme.reconstruction), reach, switch_reach)

    def check_compiled(self, reconstruction: bool, viscosity_factor: bool) -> None:
        """Refuse passes compiled for the other kind of velocity jump (a reconstructing
        scheme's pair term is a compile-time variant of the passes), or for the other answer
        to whether the scheme has a switch (passes with the factor read it from columns
        ``VISCOSITY_FACTOR`` and ``VISCOSITY_MEMORY`` of ``carried``, which without a switch
        may be the material state's own columns: ``Solver._arrays``)."""
        if self.reconstruction != reconstruction:
            raise ValueError(f"a viscosity scheme with reconstruction = {self.reconstruction} "
                             f"needs passes compiled with "
                             f"PassOptions(velocity_reconstruction={self.reconstruction})")
        switched = self.switch is not None
        if switched != viscosity_factor:
            raise ValueError(f"a viscosity scheme {'with' if switched else 'without'} a switch "
                             f"needs passes compiled with "
                             f"PassOptions(viscosity_factor={switched})")


class RateBuffers:
    """Output arrays of one rate evaluation, allocated once per run.  The contact force has
    a row per particle only where there is contact (several bodies, or walls), and the
    correction terms only with a correcting scheme: otherwise they have no rows."""

    def __init__(self, n: int, dim: int, contact: bool = True, corrected: bool = True,
                 hourglass: bool = False, switched: bool = False, compatible: bool = False):
        self.drho = np.zeros(n)
        self.dv = np.zeros((n, dim))
        self.de = np.zeros(n)
        self.de_visc = np.zeros(n)
        self.dS = np.zeros((n, 6))  # the deviator's rate: six components (stress_rate.UPPER)
        self.contact_force = np.zeros((n if contact else 0, dim))
        self.pair_count = np.zeros(n, dtype=np.int32)
        #: a correcting scheme's books of each particle: the correction's power and its
        #: heating per unit mass (W/kg; its acceleration and heating are in dv and de)
        self.correction_books = np.zeros((n if corrected else 0, 2))
        self.dhg = np.zeros((n if hourglass else 0, dim))  # the hourglass acceleration's rate
        #: the viscosity switch's factor of each particle, for the next evaluation
        self.factor = np.ones(n if switched else 0)
        #: the switch's memory of each particle, for the next evaluation
        self.memory = np.zeros(n if switched else 0)
        #: the pair pass's own specific-energy rates (the compatible energy update replaces
        #: them after the step: :meth:`impactsph.solver.Solver.work_rates`)
        self.de_pairs = np.zeros(n if compatible else 0)


class CpuRates:
    """The rate passes on the CPU: fills a :class:`RateBuffers`."""

    device = "cpu"

    def __init__(self, dim: int, options: PassOptions | str | None = None):
        self.dim = dim
        self.options = PassOptions.coerce(options)
        self.passes = compiled_passes(dim, options=self.options)
        self._packed: np.ndarray | None = None  # the packed particle records (.records)
        self._chunk: tuple[int, int] | None = None  # (rows, particles per work item)
        self._gradients: np.ndarray | None = None  # velocity gradients, for the hourglass pass
        self._switch_passes: dict[int, Any] = {}
        self._uniform: ModuleType | None = None  # the passes with PassOptions.uniform_h
        self._loops = self.passes  # the module of the last evaluation's neighbour loops

    def switch_pass(self, kind: int) -> Any:
        """The switch pass of the scheme of kind code ``kind``: from a passes module that
        names only that switch (``PassOptions.switch_kind``; the module's other functions are
        never called, so never compiled)."""
        if kind not in self._switch_passes:
            options = replace(self.options.compiled(), switch_kind=kind)
            self._switch_passes[kind] = compiled_passes(self.dim,
                                                        options=options).switch_pass
        return self._switch_passes[kind]

    def neighbour_loops(self, uniform_h: bool) -> ModuleType:
        """The passes module whose vectorised neighbour loops (the moment, velocity-gradient,
        pair and hourglass passes) run an evaluation: where every row's smoothing length is
        the same (``uniform_h``), the module compiled with ``PassOptions.uniform_h``, whose
        loops read no neighbour's h and divide by no pair's (the same results to the bit:
        ``(h + h) / 2`` is ``h``); else the run's own.  Each is compiled on its first use,
        so a run compiles only the one it uses."""
        if not uniform_h:
            return self.passes
        if self._uniform is None:
            self._uniform = compiled_passes(self.dim,
                                            options=replace(self.options, uniform_h=True))
        return self._uniform

    def record_columns(self, viscosity: ViscositySettings) -> int:
        """The packed records' row length for ``viscosity``: every column of the passes'
        layout (:func:`impactsph.physics.records.record_columns`, unpadded), less the viscous
        acceleration's (the last) where no pass reads them, that is for a scheme with neither
        a correction nor a switch (8 ``dim`` bytes a particle and ghost)."""
        k = self.passes
        needed = viscosity.correction is not None or viscosity.switch is not None
        return k.RECORD_COLUMNS if needed else k.U

    def evaluate(self, n_active: int, arrays: tuple, table: np.ndarray, neighbours,
                 viscosity: ViscositySettings, b: RateBuffers, hourglass: float = 0.0,
                 hourglass_acceleration: np.ndarray | None = None,
                 after_pairs=None, after_moments=None, n_bodies: int = 1,
                 switch_elapsed: float = 0.0, uniform_h: bool | None = None) -> None:
        """Rates of the first ``n_active`` rows of ``arrays = (x, v, rho, e, S, m, h,
        material, body, carried)`` (``carried``: the common material state, damage and thickness
        ratio among it; all rows, ghosts included, take part in the sums) into ``b``:
        ``drho``, the total accelerations ``dv`` and specific-energy rates ``de``, the
        viscous heating ``de_visc``, ``contact_force, pair_count, dS`` and, for a scheme with
        a correction, ``correction_books``; with ``hourglass`` (the coefficient zeta) > 0,
        ``dhg`` from the particles' ``hourglass_acceleration`` (added to ``dv``); for a scheme
        with a switch, ``factor`` (each particle's viscosity factor for the next evaluation;
        the factors used are the last column of ``carried``, set ``switch_elapsed`` seconds
        before).
        ``after_pairs(packed, gradients, u_column)``, if given, runs after the pair pass and
        before the passes that read its per-particle results (the symmetry planes' mirror:
        :func:`impactsph.boundaries.mirror_ghost_results`); ``after_moments(packed, c0)``
        likewise after the correction matrices and after the velocity gradients of a
        reconstructing viscosity (``c0`` their first record column).  With the
        options' ``contact_friction`` > 0, the friction between the ``n_bodies`` bodies (rows
        of a body index at or above it are rigid walls' ghosts) is added after the pairs.
        ``uniform_h``: whether every row's smoothing length is the same, so that the
        neighbour loops may take the particle's own h for each pair's
        (:meth:`neighbour_loops`): None to see it here, from the rows' ``h`` the loops read
        (the solver's choice, but for a run whose h may come to differ: False)."""
        x, v, rho, e, S, m, h, material, body, carried = arrays
        k = self.passes
        if uniform_h is None:
            uniform_h = h.shape[0] > 0 and float(h.min()) == float(h.max())
        loops = self._loops = self.neighbour_loops(uniform_h)
        viscosity.check_compiled(k.VELOCITY_RECONSTRUCTION, k.VISCOSITY_FACTOR)
        nl = neighbours
        n = x.shape[0]
        columns = self.record_columns(viscosity)
        if self._packed is None or self._packed.shape != (n, columns):
            self._packed = np.empty((n, columns), self.options.record_dtype)
        if n >= k.PREFETCH_ROWS:  # (the state read in sequence: passes.own_order_particle_pass)
            k.own_order_particle_pass(nl.rank, x, v, m, rho, e, S, carried, h, body, material,
                                      table, self._packed)
        else:
            k.particle_pass(nl.order, x, v, m, rho, e, S, carried, h, body, material, table,
                            self._packed)
        if self._chunk is None or self._chunk[0] != n:  # get_num_threads takes a lock
            self._chunk = (n, chunk_size(n))
        chunk = self._chunk[1]
        threads = threads_for(n, chunk, self.options.parallel)
        if hourglass > 0.0 and (b.dhg.shape[0] < n_active or hourglass_acceleration is None
                                or hourglass_acceleration.shape != (n_active, self.dim)):
            raise ValueError("the hourglass control needs RateBuffers(..., hourglass=True) and "
                             "an (n_active, dim) hourglass_acceleration")
        rows = n if hourglass > 0.0 else 0
        if self._gradients is None or self._gradients.shape[0] != rows:
            self._gradients = np.empty((rows, self.dim, self.dim))
        if k.FORCE_CORRECTION:
            run_chunked(loops.moment_pass, threads, nl.order, self._packed, nl.offsets,
                        nl.indices, nl.filter_starts, chunk)
            if after_moments is not None:
                after_moments(self._packed, k.CM0)
        if k.VELOCITY_RECONSTRUCTION:
            run_chunked(loops.gradient_pass, threads, nl.order, self._packed, nl.offsets,
                        nl.indices, nl.filter_starts, chunk)
            if after_moments is not None:  # a matrix as C: a mirror ghost gets R L R
                after_moments(self._packed, k.LV0)
        run_chunked(loops.pair_pass, threads, n_active, nl.order, self._packed, nl.offsets,
                    nl.indices, nl.filter_starts, viscosity.kind, viscosity.pair,
                    self.options.normal_stress, S, material, table, b.drho, b.dv, b.de,
                    b.de_visc, b.contact_force, b.pair_count, b.dS, self._gradients, chunk)
        if b.de_pairs.shape[0]:
            np.copyto(b.de_pairs[:n_active], b.de[:n_active])
        if after_pairs is not None:
            after_pairs(self._packed, self._gradients, k.U)
        if self.options.contact_friction > 0.0:
            k.friction_pass(n_active, nl.order, self._packed, nl.offsets, nl.indices,
                            viscosity.kind, viscosity.pair, self.options.contact_friction,
                            n_bodies, self.options.normal_stress, b.dv, b.de, b.contact_force,
                            chunk)
        if viscosity.correction is not None:  # (the inner list where there is one)
            k.correction_pass(n_active, nl.order, self._packed, nl.offsets,
                              nl.within(viscosity.correction_reach), nl.indices,
                              viscosity.kind, viscosity.correction, b.correction_books,
                              b.dv, b.de, chunk)
        if viscosity.switch is not None:
            if b.factor.shape[0] < n_active:
                raise ValueError("a viscosity switch needs RateBuffers(..., switched=True)")
            run_chunked(self.switch_pass(viscosity.kind), threads, n_active, nl.order,
                        self._packed, nl.offsets, nl.within(viscosity.switch_reach),
                        nl.indices, viscosity.kind,
                        viscosity.switch, float(switch_elapsed), b.factor, b.memory, chunk)
        if hourglass > 0.0:
            run_chunked(loops.hourglass_pass, threads, n_active, nl.order, self._packed,
                        self._gradients, nl.offsets, nl.indices, nl.filter_starts, material,
                        table, hourglass, hourglass_acceleration, b.dv, b.de, b.dhg, chunk)


    def work_energy(self, n_active: int, work_velocity: np.ndarray, neighbours,
                    viscosity: ViscositySettings, S: np.ndarray, material: np.ndarray,
                    table: np.ndarray, scratch: RateBuffers) -> np.ndarray:
        """The pair pass's specific-energy rates of the first ``n_active`` rows (W/kg) with
        the records of the last :meth:`evaluate` (its forces) and the velocity differences of
        ``work_velocity`` (one row per row of that evaluation, ghosts included) in the energy
        terms: the compatible energy update's work pass.  ``scratch``: buffers for the pass's
        other results, which are discarded.  Passes compiled with
        ``PassOptions(compatible_energy=True)`` only."""
        k = self.passes
        if not k.COMPATIBLE_ENERGY:
            raise ValueError("the work pass needs passes compiled with "
                             "PassOptions(compatible_energy=True)")
        nl = neighbours
        self._packed[:, k.W:k.W + self.dim] = work_velocity[nl.order]
        # (the evaluation's own module: its neighbour loops, the same sums)
        chunk = self._chunk[1]
        run_chunked(self._loops.pair_pass,
                    threads_for(nl.order.shape[0], chunk, self.options.parallel), n_active,
                    nl.order, self._packed, nl.offsets, nl.indices, nl.filter_starts,
                    viscosity.kind, viscosity.pair, self.options.normal_stress, S, material,
                    table, scratch.drho, scratch.dv, scratch.de, scratch.de_visc,
                    scratch.contact_force[:0], scratch.pair_count, scratch.dS,
                    np.empty((0, self.dim, self.dim)), chunk)
        return scratch.de


def pressures(rho: np.ndarray, e: np.ndarray, material: np.ndarray, table: np.ndarray,
              dim: int, out: np.ndarray | None = None) -> np.ndarray:
    """The pressure of each particle from its material's EOS (Pa), by the passes of the run's
    dimension ``dim`` (the EOS does not depend on it; the run has those compiled already)."""
    out = np.empty(rho.shape[0]) if out is None else out
    return compiled_passes(dim).pressures(rho, e, material, table, out)


def _records_of(x: np.ndarray, v: np.ndarray, m: np.ndarray, rho: np.ndarray, h: np.ndarray,
                body: np.ndarray, neighbours, u: np.ndarray, c: np.ndarray | None = None,
                factor: np.ndarray | None = None, memory: np.ndarray | None = None,
                record_precision: str = "float64") -> np.ndarray:
    """Packed records (:mod:`.records`) of given fields in the list's order, for running one
    per-particle pass alone; in float32 (``record_precision``) with the positions in two
    parts, as the particle pass writes them."""
    n, dim = x.shape
    split = PassOptions(record_precision=record_precision).record_dtype == np.float32
    lay = record_columns(dim, viscosity_factor=factor is not None, split_positions=split)
    order = neighbours.order
    packed = np.zeros((n, lay["width"]), np.float32 if split else np.float64)
    packed[:, lay["x"]:lay["x"] + dim] = x[order]
    if split:  # the rest of each position, after its rounding
        packed[:, lay["xl"]:lay["xl"] + dim] = (
            x[order] - packed[:, lay["x"]:lay["x"] + dim].astype(np.float64))
    packed[:, lay["v"]:lay["v"] + dim] = v[order]
    packed[:, lay["h"]] = h[order]
    packed[:, lay["m"]] = m[order]
    packed[:, lay["volume"]] = (m / rho)[order]
    packed[:, lay["rho"]] = rho[order]
    packed[:, lay["body"]] = body[order]
    packed[:, lay["u"]:lay["u"] + dim] = u[order]
    if c is not None:
        packed[:, lay["c"]] = c[order]
    if factor is not None:
        packed[:, lay["f"]] = factor[order]
        packed[:, lay["f"] + 1] = (np.zeros(n) if memory is None else memory)[order]
    return packed


def correction_only(x: np.ndarray, v: np.ndarray, m: np.ndarray, rho: np.ndarray,
                    h: np.ndarray, body: np.ndarray, neighbours, u: np.ndarray,
                    viscosity: Any, record_precision: str = "float64"
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The correction pass alone on given fields: ``(dv_corr, de_corr)`` for viscous
    accelerations ``u`` (all particles active), for the ``[viscosity]`` table ``viscosity``
    of a correcting scheme, on records of ``record_precision`` (``compute.record_precision``).
    For tests and analysis; the solver runs it inside :meth:`CpuRates.evaluate`."""
    n, dim = x.shape
    packed = _records_of(x, v, m, rho, h, body, neighbours, u,
                         record_precision=record_precision)
    settings = ViscositySettings.of(viscosity)
    # (the pass adds its terms to dv and de: from zeros, they are the terms)
    dv_corr, de_corr = np.zeros((n, dim)), np.zeros(n)
    compiled_passes(dim, options=PassOptions(record_precision=record_precision)).correction_pass(
        n, neighbours.order, packed, neighbours.offsets,
        neighbours.within(settings.correction_reach), neighbours.indices, settings.kind,
        settings.correction, np.zeros((n, 2)), dv_corr, de_corr, chunk_size(n))
    return dv_corr, de_corr


def switch_only(x: np.ndarray, v: np.ndarray, m: np.ndarray, rho: np.ndarray, h: np.ndarray,
                body: np.ndarray, c: np.ndarray, neighbours, u: np.ndarray,
                viscosity: Any, factor: np.ndarray | None = None, elapsed: float = 0.0,
                memory: np.ndarray | None = None, with_memory: bool = False,
                record_precision: str = "float64"):
    """The viscosity switch alone on given fields (wave speeds ``c``, unscaled viscous
    accelerations ``u``, the factors in use ``factor`` (default 1) and the switch's memory
    ``memory`` (default 0), set ``elapsed`` seconds before; all particles active): each
    particle's next factor (and, ``with_memory``, its next memory), for the ``[viscosity]``
    table ``viscosity`` of a scheme with a switch, on records of ``record_precision``
    (``compute.record_precision``).  For tests and analysis."""
    n, dim = x.shape
    factor = np.ones(n) if factor is None else factor
    packed = _records_of(x, v, m, rho, h, body, neighbours, u, c, factor, memory,
                         record_precision)
    settings = ViscositySettings.of(viscosity)
    out, new_memory = np.zeros(n), np.zeros(n)
    compiled_passes(dim, options=PassOptions(viscosity_factor=True, switch_kind=settings.kind,
                                             record_precision=record_precision)).switch_pass(
        0, 1, n, neighbours.order, packed, neighbours.offsets,
        neighbours.within(settings.switch_reach), neighbours.indices, settings.kind,
        settings.switch, float(elapsed), out, new_memory, chunk_size(n))
    return (out, new_memory) if with_memory else out
