"""The registries of material and viscosity models: what a model declares, and where it is
found by name.

A model is one module that builds one of the dataclasses below and registers it with one line
(``register(EquationOfState(...))``).  It declares

- its **name**, the value that selects it in a case file (``eos = "mie_gruneisen"``,
  ``model = "elastic_plastic"``, ``scheme = "ac"``);
- its **parameters**, a :class:`Parameters` model (pydantic), which becomes its part of the
  case schema: a sub-table named after the model (``[materials.iron.mie_gruneisen]``), or
  fields of the enclosing table where the model says ``flat=True``;
- its **table columns**, the names of the numbers it keeps per material in the kernels'
  material table, and ``coefficients(...)``, which computes them from its parameters;
- its **compiled functions** (``numba.njit``), which the generated passes call
  (:mod:`impactsph.codegen`): an EOS's ``pressure``, a strength model's ``return_map``, a
  viscosity scheme's ``pair_viscosity`` and optional ``correction`` (a per-particle pass after
  the pair pass);
- the **per-particle state** it needs (a strength or damage model's ``state``: names of
  scalar fields that the integrator carries and hands to it, after the state every particle
  carries, :mod:`impactsph.models.columns`);
- the **material fields** it needs (``needs``: e.g. ``("melting_temperature",)``), refused at
  validation when missing.

The registries are read by the case schema (:mod:`impactsph.config`), the material table
(:mod:`impactsph.materials`), the problem set-up, the generated passes and the outputs.  A model
registered from user code, before the case is loaded, works in a case file like a built-in one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, ConfigDict


class Parameters(BaseModel):
    """Base of every table of a case file: unknown keys are refused and no string or boolean
    is taken for a number (TOML has real types)."""

    model_config = ConfigDict(extra="forbid", validate_default=True, strict=True)


@dataclass(frozen=True)
class ElasticConstants:
    """A material's resolved constants (SI), handed to ``coefficients``."""

    density: float  #: reference density rho0 (kg/m^3)
    youngs_modulus: float  #: E (Pa)
    poisson_ratio: float  #: nu
    bulk_modulus: float  #: K (Pa)
    shear_modulus: float  #: mu (Pa)
    melting_temperature: float = 0.0  #: K (0: not given)
    specific_heat: float = 0.0  #: J/(kg K) (0: not given)


@dataclass(frozen=True)
class EquationOfState:
    """An equation of state ``P(rho, e)``.

    ``pressure(rho, e, rho0, bulk_modulus, params) -> P``: compiled (``numba.njit``, best with
    ``inline="always"``); ``params`` is the material's row of the table from this model's first
    column on (``params[k]`` is ``columns[k]``).  ``coefficients(parameters, constants)``
    returns the values of ``columns`` (a tuple of floats) from the validated parameters (None
    when the model has none) and the material's :class:`ElasticConstants`."""

    name: str
    pressure: Any
    description: str = ""
    parameters: type[Parameters] | None = None
    columns: tuple[str, ...] = ()
    coefficients: Callable[[Any, ElasticConstants], tuple[float, ...]] | None = None
    source: str = ""  #: where the equations come from (paper, equation numbers)


@dataclass(frozen=True)
class StrengthModel:
    """A strength model: what becomes of the deviatoric stress after each integrator stage.

    ``return_map(S, rho, pressure, shear_modulus, params, state, own, dt) -> dissipated
    specific work (J/kg)``: compiled; ``S`` is the particle's 3x3 deviatoric stress after the
    elastic (Jaumann) update, changed in place; ``pressure`` the particle's pressure (Pa);
    ``params`` the material's row of the table from this model's first column; ``state`` the
    particle's common material state (:mod:`impactsph.models.columns`: the equivalent plastic
    strain and its rate, which the model updates, the temperature, the damage), ``own`` its
    values of this model's ``state`` fields (views), changed in place; ``dt`` the stage's time
    step (s).  Of the common state a return map writes the plastic strain and its rate
    only: the integrator restores those (the first two columns, ``PLASTIC_COLUMNS``), the
    temperature where a material that yields heats (the first three, ``RETURN_MAP_COLUMNS``)
    and ``own`` at the start of each stage, as it does the stress, and not the damage or the
    thickness ratio unless a damage model, plane stress or axisymmetry changes them
    (:func:`impactsph.integrate.material_state_kept`).
    The integrator then heats the particle by ``beta / c_p`` times the returned work.
    ``None``: the stress is left as it is (elastic).

    ``uniaxial_stress``: the 1D bar of the paper's Example 1 (``K = E``, no deviatoric stress,
    bar wave speed); ``dimensions`` and ``equations_of_state`` (None: any) restrict where the
    model may be used."""

    name: str
    return_map: Any = None
    description: str = ""
    parameters: type[Parameters] | None = None
    flat: bool = False  #: parameters are fields of the material table, not a sub-table
    columns: tuple[str, ...] = ()
    coefficients: Callable[[Any, ElasticConstants], tuple[float, ...]] | None = None
    state: tuple[str, ...] = ()
    needs: tuple[str, ...] = ()  #: material fields it cannot do without
    uniaxial_stress: bool = False
    dimensions: tuple[int, ...] = (1, 2, 3)
    equations_of_state: tuple[str, ...] | None = None
    source: str = ""


@dataclass(frozen=True)
class DamageModel:
    """A damage (failure) model: how the damage D of a particle grows after each stage.

    ``update(S, pressure, rho, size, dt, plastic_strain_increment, row, params, state, own)``
    (compiled) is called after the strength model's return map with the particle's deviatoric
    stress ``S`` (undamaged), its pressure (Pa, undamaged), density, size (its smoothing
    length, m), the stage's ``dt`` and the increment of equivalent plastic strain the return
    map just made; ``row`` is the material's whole row of the table
    (:mod:`impactsph.models.columns` for the common columns), ``params`` its columns of this
    model; it writes the damage into ``state[DAMAGE]`` and its own fields into ``own``.  The
    passes apply D (``impactsph.physics.passes.particle_record``): the deviatoric stress and a
    tensile pressure are scaled by ``1 - D``.

    ``initial_state(parameters, volume, rng) -> (n, len(state))``: the own fields at t = 0
    (e.g. each particle's flaws), from the particles' volumes (m^3, or m^2 and m in 2D and 1D)
    and a seeded ``numpy.random.Generator``; None: zeros."""

    name: str
    update: Any = None
    description: str = ""
    parameters: type[Parameters] | None = None
    columns: tuple[str, ...] = ()
    coefficients: Callable[[Any, ElasticConstants], tuple[float, ...]] | None = None
    state: tuple[str, ...] = ()
    initial_state: Callable[..., Any] | None = None
    needs: tuple[str, ...] = ()
    source: str = ""


@dataclass(frozen=True)
class ViscosityScheme:
    """A viscosity scheme: the pair term ``Pi_ij`` of the momentum and energy equations
    (eqs 27-28), and optionally a per-particle correction applied after the pair pass.

    ``pair_viscosity(vr, r2, h_ij, c_ij, rho_ij, params) -> Pi_ij`` (compiled): ``vr = v_ij .
    r_ij``, ``r2 = |r_ij|^2``, pair means ``h_ij, c_ij, rho_ij``; ``params`` the tuple of four
    floats that ``pair_parameters(viscosity)`` returns for the case's ``[viscosity]`` table.

    ``correction`` (compiled, optional): ``correction(p, i, P, start, end, indices, layout,
    dim, params, books, dv, de)`` for the active particle ``i`` at sorted position ``p``,
    whose neighbours are the sorted positions ``indices[start:end]``, reading the packed
    records ``P`` (``layout``: the tuple of their column indices, see
    :func:`impactsph.physics.passes.record_columns`), adding its acceleration and heating to
    ``dv[i]``, ``de[i]`` and writing for the run's books the power of that acceleration per
    unit mass (``v_i`` from ``P``) and that heating (W/kg) into ``books[i, 0]``, ``books[i,
    1]``; ``correction_parameters(viscosity)`` gives its four floats.

    ``switch`` (compiled, optional): ``switch(p, i, P, start, end, indices, layout, dim, params,
    elapsed, memory) -> f_i`` (its neighbours as the correction's), the particle's viscosity
    factor for the next rate evaluation (a float in ``[0, 1]``), read from the packed records
    after the pair pass (``layout``: the columns ``(x, v, h, volume, body, u, c, f, memory, rho,
    m)``, ``u`` the viscous acceleration of the unscaled ``Pi_ij``, ``f`` the factor in use,
    ``memory`` what the switch kept at the last evaluation); ``elapsed`` is the time (s) since
    the factors were last set, for a switch that evolves them (0 at the first evaluation); the
    switch writes what it keeps for the next evaluation into ``memory[i]`` (it must write it:
    the array is not initialised); ``switch_parameters(viscosity)`` gives its four floats. A
    scheme with a switch has every pair's ``Pi_ij`` multiplied by the mean ``(f_i + f_j) / 2``
    of the two particles' factors (docs/dissipation.md): a symmetric factor, so momentum and the
    energy balance are kept exactly."""

    name: str
    pair_viscosity: Any
    pair_parameters: Callable[[Any], tuple[float, float, float, float]]
    description: str = ""
    parameters: type[Parameters] | None = None  #: fields of the [viscosity] table
    correction: Any = None
    correction_parameters: Callable[[Any], tuple[float, float, float, float]] | None = None
    source: str = ""
    switch: Any = None
    switch_parameters: Callable[[Any], tuple[float, float, float, float]] | None = None
    #: the factor every particle starts a run with (a scheme with a switch)
    initial_factor: Callable[[Any], float] = lambda viscosity: 1.0
    #: ``switch``'s neighbour loop is written for LLVM's vectoriser (no branch: a pair to
    #: skip is a mask; the neighbour's columns read as ``P[j, col]``), so its CPU pass is
    #: compiled with reassociation and without zero-division checks (the pair pass's flags;
    #: the factors then move at round-off with the order of the sums)
    switch_vectorises: bool = False
    #: ``pair_viscosity`` gets, for a pair of the same body, the velocity jump reconstructed
    #: to the pair's midpoint with a limiter (:mod:`impactsph.physics.reconstruction`) in
    #: place of ``v_ij . r_ij``; the passes then compute every particle's velocity gradient
    #: before the pair pass
    reconstruction: bool = False
    #: how far ``correction`` reads its neighbours: ``correction_reach(viscosity)`` is a
    #: fraction ``f`` of the kernel support such that the correction never uses a pair at
    #: ``r_ij >= f 2 h_max`` (``h_max`` the largest smoothing length of the run; None: the
    #: whole support).  The CPU's correction pass then reads only each row's inner list
    #: (:mod:`impactsph.neighbours`: its first entries), which holds every pair closer than
    #: that; a reach too short drops pairs silently, so a correction must skip the pairs
    #: beyond it itself
    correction_reach: Callable[[Any], float] | None = None
    #: the same for ``switch``: ``switch_reach(viscosity) -> f``, no pair at ``r_ij >= f 2
    #: h_max`` used by the switch (None: the whole support)
    switch_reach: Callable[[Any], float] | None = None


M = TypeVar("M", EquationOfState, StrengthModel, DamageModel, ViscosityScheme)


@dataclass
class Registry(Generic[M]):
    """Models of one kind, by name, in the order they were registered."""

    kind: str  #: what a model of this registry is, for messages ("equation of state")
    models: dict[str, M] = field(default_factory=dict)

    def register(self, model: M, *, replace: bool = False) -> M:
        """Add ``model``; a second model of the same name is refused unless ``replace``, and
        so is a kernel function (:data:`KERNEL_FUNCTIONS`) that numba has not compiled: the
        passes inline every registered model's, so one plain Python function would stop
        every later run's compilation, whatever its models."""
        if not isinstance(model.name, str) or not model.name.isidentifier():
            raise ValueError(f"{self.kind} name {model.name!r} must be a Python identifier")
        article = "an" if self.kind[0] in "aeiou" else "a"
        if model.name in self.models and not replace:
            raise ValueError(f"{article} {self.kind} named {model.name!r} is already "
                             f"registered (pass replace=True to replace it)")
        for attribute, arguments in KERNEL_FUNCTIONS.items():
            function = getattr(model, attribute, None)
            if function is None:
                continue
            if not hasattr(function, "py_func"):
                raise TypeError(f"{self.kind} {model.name!r}: {attribute} = {function!r} is "
                                f"not compiled by numba; decorate it with "
                                f"{INLINED.get(attribute, '@numba.njit(cache=True)')}")
            least, most = _positional_counts(function.py_func)
            if not least <= len(arguments) <= most:
                taken = str(least) if least == most else f"{least} to {most}"
                raise TypeError(f"{self.kind} {model.name!r}: {attribute} takes {taken} "
                                f"argument{'s' * (taken != '1')}; the passes call it with "
                                f"{len(arguments)}: {attribute}({', '.join(arguments)})")
        _check_columns(self.kind, model)
        before = self.models.get(model.name)
        self.models[model.name] = model
        _bump()
        try:
            for check in REGISTRY_CHECKS:  # (the case schema's: a field two models declare)
                check()
        except Exception:
            if before is None:
                del self.models[model.name]
            else:
                self.models[model.name] = before
            _bump()
            raise
        return model

    def unregister(self, name: str) -> None:
        """Remove a model (tests register toy models and remove them again)."""
        if self.models.pop(name, None) is not None:
            _bump()

    def __getitem__(self, name: str) -> M:
        try:
            return self.models[name]
        except KeyError:
            raise KeyError(f"no {self.kind} named {name!r}; registered: "
                           f"{', '.join(self.models)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.models

    def __iter__(self) -> Iterator[M]:
        return iter(self.models.values())

    def __len__(self) -> int:
        return len(self.models)

    def names(self) -> tuple[str, ...]:
        """The registered names, in registration order."""
        return tuple(self.models)

    def index(self, name: str) -> int:
        """Position of ``name`` in the registration order: its kind code in the kernels."""
        return list(self.models).index(name)


_version = 0


def _bump() -> None:
    global _version
    _version += 1


def version() -> int:
    """A number that changes whenever any registry changes (the schema and the generated
    passes are rebuilt when it does)."""
    return _version


EOS: Registry[EquationOfState] = Registry("equation of state")
STRENGTH: Registry[StrengthModel] = Registry("strength model")
DAMAGE: Registry[DamageModel] = Registry("damage model")
VISCOSITY: Registry[ViscosityScheme] = Registry("viscosity scheme")


#: the models' functions that the compiled passes call (each a numba dispatcher), with the
#: arguments they are called with (the dataclasses' docstrings say what each is)
KERNEL_FUNCTIONS: dict[str, tuple[str, ...]] = {
    "pressure": ("rho", "e", "rho0", "bulk_modulus", "params"),
    "return_map": ("S", "rho", "pressure", "shear_modulus", "params", "state", "own", "dt"),
    "update": ("S", "pressure", "rho", "size", "dt", "plastic_strain_increment", "row",
               "params", "state", "own"),
    "pair_viscosity": ("vr", "r2", "h_ij", "c_ij", "rho_ij", "params"),
    "correction": ("p", "i", "P", "start", "end", "indices", "layout", "dim", "params",
                   "books", "dv", "de"),
    "switch": ("p", "i", "P", "start", "end", "indices", "layout", "dim", "params", "elapsed",
               "memory"),
}

#: how each function the pair and particle passes call is compiled: inlined, which lets one
#: body serve the CPU and the CUDA kernels; the stage's (``return_map``, ``update``) are
#: plain ``numba.njit(cache=True)`` (docs/architecture.md, "Rules for a compiled model
#: function")
INLINED = {name: "@numba.njit(inline='always', cache=True) (the passes inline it)"
           for name in ("pressure", "pair_viscosity", "correction", "switch")}

#: checks of the registries as a whole, run after each registration (which is undone where
#: one raises): the case schema's (:mod:`impactsph.config`) adds that no two models declare
#: one field of a table differently
REGISTRY_CHECKS: list[Callable[[], None]] = []


def _positional_counts(function: Callable[..., Any]) -> tuple[int, float]:
    """The fewest and the most positional arguments a Python function takes (those without
    a default; all of them, or infinity with ``*args``)."""
    import inspect

    parameters = list(inspect.signature(function).parameters.values())
    positional = [p for p in parameters if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    least = sum(p.default is p.empty for p in positional)
    most = (math.inf if any(p.kind is p.VAR_POSITIONAL for p in parameters)
            else len(positional))
    return least, most


def _check_columns(kind: str, model: Any) -> None:
    """Refuse a material model whose parameters cannot reach its kernels: parameters without
    table columns (its kernel would read the next model's columns as its own; a damage
    model's ``initial_state`` may read them instead), or columns without ``coefficients``
    to fill them, or ``coefficients`` without columns."""
    if not hasattr(model, "columns"):
        return  # a viscosity scheme: pair_parameters gives its kernels' numbers
    fields = tuple(model.parameters.model_fields) if model.parameters is not None else ()
    name = f"{kind} {model.name!r}"
    if fields and not model.columns and getattr(model, "initial_state", None) is None:
        raise ValueError(f"{name}: its parameters ({', '.join(fields)}) have no table "
                         f"columns, so no kernel would read them; declare columns=(...) "
                         f"and coefficients=lambda parameters, constants: (...)")
    if model.columns and model.coefficients is None:
        raise ValueError(f"{name}: columns {model.columns} without coefficients to fill "
                         f"them; declare coefficients=lambda parameters, constants: (...)")
    if model.coefficients is not None and not model.columns:
        raise ValueError(f"{name}: coefficients without columns; declare columns=(NAME, ...)"
                         f", one a value coefficients returns")


def register(model: M, *, replace: bool = False) -> M:
    """Register an equation of state, strength model, damage model or viscosity scheme (by
    its type)."""
    registry = {EquationOfState: EOS, StrengthModel: STRENGTH, DamageModel: DAMAGE,
                ViscosityScheme: VISCOSITY}.get(type(model))
    if registry is None:
        raise TypeError(f"cannot register {model!r}: not an EquationOfState, StrengthModel, "
                        f"DamageModel or ViscosityScheme")
    return registry.register(model, replace=replace)
