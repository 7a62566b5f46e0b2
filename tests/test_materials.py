"""Equations of state, radial return and the Jaumann stress rate against hand values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactsph.models.eos.linear import pressure as linear_eos
from impactsph.models.eos.mie_gruneisen import (
    hugoniot_coefficients as mie_gruneisen_coefficients,
)
from impactsph.models.eos.mie_gruneisen import mie_gruneisen_pressure
from impactsph.models.strength.von_mises import radial_return, von_mises
from impactsph.physics.stress_rate import jaumann_stress_rate, symmetric_full

# Taylor bar iron (Table 3; density 7850 kg/m^3, docs/modelling.md)
RHO0, C, S, GAMMA = 7850.0, 3600.0, 1.8, 1.8


def test_linear_eos():
    assert linear_eos(7900.0 * 1.01, 0.0, 7900.0, 215e9, np.zeros(1)) == pytest.approx(
        215e9 * 0.01)


def test_mie_gruneisen_coefficients_by_hand():
    a0, b0, c0 = mie_gruneisen_coefficients(RHO0, C, S)
    assert a0 == pytest.approx(7850 * 3600**2)  # 1.01736e11 Pa
    assert b0 == pytest.approx(a0 * 2.6)  # 1 + 2 (S - 1) = 2.6
    assert c0 == pytest.approx(a0 * (1.6 + 3 * 0.64))  # 2 (S-1) + 3 (S-1)^2 = 3.52


def test_mie_gruneisen_compression_by_hand():
    eta, e = 0.05, 2.0e4
    rho = RHO0 * (1 + eta)
    a0 = 1.01736e11
    p_h = a0 * (eta + 2.6 * eta**2 + 3.52 * eta**3)
    expected = (1 - 0.5 * 1.8 * eta) * p_h + 1.8 * rho * e
    a, b, c = mie_gruneisen_coefficients(RHO0, C, S)
    assert mie_gruneisen_pressure(rho, e, RHO0, a, b, c, GAMMA) == pytest.approx(expected,
                                                                               rel=1e-12)
    assert expected == pytest.approx(5.82890e9, rel=1e-4)  # worked by hand


def test_mie_gruneisen_tension_is_linear_in_eta():
    """Eq 8 prints a0 eta^3 for tension; the tension branch is a0 eta (docs/modelling.md)."""
    eta = -0.01
    a, b, c = mie_gruneisen_coefficients(RHO0, C, S)
    p = mie_gruneisen_pressure(RHO0 * (1 + eta), 0.0, RHO0, a, b, c, GAMMA)
    assert p == pytest.approx((1 - 0.5 * GAMMA * eta) * a * eta, rel=1e-12)
    assert p < 0


def test_radial_return_by_hand():
    S = np.zeros((3, 3))
    S[0, 1] = S[1, 0] = 500e6  # pure shear: sigma_eq = sqrt(3) * 500 MPa = 866 MPa
    assert von_mises(S) == pytest.approx(math.sqrt(3) * 500e6)
    f = radial_return(S, 600e6)
    assert f == pytest.approx(600e6 / (math.sqrt(3) * 500e6))
    assert von_mises(S) == pytest.approx(600e6)
    assert S[0, 1] == pytest.approx(600e6 / math.sqrt(3))
    # below yield: untouched
    S2 = np.diag([100e6, -100e6, 0.0])
    assert radial_return(S2, 600e6) == 1.0 and S2[0, 0] == 100e6


def test_plane_strain_yield_includes_szz():
    """A plane-strain deviator with S_zz != 0: ignoring S_zz underestimates sigma_eq."""
    S = np.diag([300e6, 100e6, -400e6])  # traceless, S_zz = -(S_xx + S_yy)
    full = von_mises(S)
    assert full == pytest.approx(math.sqrt(1.5 * (300e6**2 + 100e6**2 + 400e6**2)))
    in_plane_only = math.sqrt(1.5 * (300e6**2 + 100e6**2))
    assert full / in_plane_only > 1.3
    Sy = S.copy()
    radial_return(Sy, 400e6)
    assert von_mises(Sy) == pytest.approx(400e6)
    assert Sy[2, 2] == pytest.approx(-(Sy[0, 0] + Sy[1, 1]))


def test_jaumann_pure_strain_rate_factor_two():
    """Uniaxial strain rate in 2D plane strain: dS_xx = 2 mu (2/3) eps_dot (eq 14, its factor 2
    restored)."""
    mu, rate = 80e9, 1e3
    L = np.array([[rate, 0.0], [0.0, 0.0]])
    components = np.zeros(6)  # the rate's six components (xx, xy, xz, yy, yz, zz)
    jaumann_stress_rate(L, np.zeros((3, 3)), mu, components)
    dS = symmetric_full(components)
    assert dS[0, 0] == pytest.approx(2 * mu * 2 / 3 * rate)
    assert dS[1, 1] == pytest.approx(-2 * mu * rate / 3)
    assert dS[2, 2] == pytest.approx(-2 * mu * rate / 3)
    assert abs(np.trace(dS)) < 1e-12 * abs(dS[0, 0])


def test_jaumann_spin_rotates_stress():
    """With pure spin, dS = omega S - S omega: the derivative of R S R^T at R = I."""
    w = 2.0
    L = np.array([[0.0, -w], [w, 0.0]])  # v = w (-y, x): counter-clockwise
    S = np.diag([1.0, -1.0, 0.0])
    components = np.zeros(6)
    jaumann_stress_rate(L, S, 1e9, components)
    dS = symmetric_full(components)
    Omega = np.array([[0, -w, 0], [w, 0, 0], [0, 0, 0]])
    np.testing.assert_allclose(dS, Omega @ S - S @ Omega, atol=1e-12)
    assert np.sum(dS * S) == pytest.approx(0.0)  # d(S:S)/dt = 0: invariants kept
