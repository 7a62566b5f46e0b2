"""Compile-time options of the generated passes (:mod:`impactsph.codegen`).

Each option changes what the pair loop computes, so each set of options is a module of its own
(its constants bound in, numba compiling only the branches it uses): a run that does not ask
for an option pays nothing for it.  The options come from a case's ``[stabilisation]`` and
``[contact]`` tables (docs/stabilisation.md).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..models.registry import DAMAGE, EOS, STRENGTH, VISCOSITY

#: ``gradient_correction`` modes and the file-name tag of their generated modules
GRADIENT_CORRECTIONS = {"none": "", "velocity_gradient": "_kgc",
                        "velocity_gradient_and_forces": "_kgcf"}
#: ``contact_traction`` modes (a run-time switch of the pair pass: no module of their own)
CONTACT_TRACTIONS = ("pressure", "normal_stress")
#: ``record_precision``: the packed records' dtypes (float32: a module of its own, whose records
#: split the positions)
RECORD_PRECISIONS = ("float64", "float32")
#: the environment variable that compiles the generated passes without numba's parallel
#: transform (:func:`parallel_default`)
PARALLEL_VARIABLE = "IMPACTSPH_PARALLEL"


def parallel_default() -> bool:
    """Whether generated passes are compiled with ``parallel=True``: ``$IMPACTSPH_PARALLEL``
    ``1`` yes, ``0`` no; unset (or empty), yes unless numba has one thread in this process
    (``NUMBA_NUM_THREADS=1``, or a machine of one core), where the threaded passes could only
    cost compile time; anything else is an error naming the variable.

    The serial module runs the same loops over the same chunks on one thread and gives the
    same results to the bit (``tests/test_parallel_passes.py``; its switch pass stays
    threaded).  numba compiles it faster (the 2D pair pass 3.6 s against 9.3 s, the stage 9.6
    s against 13.4 s, a cold Taylor run 33.5 s against 51 s), and on one thread it runs as
    fast as the threaded passes, its arrays without reference counts as numba's threaded
    bodies get them (:mod:`impactsph.physics.borrow`; docs/architecture.md, "Compile
    time").  A process whose numba has one thread takes it by itself (a cold Taylor run on
    one thread 44.9 s serial against 53.6 s threaded, 2026-12-05); the test suite sets it
    (``tests/conftest.py``: its workers run one thread each and compile far more variants
    than they run long), and so may a user whose runs are short enough that compiling them
    is the larger cost.
    """
    value = os.environ.get(PARALLEL_VARIABLE, "").strip()
    if value not in ("0", "1", ""):
        raise ValueError(f"${PARALLEL_VARIABLE} = {value!r}: allowed are 1 (the passes run on "
                         f"numba's threads, the default where numba has more than one) and 0 "
                         f"(compiled serial: quicker to compile, one thread)")
    if value == "":
        import numba

        return int(numba.config.NUMBA_NUM_THREADS) > 1
    return value == "1"


@dataclass(frozen=True)
class PassOptions:
    """The compile-time options of one generated passes module.

    - ``gradient_correction``: ``"none"``, ``"velocity_gradient"`` or
      ``"velocity_gradient_and_forces"`` (kernel gradient correction);
    - ``contact_traction``: what pushes two particles of different bodies (or a particle and
      its wall ghost) apart: ``"pressure"`` (``P_i/rho_i^2 + P_j/rho_j^2``, the paper's
      contact) or ``"normal_stress"`` (the compressive normal stress along the line of
      centres, deviatoric part included); a run-time argument of the pair pass (contact pairs
      are few, so the test costs nothing), not part of the generated module;
    - ``artificial_stress``: Monaghan's (2000) coefficient epsilon, 0 for none;
      ``artificial_stress_exponent`` n and ``reference_q`` = dx / h, the kernel argument at
      which ``f_ij = W(r_ij) / W(dx)`` is 1; ``artificial_stress_compensation``: the smooth
      part of its force cancelled (its pair weight ``f_ij^n - kappa``, ``AS_COMPENSATION``);
    - ``contact_friction``: the Coulomb coefficient between bodies (0: frictionless); a
      run-time argument of the friction pass, which runs only where it is > 0;
    - ``axisymmetric``: a 2D run in axisymmetry (``x`` the radius, ``y`` the axis; the hoop
      terms of :func:`impactsph.physics.passes.particle_rates`);
    - ``plane_stress``: a 2D run in plane stress (``sigma_zz = 0``, each particle's thickness
      changing; :func:`impactsph.physics.passes.plane_stress_return`) instead of plane strain;
    - ``viscosity_factor``: the viscosity scheme has a switch (a per-particle factor on
      ``Pi_ij``, :class:`impactsph.models.registry.ViscosityScheme`): the records carry the
      factor and the pair pass also sums the unscaled viscous acceleration for the switch;
    - ``velocity_reconstruction``: the viscosity scheme takes the velocity jump reconstructed
      to each pair's midpoint (:mod:`impactsph.physics.reconstruction`): the records carry
      each particle's velocity gradient, set by a pass before the pair pass;
    - ``compatible_energy``: the records carry a second velocity, the *work velocity*, which
      the pair pass's energy terms (and only they) read; the ordinary evaluations set it to
      the velocity, and the step's work pass to the step's mean velocity
      (``time.energy_update = "compatible"``, :meth:`impactsph.solver.Solver.work_rates`);
    - ``switch_kind``: the one viscosity switch (its scheme's kind code, the position in the
      registry) the module's ``viscosity_switch`` calls, -1 for all the registered ones
      (dispatched on the kind at run time).  The CPU's switch pass comes from a module of its
      own with this set (:meth:`impactsph.physics.rates.CpuRates.switch_pass`): numba inlines
      every switch a dispatch names into the pass, and one switch compiles in a quarter of
      the time of all five, with the same machine code for the one that runs;
    - ``uniform_h``: every record's smoothing length is the same, so the vectorised
      neighbour loops take a pair's ``h_ij = (h_i + h_j) / 2`` as ``h_i``, which it then is
      to the bit, and its inverse is the particle's, not a division a pair (one gather and
      one division a pair fewer).  Not from the case: the CPU's rates choose it at each
      evaluation from the rows' smoothing lengths
      (:meth:`impactsph.physics.rates.CpuRates.evaluate`'s ``uniform_h``);
    - ``record_precision``: the packed records' numbers (``compute.record_precision``):
      ``"float64"``, or ``"float32"`` (half the records' memory and traffic; the state, the
      outputs and the sums stay float64).  With float32 the records carry each position in
      two parts, the position rounded and the rest (``SPLIT_POSITIONS``), and the passes add
      them in float64, so a pair's separation is as exact as in float64 wherever the bodies
      are; the other columns' rounding, and the arithmetic between two record values (done in
      float32), are what change (docs/gpu.md, "Records in float32");
    - ``strength_kinds``, ``damage_kinds``: the strength and damage models (their kind codes,
      the positions in the registries) whose return maps and updates the module's
      ``strength_return`` and ``damage_update`` name; None (the default) for every registered
      one.  The integrator's stage comes from a module with just the models of its run's
      materials (:func:`impactsph.integrate.stage_options`): numba inlines every model a
      dispatch names into the stage, and the elastic 1D bars' stage (no return map)
      compiled in 3.5-3.8 s against 6.4-6.6 s with all six models (benchmarks/README.md,
      "The stage with its run's models").  Such a module must run only materials whose
      models it names: the dispatch's fallback for any other is the elastic model's;
    - ``eos_kinds``: likewise the equations of state the module's ``eos_pressure`` names
      (None: every registered one); the stage's module takes its run's (the elastic bars'
      stage compiled in 4.4-4.9 s against 5.3-6.3 s with all three: benchmarks/README.md, "A
      cold first command again").  The dispatch's fallback for a kind it does not name is
      the last it names;
    - ``parallel``: the passes are compiled with numba's ``parallel=True`` (their chunks on
      numba's threads) or, False, as plain loops over the same chunks: the same results to
      the bit, quicker to compile, one thread.  Not from the case: from the environment
      (:func:`parallel_default`), like numba's thread count.
    """

    gradient_correction: str = "none"
    contact_traction: str = "pressure"
    artificial_stress: float = 0.0
    artificial_stress_exponent: float = 4.0
    reference_q: float = 1.0 / 1.3
    artificial_stress_compensation: bool = False
    plane_stress: bool = False
    axisymmetric: bool = False
    contact_friction: float = 0.0
    viscosity_factor: bool = False
    velocity_reconstruction: bool = False
    compatible_energy: bool = False
    switch_kind: int = -1
    uniform_h: bool = False
    record_precision: str = "float64"
    strength_kinds: tuple[int, ...] | None = None
    damage_kinds: tuple[int, ...] | None = None
    eos_kinds: tuple[int, ...] | None = None
    parallel: bool = field(default_factory=parallel_default)

    def __post_init__(self) -> None:
        if self.record_precision not in RECORD_PRECISIONS:
            raise ValueError(f"record_precision = {self.record_precision!r}: allowed are "
                             f"{', '.join(map(repr, RECORD_PRECISIONS))}")
        if self.gradient_correction not in GRADIENT_CORRECTIONS:
            raise ValueError(f"gradient_correction = {self.gradient_correction!r}: allowed are "
                             f"{', '.join(map(repr, GRADIENT_CORRECTIONS))}")
        if self.contact_traction not in CONTACT_TRACTIONS:
            raise ValueError(f"contact_traction = {self.contact_traction!r}: allowed are "
                             f"{', '.join(map(repr, CONTACT_TRACTIONS))}")
        for name, kinds, registry in (("strength_kinds", self.strength_kinds, STRENGTH),
                                      ("damage_kinds", self.damage_kinds, DAMAGE),
                                      ("eos_kinds", self.eos_kinds, EOS)):
            if kinds is not None and (tuple(sorted(set(kinds))) != tuple(kinds)
                                      or any(not 0 <= k < len(registry) for k in kinds)
                                      or (name == "eos_kinds" and not kinds)):
                raise ValueError(f"{name} = {kinds!r}: allowed are None (every registered "
                                 f"model) and a sorted tuple of distinct kind codes in "
                                 f"0..{len(registry) - 1}"
                                 f"{' (at least one)' if name == 'eos_kinds' else ''}")
        if self.switch_kind != -1:
            switches = [k for k, m in enumerate(VISCOSITY) if m.switch is not None]
            if self.switch_kind not in switches or not self.viscosity_factor:
                raise ValueError(f"switch_kind = {self.switch_kind!r}: allowed are -1 (all) "
                                 f"and, with viscosity_factor, the kind codes of the schemes "
                                 f"with a switch {switches}")

    @classmethod
    def coerce(cls, options: PassOptions | str | None) -> PassOptions:
        """``options`` itself, the defaults for None, or those with a gradient-correction
        mode given by name."""
        if options is None:
            return cls()
        if isinstance(options, str):
            return cls(gradient_correction=options)
        return options

    @classmethod
    def of_case(cls, case: Any) -> PassOptions:
        """The options a validated case asks for."""
        stab = case.stabilisation
        return cls(gradient_correction=stab.gradient_correction,
                   contact_traction=case.contact.traction,
                   artificial_stress=float(stab.artificial_stress),
                   artificial_stress_exponent=float(stab.artificial_stress_exponent),
                   reference_q=1.0 / float(case.kernel.h_over_dx),
                   artificial_stress_compensation=bool(stab.artificial_stress_compensation),
                   plane_stress=getattr(case, "two_dimensional", "") == "plane_stress",
                   axisymmetric=getattr(case, "two_dimensional", "") == "axisymmetric",
                   contact_friction=float(case.contact.friction),
                   viscosity_factor=VISCOSITY[case.viscosity.scheme].switch is not None,
                   velocity_reconstruction=VISCOSITY[case.viscosity.scheme].reconstruction,
                   compatible_energy=case.time.energy_update == "compatible",
                   record_precision=case.compute.record_precision)

    @property
    def normal_stress(self) -> bool:
        """The pair pass's run-time switch for the contact traction."""
        return self.contact_traction == "normal_stress"

    @property
    def record_dtype(self) -> np.dtype:
        """The packed records' dtype (:attr:`record_precision`)."""
        return np.dtype(self.record_precision)

    def compiled(self) -> PassOptions:
        """The options that decide the generated module: these, with the run-time ones
        (the contact traction and friction) set to their defaults, so that runs differing only
        in those share one compiled module."""
        return replace(self, contact_traction="pressure", contact_friction=0.0)

    @property
    def tag(self) -> str:
        """A short tag for the generated module's file name."""
        tag = GRADIENT_CORRECTIONS[self.gradient_correction]
        if self.artificial_stress > 0.0:
            tag += "_asc" if self.artificial_stress_compensation else "_as"
        if self.plane_stress:
            tag += "_ps"
        if self.viscosity_factor:
            tag += "_vf" if self.switch_kind == -1 else f"_vf{self.switch_kind}"
        if self.axisymmetric:
            tag += "_ax"
        if self.velocity_reconstruction:
            tag += "_vr"
        if self.compatible_energy:
            tag += "_ce"
        if self.uniform_h:
            tag += "_uh"
        if self.record_precision == "float32":
            tag += "_f32"
        if self.strength_kinds is not None:
            tag += "_s" + "-".join(map(str, self.strength_kinds))
        if self.damage_kinds is not None:
            tag += "_d" + "-".join(map(str, self.damage_kinds))
        if self.eos_kinds is not None:
            tag += "_e" + "-".join(map(str, self.eos_kinds))
        if not self.parallel:
            tag += "_serial"
        return tag

    def compensation(self, dim: int) -> float:
        """``kappa = M_f / M`` on the regular lattice of this ``h/dx`` in ``dim`` dimensions
        (:func:`impactsph.kernels.artificial_stress_moment`,
        :func:`impactsph.kernels.gradient_moment`) with the compensation on, else 0."""
        if not (self.artificial_stress_compensation and self.artificial_stress > 0.0):
            return 0.0
        from ..kernels import artificial_stress_moment, gradient_moment

        h_over_dx = 1.0 / self.reference_q
        return (artificial_stress_moment(h_over_dx, dim, self.artificial_stress_exponent)
                / gradient_moment(h_over_dx, dim))

    def constants(self, dim: int) -> list[str]:
        """The binding's lines for these options in ``dim`` dimensions (the artificial
        stress's parameters only where it is on, so that a run without it shares one module
        whatever its h/dx)."""
        on = self.artificial_stress > 0.0
        return [
            f"GRADIENT_CORRECTION = {self.gradient_correction == 'velocity_gradient'}",
            f"FORCE_CORRECTION = {self.gradient_correction == 'velocity_gradient_and_forces'}",
            f"ARTIFICIAL_STRESS = {float(self.artificial_stress)!r}",
            f"ARTIFICIAL_STRESS_EXPONENT = "
            f"{float(self.artificial_stress_exponent) if on else 4.0!r}",
            f"REFERENCE_Q = {float(self.reference_q) if on else 1.0!r}",
            f"AS_COMPENSATION = {self.compensation(dim) if on else 0.0!r}",
            f"PLANE_STRESS = {bool(self.plane_stress)}",
            f"VISCOSITY_FACTOR = {bool(self.viscosity_factor)}",
            f"AXISYMMETRIC = {bool(self.axisymmetric)}",
            f"VELOCITY_RECONSTRUCTION = {bool(self.velocity_reconstruction)}",
            f"COMPATIBLE_ENERGY = {bool(self.compatible_energy)}",
            f"SWITCH_VECTORISED = {self.switch_vectorised}",
            f"UNIFORM_H = {bool(self.uniform_h)}",
            f"SPLIT_POSITIONS = {self.record_precision == 'float32'}",
            f"PARALLEL = {bool(self.parallel)}",
        ]

    def record_layout(self, dim: int) -> dict[str, int]:
        """The packed records' columns of the passes compiled with these options in ``dim``
        dimensions (:func:`impactsph.physics.records.record_columns` with the flags that the
        binding's :meth:`constants` give the template), without compiling them."""
        from .records import record_columns

        return record_columns(
            dim, correction_matrix=self.gradient_correction == "velocity_gradient_and_forces",
            artificial_stress=self.artificial_stress > 0.0,
            viscosity_factor=bool(self.viscosity_factor), axisymmetric=bool(self.axisymmetric),
            velocity_gradient=bool(self.velocity_reconstruction),
            work_velocity=bool(self.compatible_energy),
            split_positions=self.record_precision == "float32")

    @property
    def switch_vectorised(self) -> bool:
        """The module's one switch has a neighbour loop written for the vectoriser
        (``ViscosityScheme.switch_vectorises``; False for all switches, ``switch_kind`` -1)."""
        return self.switch_kind != -1 and bool(list(VISCOSITY)[self.switch_kind].switch_vectorises)
