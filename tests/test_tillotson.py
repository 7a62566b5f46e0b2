"""The Tillotson equation of state (models/eos/tillotson.py) against hand values, its
continuity, a short 2D impact run from a case file, and the refusal of bad parameters.

Parameters:

- basalt, Benz & Asphaug (1999, Icarus 142, Table II): rho0 = 2700 kg/m^3, A = B = 26.7 GPa,
  E0 = 487 MJ/kg, E_iv = 4.72 MJ/kg, E_cv = 18.2 MJ/kg, a = 0.5, b = 1.5, alpha = beta = 5;
- aluminium, Tillotson (1962) as tabulated by Melosh (1989, Impact Cratering, App. II):
  rho0 = 2700 kg/m^3, A = 75.2 GPa, B = 65 GPa, E0 = 5.0 MJ/kg, E_iv = 3.0 MJ/kg,
  E_cv = 13.9 MJ/kg, a = 0.5, b = 1.63, alpha = beta = 5 (energies in J/kg).

The hand values are each region's formula written out again below, in plain Python.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph.cli import app
from impactsph.loading import load_case
from impactsph.materials import resolve_material
from impactsph.models import EOS
from impactsph.models.eos.tillotson import COLUMNS, pressure, pressure_of, tillotson_pressure
from impactsph.simulation import Simulation

RHO0 = 2700.0
BASALT = dict(a=0.5, b=1.5, A=2.67e10, B=2.67e10, E0=4.87e8, E_iv=4.72e6, E_cv=1.82e7,
              alpha=5.0, beta=5.0)
ALUMINIUM = dict(a=0.5, b=1.63, A=7.52e10, B=6.5e10, E0=5.0e6, E_iv=3.0e6, E_cv=1.39e7,
                 alpha=5.0, beta=5.0)
MATERIALS = {"basalt": BASALT, "aluminium": ALUMINIUM}


# -- the hand formulas (Melosh 1989 App. II; Benz & Asphaug 1999) -----------------------------

def hand_compressed(rho, e, p):
    """P_c = (a + b/omega) rho e + A mu + B mu^2."""
    eta = rho / RHO0
    mu = eta - 1.0
    omega = e / (p["E0"] * eta**2) + 1.0
    return (p["a"] + p["b"] / omega) * rho * e + p["A"] * mu + p["B"] * mu**2


def hand_expanded(rho, e, p):
    """P_e = a rho e + (b rho e/omega + A mu exp(-beta z)) exp(-alpha z^2), z = rho0/rho - 1."""
    eta = rho / RHO0
    mu = eta - 1.0
    omega = e / (p["E0"] * eta**2) + 1.0
    z = RHO0 / rho - 1.0
    return (p["a"] * rho * e
            + (p["b"] * rho * e / omega + p["A"] * mu * math.exp(-p["beta"] * z))
            * math.exp(-p["alpha"] * z**2))


def hand_between(rho, e, p):
    """((e - E_iv) P_e + (E_cv - e) P_c) / (E_cv - E_iv)."""
    return (((e - p["E_iv"]) * hand_expanded(rho, e, p)
             + (p["E_cv"] - e) * hand_compressed(rho, e, p)) / (p["E_cv"] - p["E_iv"]))


def till_p(rho, e, p):
    return tillotson_pressure(rho, e, RHO0, *(p[name] for name in COLUMNS))


# (material, rho/rho0, e, region, hand formula)
CASES = [
    ("basalt", 1.10, 1.0e6, "compressed", hand_compressed),
    ("basalt", 1.10, 5.0e7, "compressed hot", hand_compressed),
    ("basalt", 0.90, 1.0e6, "cold expanded", hand_compressed),
    ("basalt", 0.90, 5.0e7, "hot expanded", hand_expanded),
    ("basalt", 0.90, 1.0e7, "interpolated", hand_between),
    ("basalt", 0.50, 1.0e7, "interpolated, far", hand_between),
    ("aluminium", 1.20, 2.0e6, "compressed", hand_compressed),
    ("aluminium", 0.80, 1.0e6, "cold expanded", hand_compressed),
    ("aluminium", 0.80, 3.0e7, "hot expanded", hand_expanded),
    ("aluminium", 0.80, 8.0e6, "interpolated", hand_between),
]


@pytest.mark.parametrize(("material", "ratio", "e", "region", "hand"), CASES,
                         ids=[f"{c[0]}-{c[3]}" for c in CASES])
def test_pressure_by_hand(material, ratio, e, region, hand):
    p = MATERIALS[material]
    rho = ratio * RHO0
    expected = hand(rho, e, p)
    assert till_p(rho, e, p) == pytest.approx(expected, rel=1e-12)
    # the registered form, as the generated passes call it, with a table row
    row = np.array([p[name] for name in COLUMNS])
    assert pressure(rho, e, RHO0, 1.0, row) == pytest.approx(expected, rel=1e-12)


def test_worked_numbers():
    """Two values worked through by hand (basalt, rho = 1.1 rho0, e = 1 MJ/kg; aluminium,
    rho = 0.8 rho0, e = 30 MJ/kg)."""
    # omega = 1e6 / (4.87e8 * 1.21) + 1 = 1.0016971; P = (0.5 + 1.5/omega) 2970 1e6
    # + 2.67e10 (0.1 + 0.01) = 5.93245e9 + 2.937e9
    assert till_p(1.1 * RHO0, 1.0e6, BASALT) == pytest.approx(8.86945e9, rel=1e-5)
    # z = 0.25, omega = 3e7 / (5e6 * 0.64) + 1 = 10.375; exp(-5/16) = 0.731616,
    # exp(-1.25) = 0.286505; P = 0.5 2160 3e7 + (1.63 2160 3e7 / 10.375
    # - 7.52e10 0.2 0.286505) 0.731616 = 3.24e10 + (1.01806e10 - 4.30903e9) 0.731616
    assert till_p(0.8 * RHO0, 3.0e7, ALUMINIUM) == pytest.approx(3.66958e10, rel=1e-5)


def test_vectorised_helper():
    rho = RHO0 * np.array([0.8, 1.0, 1.2])
    got = pressure_of(rho, 2.0e6, RHO0, **ALUMINIUM)
    assert got == pytest.approx([till_p(r, 2.0e6, ALUMINIUM) for r in rho], rel=1e-15)


# -- continuity ----------------------------------------------------------------------------

NUDGE = 1e-12


@pytest.mark.parametrize("material", list(MATERIALS))
@pytest.mark.parametrize("e_over_cv", [0.1, 0.5, 1.0, 2.0, 10.0])
def test_continuous_across_reference_density(material, e_over_cv):
    """At rho = rho0 mu = 0 and the exponentials are 1, so P_e = P_c: continuous for every e
    (interpolated and hot regions included)."""
    p = MATERIALS[material]
    e = e_over_cv * p["E_cv"]
    at = till_p(RHO0, e, p)
    below = till_p(RHO0 * (1.0 - NUDGE), e, p)
    assert below == pytest.approx(at, rel=1e-9)
    assert till_p(RHO0 * (1.0 + NUDGE), e, p) == pytest.approx(at, rel=1e-9)


@pytest.mark.parametrize("material", list(MATERIALS))
@pytest.mark.parametrize("ratio", [0.3, 0.6, 0.9, 0.99])
@pytest.mark.parametrize("edge", ["E_iv", "E_cv"])
def test_continuous_across_vaporisation_energies(material, ratio, edge):
    """Expanded states: the interpolation is P_c at E_iv and P_e at E_cv."""
    p = MATERIALS[material]
    rho, e = ratio * RHO0, p[edge]
    below, at, above = (till_p(rho, e * (1.0 - NUDGE), p), till_p(rho, e, p),
                        till_p(rho, e * (1.0 + NUDGE), p))
    limit = hand_compressed(rho, e, p) if edge == "E_iv" else hand_expanded(rho, e, p)
    scale = max(abs(limit), p["A"] * 1e-6)  # P crosses zero at some densities
    for value in (below, at, above):
        assert abs(value - limit) <= 1e-9 * scale


def test_slope_in_e_is_not_continuous():
    """Only P is continuous: dP/de jumps at E_iv (and E_cv) for rho < rho0, by
    (P_e - P_c) / (E_cv - E_iv) at E_iv."""
    p, rho, de = BASALT, 0.5 * RHO0, 1e2
    e = p["E_iv"]
    left = (till_p(rho, e, p) - till_p(rho, e - de, p)) / de
    right = (till_p(rho, e + de, p) - till_p(rho, e, p)) / de
    jump = (hand_expanded(rho, e, p) - hand_compressed(rho, e, p)) / (p["E_cv"] - p["E_iv"])
    assert abs(jump) > 0.05 * abs(left)  # 7 % of the slope here
    assert right - left == pytest.approx(jump, rel=1e-3)


# -- a run ---------------------------------------------------------------------------------

CASE = """
name = "tillotson_blocks"
dimension = 2

[materials.basalt]
model = "elastic"
density = 2700.0
youngs_modulus = 4.005e10   # E = 3 A (1 - 2 nu): K = A
poisson_ratio = 0.25
eos = "tillotson"

[materials.basalt.tillotson]
a = 0.5
b = 1.5
A = 2.67e10
B = 2.67e10
E0 = 4.87e8
E_iv = 4.72e6
E_cv = 1.82e7
alpha = 5.0
beta = 5.0

[[bodies]]
name = "a"
material = "basalt"
velocity = [100.0, 30.0]
[bodies.geometry]
origin = [0.0, 0.0]
size = [0.008, 0.008]
spacing = 0.001

[[bodies]]
name = "b"
material = "basalt"
velocity = [-100.0, -30.0]
[bodies.geometry]
origin = [0.008, 0.003]
size = [0.008, 0.008]
spacing = 0.001

[kernel]
h_over_dx = 1.3

[viscosity]
alpha1 = 1.0
alpha2 = 1.0

[time]
end = 1.0e-5
courant = 0.15

[output]
figures = false
snapshot_times = [3e-6, 6e-6, 9e-6]
"""


def write_case(tmp_path: Path, text: str = CASE) -> Path:
    path = tmp_path / "tillotson.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_impact_conserves_momentum_and_energy(tmp_path):
    case = load_case(write_case(tmp_path))
    m = resolve_material("basalt", case.materials["basalt"])
    assert m.bulk_modulus == pytest.approx(2.67e10)  # K = A by the choice of E and nu
    assert m.eos_columns == tuple(BASALT[name] for name in COLUMNS)
    sim = Simulation(case)
    sim.run()
    s = sim.summary()
    assert s["failure"] is None
    assert s["n_steps"] >= 200, s["n_steps"]
    assert s["momentum_drift"] < 1e-12, s["momentum_drift"]
    assert abs(s["total_energy_relative_error"]) <= 1e-3, s["total_energy_relative_error"]
    assert s["internal_energy_final"] > 0.0
    # the particles' pressure is Tillotson's of their density and energy (cold states here)
    assert len(sim.record.snapshots) >= 3
    for snap in sim.record.snapshots:
        rho, e = snap.fields["density"], snap.fields["specific_energy"]
        by_hand = np.array([hand_compressed(r, x, BASALT) for r, x in zip(rho, e, strict=True)])
        np.testing.assert_allclose(snap.fields["pressure"], by_hand, rtol=1e-12,
                                   atol=1e-12 * np.abs(by_hand).max())
    assert np.abs(by_hand).max() > 1e8  # a real compression


# -- refusals ------------------------------------------------------------------------------

runner = CliRunner()


@pytest.mark.parametrize(("old", "new", "field"), [
    ("E_cv = 1.82e7", "E_cv = 4.72e6", "materials.basalt.tillotson.E_cv"),
    ("E_cv = 1.82e7", "E_cv = 1.0e6", "materials.basalt.tillotson.E_cv"),
    ("A = 2.67e10", "A = -2.67e10", "materials.basalt.tillotson.A"),
    ("E0 = 4.87e8", "E0 = 0.0", "materials.basalt.tillotson.E0"),
    ("alpha = 5.0", "alpha = -5.0", "materials.basalt.tillotson.alpha"),
    ("beta = 5.0\n", "", "beta"),
    (CASE[CASE.index("[materials.basalt.tillotson]"):CASE.index("[[bodies]]")], "",
     "needs a [tillotson] table"),
])
def test_bad_parameters_refused(tmp_path, old, new, field):
    assert old in CASE
    path = write_case(tmp_path, CASE.replace(old, new))
    for args in (["check", str(path)],
                 ["run", str(path), "--quiet", "--out", str(tmp_path / "out")]):
        res = runner.invoke(app, args)
        assert res.exit_code == 2, res.output
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert len(lines) == 1, res.output
        assert lines[0].startswith("error: ") and field in lines[0], lines[0]
        assert "Traceback" not in res.output
    assert not (tmp_path / "out").exists()


def test_registered():
    assert "tillotson" in EOS.names()
    assert EOS["tillotson"].columns == COLUMNS
