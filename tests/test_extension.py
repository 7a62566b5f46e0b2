"""A model of one's own: an equation of state and a strength model defined here, in the test
file (not in the package), registered, selected by name in a TOML case, run, and checked by
hand.

- ``scaled_linear`` (EOS): ``P = factor K (rho/rho0 - 1)``, its parameter in the sub-table
  ``[materials.NAME.scaled_linear]``.
- ``capped_deviator`` (strength): the deviator scaled back to ``sqrt(3/2 S:S) <= cap``, the
  work ``cap d / rho`` of the plastic increment booked as plastic work, and a per-particle
  state of its own, the number of steps in which the cap acted.

With ``factor = 1`` and ``cap`` equal to a yield stress these are the built-in ``linear`` EOS
and ``elastic_plastic`` model written again, so a run with them must equal the built-in run
bit for bit; with ``factor = 2`` the pressure of every particle must be twice the linear one
(a hand computation from the particle's density).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numba as nb
import numpy as np
import pytest
from pydantic import Field

from impactsph import Simulation, load_case, run_case
from impactsph.config import CaseError
from impactsph.materials import TableLayout
from impactsph.models import (
    EOS,
    STRENGTH,
    EquationOfState,
    Parameters,
    StrengthModel,
    register,
)
from impactsph.models.types import PositiveFloat

# -- the toy models ------------------------------------------------------------------------


class ScaledLinearParameters(Parameters):
    factor: PositiveFloat = Field(description="multiplies the linear EOS's pressure")


@nb.njit(inline="always", cache=True)
def scaled_linear_pressure(rho, e, rho0, bulk_modulus, params):
    return params[0] * bulk_modulus * (rho / rho0 - 1.0)


class CappedDeviatorParameters(Parameters):
    cap: PositiveFloat = Field(description="largest von Mises stress (Pa)")


@nb.njit(inline="always", cache=True)
def capped_return(S, rho, pressure, shear_modulus, params, state, own, dt):
    ss = 0.0
    for a in range(3):
        for b in range(3):
            ss += S[a, b] * S[a, b]
    seq = math.sqrt(1.5 * ss)
    if seq <= params[0]:
        return 0.0
    f = params[0] / seq
    for a in range(3):
        for b in range(3):
            S[a, b] *= f
    own[0] += 1.0
    # the plastic work sigma_y d / rho of the increment d = (sigma_eq - sigma_y) / (3 mu)
    return params[0] * (params[0] * (1.0 / f - 1.0) / (3.0 * shear_modulus)) / rho


def register_toy_models() -> None:
    """Register both toy models (again, replacing any earlier registration)."""
    register(EquationOfState(
        name="scaled_linear", pressure=scaled_linear_pressure,
        parameters=ScaledLinearParameters, columns=("factor",),
        coefficients=lambda p, constants: (p.factor,)), replace=True)
    register(StrengthModel(
        name="capped_deviator", return_map=capped_return, parameters=CappedDeviatorParameters,
        columns=("cap",), coefficients=lambda p, constants: (p.cap,), state=("capped_steps",)),
        replace=True)


@pytest.fixture
def toy_models():
    register_toy_models()
    yield
    EOS.unregister("scaled_linear")
    STRENGTH.unregister("capped_deviator")


# -- the cases -----------------------------------------------------------------------------

BLOCK = """
name = "block_on_wall"
dimension = 2
{plugins}
[materials.iron]
model = "{model}"
density = 7850.0
youngs_modulus = 208e9
poisson_ratio = 0.3
eos = "{eos}"
{extra}

[[bodies]]
name = "block"
material = "iron"
velocity = [0.0, -200.0]
[bodies.geometry]
origin = [-0.002, 0.0]
size = [0.004, 0.006]
count = [8, 12]

[[boundaries]]
type = "wall"
point = [0.0, 0.0]
normal = [0.0, 1.0]

[kernel]
h_over_dx = 1.3

[viscosity]
scheme = "ac"

[time]
end = 4e-6

[output]
snapshot_times = [2e-6, 4e-6]
figures = false
"""

TOY = dict(model="capped_deviator", eos="scaled_linear",
           extra="[materials.iron.scaled_linear]\nfactor = {factor}\n"
                 "[materials.iron.capped_deviator]\ncap = 600e6\n")
BUILT_IN = dict(model="elastic_plastic", eos="linear", extra="yield_stress = 600e6\n")


def write_case(folder: Path, name: str, plugins: str = "", factor: float = 1.0,
               **models: str) -> Path:
    models = {**models, "extra": models["extra"].format(factor=factor)}
    path = folder / f"{name}.toml"
    path.write_text(BLOCK.format(plugins=plugins, **models))
    return path


def run(path: Path) -> Simulation:
    sim = Simulation(load_case(path))
    sim.run()
    return sim


def test_toy_models_equal_the_built_in_ones_they_restate(toy_models, tmp_path):
    toy = run(write_case(tmp_path, "toy", **TOY))
    built_in = run(write_case(tmp_path, "built_in", **BUILT_IN))
    assert toy.state.plastic_work.max() > 0  # the cap acted
    for name in ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
                 "plastic_work"):
        np.testing.assert_array_equal(getattr(toy.state, name), getattr(built_in.state, name),
                                      err_msg=name)
    a, b = toy.summary(), built_in.summary()
    for key in ("n_steps", "kinetic_energy_final", "internal_energy_final", "plastic_work",
                "total_energy_relative_error", "wall_constraint_events"):
        assert a[key] == b[key], key


def test_toy_models_by_hand(toy_models, tmp_path):
    """Twice the linear pressure, the cap held, and the state counting the capped steps."""
    sim = run(write_case(tmp_path, "toy2", factor=2.0, **TOY))
    s = sim.state
    rho0, E, nu = 7850.0, 208e9, 0.3
    K = E / (3.0 * (1.0 - 2.0 * nu))
    for snap in sim.record.snapshots:
        by_hand = 2.0 * K * (snap.fields["density"] / rho0 - 1.0)
        np.testing.assert_allclose(snap.fields["pressure"], by_hand, rtol=1e-14,
                                   atol=1e-14 * np.abs(by_hand).max())
        assert np.abs(by_hand).max() > 1e8  # a real compression, not zeros
    S = s.deviatoric_stress
    von_mises = np.sqrt(1.5 * np.einsum("iab,iab->i", S, S))
    assert von_mises.max() <= 600e6 * (1 + 1e-12)
    assert von_mises.max() > 0.99 * 600e6  # the cap is reached
    # the state carries the strength model's block, not the damage models' after it
    assert s.material_state.shape[1] == TableLayout.registered().damage_state
    capped = s.material_state[:, TableLayout.registered().strength_state]
    assert capped.max() >= 1 and np.all(capped == np.round(capped))
    # plastic work is kept from the final stage of each step only, as the count is
    np.testing.assert_array_equal(capped > 0, s.plastic_work > 0)


def test_toy_model_parameters_are_validated(toy_models, tmp_path):
    bad = dict(TOY, extra="[materials.iron.scaled_linear]\nfactor = 1.0\n"
                          "[materials.iron.capped_deviator]\ncap = -5.0\n")
    with pytest.raises(CaseError, match=r"^materials\.iron\.capped_deviator\.cap = -5\.0: "):
        load_case(write_case(tmp_path, "bad", **bad))
    missing = dict(TOY, extra="[materials.iron.scaled_linear]\nfactor = 1.0\n")
    with pytest.raises(CaseError, match=r"model = 'capped_deviator' needs a "
                                        r"\[capped_deviator\] table"):
        load_case(write_case(tmp_path, "missing", **missing))


def test_unregistered_model_is_refused_with_the_registered_names(tmp_path):
    with pytest.raises(CaseError, match=r"^materials\.iron\.model = 'capped_deviator': .*"
                                        r"'elastic_plastic'"):
        load_case(write_case(tmp_path, "unknown", **TOY))


def test_plugin_registers_the_models_for_the_command_line(toy_models, tmp_path):
    """``plugins = ["toy_plugin.py"]`` in the case file: ``impactsph run`` in a fresh process
    imports it (relative to the case file) before it validates the case."""
    plugin = tmp_path / "toy_plugin.py"
    plugin.write_text(f"import sys\nsys.path.insert(0, {str(Path(__file__).parent)!r})\n"
                      "import test_extension\ntest_extension.register_toy_models()\n")
    path = write_case(tmp_path, "plugged", plugins='plugins = ["toy_plugin.py"]', **TOY)
    out = tmp_path / "out"
    res = subprocess.run([sys.executable, "-m", "impactsph", "run", str(path), "--out",
                          str(out), "--quiet"], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    # the same case run here, in this process, where the fixture registered the models
    here = run_case(load_case(path), tmp_path / "here", figures=False)
    # the same physics, to the last bit: the two processes compile the generated passes
    # separately (cold caches) or one serves the other's (warm), and both give one answer
    assert summary["plastic_work"] == here["plastic_work"]
    assert here["plastic_work"] > 0
    case = json.loads((out / "case.json").read_text())["case"]
    assert case["plugins"] == [str(plugin)]
    assert case["materials"]["iron"]["capped_deviator"] == {"cap": 600e6}


def test_missing_plugin_is_refused(tmp_path):
    path = write_case(tmp_path, "noplugin", plugins='plugins = ["nowhere.py"]', **BUILT_IN)
    with pytest.raises(CaseError, match=r"^plugins\.0 = '.*nowhere\.py': file does not exist"):
        load_case(path)


class DefaultedParameters(Parameters):
    factor: PositiveFloat = Field(1.0, description="with a default")


def test_a_table_of_defaults_may_be_left_out(tmp_path):
    """A model whose parameters all have defaults needs no sub-table: the defaults are filled
    in, and recorded in the resolved case."""
    register(EquationOfState(name="defaulted_linear", pressure=scaled_linear_pressure,
                             parameters=DefaultedParameters, columns=("factor",),
                             coefficients=lambda p, constants: (p.factor,)))
    try:
        case = load_case(write_case(tmp_path, "defaulted", model="elastic",
                                    eos="defaulted_linear", extra=""))
        assert case.materials["iron"].defaulted_linear.factor == 1.0
        assert case.model_dump()["materials"]["iron"]["defaulted_linear"] == {"factor": 1.0}
    finally:
        EOS.unregister("defaulted_linear")


PLUGIN_WITH_A_KERNEL = """
import numba as nb

@nb.njit(cache=True)
def twice(x):
    return 2.0 * x
"""


def test_a_plugin_files_module_is_its_stem_whatever_its_place_in_the_list(tmp_path):
    """numba's disk cache keys a compiled function on its source file and stores its
    module's name: a plugin imported under a name that depended on its place in ``plugins``
    found, in the next process with the list in another order, cached code that named a
    module that did not exist (an audit, 2026-12-08)."""
    for stem in ("plug_first", "plug_second"):
        (tmp_path / f"{stem}.py").write_text(PLUGIN_WITH_A_KERNEL)
    script = ("import sys\nfrom impactsph import loading\nloading.load_plugins(sys.argv[1:])\n"
              "print(*(loading._LOADED_PLUGINS[p].twice(1.5) for p in sorted(sys.argv[1:])), "
              "sys.modules['plug_first'].__file__ == sorted(sys.argv[1:])[0])\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    first, second = str(tmp_path / "plug_first.py"), str(tmp_path / "plug_second.py")
    for order in ([first, second], [second, first]):  # the second process loads the cache
        res = subprocess.run([sys.executable, "-c", script, *order], capture_output=True,
                             text=True, timeout=300, env=env)
        assert res.returncode == 0, res.stderr[-2000:]
        assert res.stdout.split() == ["3.0", "3.0", "True"]
    assert list((tmp_path / "numba").rglob("*.nbi"))  # (the cache was written and read)


def test_a_plugin_imported_by_the_caller_is_not_imported_again(tmp_path, monkeypatch):
    """A plugin the caller imported itself is the case's: importing it a second time would
    register its models twice (refused without ``replace=True``)."""
    import importlib

    from impactsph import loading
    from impactsph.loading import load_plugins

    (tmp_path / "plug_own.py").write_text("RUNS = []\nRUNS.append(1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("plug_own")
    load_plugins([str(tmp_path / "plug_own.py")])
    assert sys.modules["plug_own"] is module and module.RUNS == [1]
    # a stem that is another module's name, or a second file of one stem: a name of its own
    import json

    (tmp_path / "json.py").write_text("X = 1\n")
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "plug_own.py").write_text("RUNS = [2]\n")
    load_plugins([str(tmp_path / "json.py"), str(tmp_path / "b" / "plug_own.py")])
    assert sys.modules["json"] is json  # (not replaced)
    mine = loading._LOADED_PLUGINS[str(tmp_path / "json.py")]
    assert mine.X == 1 and mine.__name__.startswith("impactsph_plugin_json_")
    second = loading._LOADED_PLUGINS[str(tmp_path / "b" / "plug_own.py")]
    assert second.RUNS == [2] and sys.modules["plug_own"] is module


@nb.njit(inline="always", cache=True)
def three_argument_pressure(rho, rho0, bulk_modulus):
    return bulk_modulus * (rho / rho0 - 1.0)


@nb.njit(inline="always", cache=True)
def pressure_with_a_default(rho, e, rho0, bulk_modulus, params, scale=1.0):
    return scale * bulk_modulus * (rho / rho0 - 1.0)


@nb.njit(inline="always", cache=True)
def any_pressure(*arguments):
    return 0.0


class NegativeYieldParameters(Parameters):
    yield_stress: float = Field(-1.0, description="another range than elastic_plastic's")


class AlphaAsText(Parameters):
    alpha1: str = Field("1", description="another type than av's")


def test_a_model_its_kernels_cannot_use_is_refused_when_registered():
    """What a model's author gets wrong, refused in one line at its registration (a plugin's
    import, so `impactsph check` names the plugin), and the registries left as they were:
    before (an audit, 2026-12-08) a kernel of three arguments passed `check` and failed the
    run with numba's traceback; parameters without columns were dropped without a word (the
    kernel read the next model's columns); a flat field of another range took the place of
    elastic_plastic's in the schema; a viscosity field of another type broke the schema."""
    from impactsph.config import schema
    from impactsph.models import VISCOSITY, ViscosityScheme
    from impactsph.models.viscosity.monaghan import pair_viscosity

    version_schema = schema()
    with pytest.raises(TypeError, match=r"^equation of state 'short': pressure takes 3 "
                                        r"arguments; the passes call it with 5: pressure\(rho, "
                                        r"e, rho0, bulk_modulus, params\)$"):
        register(EquationOfState(name="short", pressure=three_argument_pressure))
    # a trailing default or *args: the passes' five arguments fit (and the model registers)
    for name, function in (("defaulted", pressure_with_a_default), ("starred", any_pressure)):
        register(EquationOfState(name=name, pressure=function))
        EOS.unregister(name)
    with pytest.raises(ValueError, match=r"^equation of state 'uncolumned': its parameters "
                                         r"\(factor\) have no table columns"):
        register(EquationOfState(name="uncolumned", pressure=scaled_linear_pressure,
                                 parameters=ScaledLinearParameters))
    with pytest.raises(ValueError, match=r"columns \('factor',\) without coefficients"):
        register(EquationOfState(name="uncoefficiented", pressure=scaled_linear_pressure,
                                 parameters=ScaledLinearParameters, columns=("factor",)))
    with pytest.raises(ValueError, match=r"^strength model 'negative_yield' and strength model "
                                         r"'elastic_plastic' both declare the material "
                                         r"table's key 'yield_stress', differently"):
        register(StrengthModel(name="negative_yield", return_map=capped_return, flat=True,
                               parameters=NegativeYieldParameters, columns=("yield_stress",),
                               coefficients=lambda p, constants: (p.yield_stress,)))
    with pytest.raises(ValueError, match=r"^viscosity schemes: 'alpha_as_text' and 'av' both "
                                         r"declare the field 'alpha1', differently$"):
        register(ViscosityScheme(name="alpha_as_text", pair_viscosity=pair_viscosity,
                                 parameters=AlphaAsText,
                                 pair_parameters=lambda v: (1.0, 1.0, 0.01, 0.0)))
    for name in ("short", "uncolumned", "uncoefficiented", "negative_yield", "alpha_as_text"):
        assert name not in EOS and name not in STRENGTH and name not in VISCOSITY
    assert repr(schema().Material.model_fields["yield_stress"]) == \
        repr(version_schema.Material.model_fields["yield_stress"])
    assert "alpha_as_text" not in str(schema().Viscosity.model_fields["scheme"].annotation)


def test_elastic_plastic_yield_stress_keeps_its_range_after_a_refused_plugin(tmp_path):
    with pytest.raises(ValueError, match=r"both declare the material table's key"):
        register(StrengthModel(name="negative_yield", return_map=capped_return, flat=True,
                               parameters=NegativeYieldParameters, columns=("yield_stress",),
                               coefficients=lambda p, constants: (p.yield_stress,)))
    with pytest.raises(CaseError, match=r"^materials\.iron\.yield_stress = -5\.0: Input should "
                                        r"be greater than 0$"):
        load_case(write_case(tmp_path, "negative", **{**BUILT_IN,
                                                      "extra": "yield_stress = -5e0\n"}))


def test_a_models_coefficients_that_do_not_fit_its_columns_name_the_material(tmp_path):
    register(EquationOfState(name="one_short", pressure=scaled_linear_pressure,
                             parameters=ScaledLinearParameters, columns=("factor", "other"),
                             coefficients=lambda p, constants: (p.factor,)))
    try:
        case = load_case(write_case(tmp_path, "short", model="elastic", eos="one_short",
                                    extra="[materials.iron.one_short]\nfactor = 1.0\n"))
        with pytest.raises(CaseError, match=r"^materials\.iron\.eos = 'one_short': its "
                                            r"coefficients gave 1 value for its 2 columns "
                                            r"\('factor', 'other'\)$"):
            Simulation(case)
    finally:
        EOS.unregister("one_short")
