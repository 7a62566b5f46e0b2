"""Hardening, Johnson-Cook strength, heating and damage against their formulas, on
homogeneous deformations of one material point (:mod:`impactsph.material_point`: the run's
own compiled EOS, Jaumann rate, return map, heating and damage update, with no SPH around).

- linear and power-law hardening: the return lands on ``sigma_y(eps_p)`` at every plastic
  step, and the plastic strain is the total strain less the elastic one (uniaxial stress);
- Johnson-Cook: ``sigma_eq = (A + B eps^n)(1 + C ln rate*)(1 - T*^m)`` at every plastic step,
  in uniaxial stress and uniaxial strain, at three rates and three temperatures;
- the adiabatic temperature rise is ``beta / (rho c) int sigma_eq d eps_p`` (the plastic work
  per volume integrated independently of the code's own book-keeping);
- Johnson-Cook damage fails the point where ``eps_p`` reaches ``eps_f(sigma*)`` at two
  triaxialities (1/3 in tension, 0 in shear), and not before;
- a Grady-Kipp bar in tension: the damage reaches 1 at ``t_act + 2h / c_g`` after the strain
  passes the weakest flaw, faster with more active flaws; the flaw assignment follows the
  Weibull law;
- bad material parameters are refused with exit code 2 and one line naming the field.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph.cli import app
from impactsph.config import schema
from impactsph.material_point import material_point
from impactsph.materials import resolve_material
from impactsph.models.damage.grady_kipp import GradyKippParameters, assign_flaws

E, NU, RHO = 200e9, 0.3, 7850.0
MU = E / (2 * (1 + NU))


def steel(model: str, table: dict | None = None, **extra) -> dict:
    out = {"model": model, "density": RHO, "youngs_modulus": E, "poisson_ratio": NU, **extra}
    if table is not None:
        out[model] = table
    return out


def plastic(history, start: int = 1) -> np.ndarray:
    """Steps (from ``start``) in which the plastic strain grew."""
    k = np.flatnonzero(np.diff(history.equivalent_plastic_strain) > 0) + 1
    return k[k >= start]


# -- hardening ---------------------------------------------------------------------------


@pytest.mark.parametrize("rate", [-1e3, 1e3])
def test_linear_hardening_follows_its_line(rate):
    sigma0, H = 300e6, 2e9
    h = material_point(steel("linear_hardening", {"yield_stress": sigma0,
                                                 "hardening_modulus": H}),
                       strain_rate=rate, strain=0.05, steps=1000)
    k = plastic(h)
    assert k.size > 900
    eps = h.equivalent_plastic_strain
    np.testing.assert_allclose(h.von_mises_stress[k], sigma0 + H * eps[k], rtol=1e-9)
    assert np.sign(h.axial_stress[-1]) == np.sign(rate)
    # uniaxial stress: the lateral stresses vanish, and eps_p = eps - sigma / E
    np.testing.assert_allclose(h.stress[:, 1, 1], 0.0, atol=1e-6 * abs(h.axial_stress).max())
    elastic = np.abs(h.axial_stress[-1]) / E
    assert eps[-1] == pytest.approx(abs(h.axial_strain[-1]) - elastic, rel=2e-3)
    assert eps[-1] > 0.04


def test_power_law_hardening_follows_its_curve():
    sigma0, K, n = 200e6, 500e6, 0.3
    h = material_point(steel("power_law_hardening", {
        "yield_stress": sigma0, "strength_coefficient": K, "hardening_exponent": n}),
        strain_rate=-500.0, strain=0.3, steps=1500)
    k = plastic(h)
    eps = h.equivalent_plastic_strain
    np.testing.assert_allclose(h.von_mises_stress[k], sigma0 + K * eps[k] ** n, rtol=1e-9)
    assert eps[-1] == pytest.approx(0.3 - abs(h.axial_stress[-1]) / E, rel=3e-3)


# -- Johnson-Cook ------------------------------------------------------------------------

JC = {"yield_stress": 90e6, "hardening_modulus": 292e6, "hardening_exponent": 0.31,
      "strain_rate_coefficient": 0.025, "thermal_exponent": 1.09,
      "reference_temperature": 294.0}
T_MELT, CP = 1356.0, 383.0


def copper(temperature: float = 294.0, **extra) -> dict:
    return {"model": "johnson_cook", "density": 8960.0, "youngs_modulus": 124e9,
            "poisson_ratio": 0.34, "specific_heat": CP, "melting_temperature": T_MELT,
            "temperature": temperature, "johnson_cook": dict(JC), **extra}


def jc_flow(eps, rate, T):
    t_star = np.clip((T - 294.0) / (T_MELT - 294.0), 0.0, 1.0)
    rate_term = 1.0 + 0.025 * np.log(np.maximum(rate, 1.0))
    return (90e6 + 292e6 * eps ** 0.31) * rate_term * (1.0 - t_star ** 1.09)


@pytest.mark.parametrize("mode", ["uniaxial_stress", "uniaxial_strain"])
@pytest.mark.parametrize("rate", [0.1, 1e2, 1e4])
@pytest.mark.parametrize("temperature", [294.0, 600.0, 900.0])
def test_johnson_cook_flow_stress(mode, rate, temperature):
    h = material_point(copper(temperature), mode=mode, strain_rate=-rate, strain=0.4,
                       steps=800)
    k = plastic(h, start=2)
    assert k.size > 700
    # the return lands on the surface at the step's plastic strain and rate, and the
    # temperature of the step's start (explicit in T)
    expected = jc_flow(h.equivalent_plastic_strain[k], h.plastic_strain_rate[k],
                       h.temperature[k - 1])
    np.testing.assert_allclose(h.von_mises_stress[k], expected, rtol=1e-9)
    if mode == "uniaxial_strain":  # sigma_eq = |sigma_xx - sigma_yy|
        np.testing.assert_allclose(np.abs(h.stress[k, 0, 0] - h.stress[k, 1, 1]),
                                   h.von_mises_stress[k], rtol=1e-9)
    # the plastic strain rate settles at the imposed rate (uniaxial stress: plastic flow is
    # incompressible, so the axial plastic rate is the imposed one less the elastic part)
    if mode == "uniaxial_stress":
        assert h.plastic_strain_rate[-1] == pytest.approx(rate, rel=2e-3)
    # hotter is softer, faster is harder, at the same plastic strain
    at = h.equivalent_plastic_strain[-1]
    assert h.von_mises_stress[-1] < jc_flow(at, rate, 294.0) * (1 + 1e-9)


def test_adiabatic_temperature_rise():
    """``T - T0 = beta / (rho c_p) int sigma_eq d eps_p`` (per volume; rho changes little)."""
    h = material_point(copper(), strain_rate=-1e3, strain=0.8, steps=4000)
    work_per_mass = np.trapezoid(h.von_mises_stress / h.density, h.equivalent_plastic_strain)
    rise = h.temperature[-1] - 294.0
    assert rise == pytest.approx(0.9 * work_per_mass / CP, rel=2e-3)
    assert rise > 50.0  # a real heating: copper at 0.8 strain gains ~70 K
    # and the code's plastic-work book-keeping heats by beta w / c_p exactly
    assert rise == pytest.approx(0.9 * h.plastic_work[-1] / CP, rel=1e-12)


def test_without_specific_heat_johnson_cook_is_refused():
    material = copper()
    del material["specific_heat"]
    with pytest.raises(ValueError, match="needs specific_heat"):
        schema().Material.model_validate(material)


# -- Johnson-Cook damage ----------------------------------------------------------------

D1, D2, D3 = 0.1, 0.5, -1.5


def fracture_strain(triaxiality: float) -> float:
    return D1 + D2 * math.exp(D3 * triaxiality)


@pytest.mark.parametrize(("mode", "triaxiality"), [("uniaxial_stress", 1.0 / 3.0),
                                                    ("shear", 0.0)])
def test_johnson_cook_damage_fails_at_the_predicted_strain(mode, triaxiality):
    material = copper(damage="johnson_cook_damage",
                      johnson_cook_damage={"d1": D1, "d2": D2, "d3": D3})
    rate = 1e3 if mode == "uniaxial_stress" else 1e3 * math.sqrt(3.0)
    strain = 0.8 if mode == "uniaxial_stress" else 1.5
    h = material_point(material, mode=mode, strain_rate=rate, strain=strain, steps=3000)
    eps_f = fracture_strain(triaxiality)
    failed = np.flatnonzero(h.damage >= 1.0)
    assert failed.size, f"never failed: eps_p reached {h.equivalent_plastic_strain[-1]}"
    first = failed[0]
    eps = h.equivalent_plastic_strain
    step = eps[first] - eps[first - 1]
    assert eps[first - 1] < eps_f <= eps[first] + 1e-12, (eps[first - 1], eps_f, eps[first])
    assert step < 0.01 * eps_f
    assert np.all(h.damage[:first] == 0.0)
    # failed: no deviatoric stress, no tension
    assert h.von_mises_stress[-1] == 0.0
    assert h.pressure[-1] >= 0.0
    # the accumulated indicator is sum d eps_p / eps_f
    assert h.own_state[first - 1, -3] == pytest.approx(eps[first - 1] / eps_f, rel=1e-9)


# -- Grady-Kipp ----------------------------------------------------------------------------

GK = {"weibull_coefficient": 4e35, "weibull_exponent": 9.0}


def basalt(**extra) -> dict:
    return {"model": "elastic", "density": 2700.0, "youngs_modulus": 53e9,
            "poisson_ratio": 0.17, "damage": "grady_kipp", "grady_kipp": dict(GK), **extra}


@pytest.mark.parametrize("flaws", [1, 8])
def test_grady_kipp_bar_fails_at_the_growth_time(flaws):
    """Uniaxial tension at ``rate``: the weakest flaw activates at ``eps_min = sigma_1 / E``,
    and with ``n_act`` active flaws ``D^(1/3)`` grows at ``n_act^(1/3) c_g / (2h)``: one flaw
    breaks the point ``2h / c_g`` later, eight (all active at once: eps_max = eps_min) twice
    as fast."""
    eps_min, rate, h_size = 2e-4, 20.0, 1e-3
    material = basalt()
    model = resolve_material("basalt", schema().Material.model_validate(material))
    c_g = 0.4 * math.sqrt((model.bulk_modulus + 4 / 3 * model.shear_modulus) / model.density)
    t_act = eps_min / rate
    t_grow = 2.0 * h_size / c_g / flaws ** (1.0 / 3.0)
    duration = 1.5 * (t_act + t_grow)
    h = material_point(material, mode="uniaxial_stress", strain_rate=rate, duration=duration,
                       steps=6000, size=h_size, flaws=np.array([flaws, eps_min, eps_min]))
    dt = h.time[1]
    first_damage = h.time[np.flatnonzero(h.damage > 0)[0]]
    assert first_damage == pytest.approx(t_act, abs=2 * dt)
    broken = h.time[np.flatnonzero(h.damage >= 1.0)[0]]
    assert broken == pytest.approx(t_act + t_grow, abs=3 * dt)
    # D^(1/3) grows linearly in between
    mid = (h.time > t_act + 0.2 * t_grow) & (h.time < t_act + 0.8 * t_grow)
    root = h.damage[mid] ** (1.0 / 3.0)
    slope = np.polyfit(h.time[mid], root, 1)[0]
    assert slope == pytest.approx(1.0 / t_grow, rel=1e-3)
    # a broken bar carries no tension
    assert h.axial_stress[-1] == pytest.approx(0.0, abs=1e-9 * E * eps_min)


def test_grady_kipp_in_compression_stays_intact():
    h = material_point(basalt(), mode="uniaxial_stress", strain_rate=-20.0, duration=5e-5,
                       steps=500, flaws=np.array([1.0, 2e-4, 2e-4]))
    assert h.damage.max() == 0.0


def test_flaws_follow_the_weibull_law():
    n = 4000
    volume = np.full(n, 1e-9)
    params = GradyKippParameters(**GK)
    a = assign_flaws(params, volume, np.random.default_rng(1))
    b = assign_flaws(params, volume, np.random.default_rng(1))
    np.testing.assert_array_equal(a, b)  # seeded: reproducible
    count, weakest, strongest = a.T
    assert count.min() >= 1 and np.all(weakest <= strongest)
    total = count.sum()
    # about n ln n flaws to give every particle one (coupon collector: n H_n on average)
    assert 0.7 * n * math.log(n) < total < 1.5 * n * (math.log(n) + 1)
    kV = GK["weibull_coefficient"] * volume.sum()
    # the body's weakest flaw is the first: (1 / kV)^(1/m); its j-th: (j / kV)^(1/m)
    assert weakest.min() == pytest.approx((1.0 / kV) ** (1 / 9.0), rel=1e-12)
    assert strongest.max() == pytest.approx((total / kV) ** (1 / 9.0), rel=1e-12)
    # n(eps) = k V eps^m: the number of flaws below eps is k V eps^m (exact for the list)
    eps = np.sort(weakest)[n // 2]
    assert (weakest <= eps).sum() <= kV * eps ** 9.0 + 1


# -- refusals ------------------------------------------------------------------------------

runner = CliRunner()

CASE = """
name = "jc_block"
dimension = 2

[materials.cu]
library = "ofhc_copper"

[[bodies]]
name = "a"
material = "cu"
velocity = [50.0, 0.0]
[bodies.geometry]
origin = [0.0, 0.0]
size = [0.004, 0.004]
spacing = 0.001

[time]
end = 1.0e-7

[output]
figures = false
"""


@pytest.mark.parametrize(("extra", "field"), [
    ("[materials.cu.johnson_cook]\nhardening_exponent = 1.5\n",
     "materials.cu.johnson_cook.hardening_exponent"),
    ("[materials.cu.johnson_cook]\nyield_stress = -1.0\n",
     "materials.cu.johnson_cook.yield_stress"),
    ("[materials.cu.johnson_cook_damage]\nd1 = nan\n", "materials.cu.johnson_cook_damage.d1"),
    ("[materials.cu.grady_kipp]\nweibull_coefficient = 1e30\nweibull_exponent = 0.0\n",
     "materials.cu.grady_kipp.weibull_exponent"),
])
def test_bad_material_parameters_refused(tmp_path, extra, field):
    text = CASE + extra
    if "grady_kipp" in extra:
        text = text.replace('library = "ofhc_copper"',
                            'library = "ofhc_copper"\ndamage = "grady_kipp"')
    path = tmp_path / "case.toml"
    path.write_text(text)
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and field in lines[0], lines


@pytest.mark.parametrize(("change", "message"), [
    (('library = "ofhc_copper"', 'library = "unobtainium"'),
     "materials.cu.library = 'unobtainium': not a library material"),
    (('library = "ofhc_copper"', 'library = "ofhc_copper"\nmelting_temperature = -5.0'),
     "materials.cu.melting_temperature"),
    (('library = "ofhc_copper"', 'library = "ofhc_copper"\ntaylor_quinney = 1.5'),
     "materials.cu.taylor_quinney"),
])
def test_bad_library_use_refused(tmp_path, change, message):
    path = tmp_path / "case.toml"
    path.write_text(CASE.replace(*change))
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 2, res.output
    assert message in res.output and len(res.output.strip().splitlines()) == 1, res.output


def test_library_materials_validate_and_override(tmp_path):
    from impactsph.library import library
    from impactsph.loading import load_case

    for name, entry in library().items():
        assert entry["sources"], name
        material = {k: v for k, v in entry.items() if k not in ("description", "sources")}
        resolve_material(name, schema().Material.model_validate(material))
    path = tmp_path / "case.toml"
    path.write_text(CASE + "[materials.cu.johnson_cook]\nyield_stress = 95.0e6\n")
    case = load_case(path)
    cu = case.materials["cu"]
    assert cu.library == "ofhc_copper"
    assert cu.johnson_cook.yield_stress == 95e6  # overridden
    assert cu.johnson_cook.hardening_modulus == 292e6  # the library's
    assert cu.density == 8960.0


def test_materials_command_lists_sources():
    res = runner.invoke(app, ["materials"])
    assert res.exit_code == 0
    for name in ("ofhc_copper", "armco_iron", "steel_4340", "al_6061_t6", "al_2024_t3",
                 "tungsten_alloy", "basalt"):
        assert name in res.output
    assert "Johnson & Cook (1983)" in res.output
    one = runner.invoke(app, ["materials", "ofhc_copper"])
    assert one.exit_code == 0 and "[materials.ofhc_copper.johnson_cook]" in one.output
    bad = runner.invoke(app, ["materials", "unobtainium"])
    assert bad.exit_code == 2
