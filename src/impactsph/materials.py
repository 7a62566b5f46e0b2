"""Material models and their packed, compiled-kernel form.

Three models:

- ``bar``: one-dimensional uniaxial stress (the bars of Example 1).  Pressure
  ``P = E (rho/rho0 - 1)``, no deviatoric stress; wave speed ``sqrt(E/rho)``.
- ``elastic``: linear EOS with ``K = E / (3 (1 - 2 nu))`` (or Mie-Gruneisen), shear modulus
  ``mu = E / (2 (1 + nu))``, Jaumann deviatoric stress.
- ``elastic_plastic``: ``elastic`` plus von Mises perfect plasticity with yield stress
  ``sigma_y``.

The kernels read a float table with one row per material; the column indices are below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .physics.eos import LINEAR, MIE_GRUNEISEN, mie_gruneisen_coefficients

RHO0, EOS, BULK, B0, C0, GAMMA, SHEAR, YIELD, WAVE_MODULUS = range(9)
N_COLUMNS = 9


@dataclass(frozen=True)
class MaterialModel:
    """Resolved material constants in SI units."""

    name: str
    model: str
    density: float
    youngs_modulus: float
    poisson_ratio: float
    shear_modulus: float
    bulk_modulus: float
    eos: str = "linear"
    yield_stress: float = math.inf
    mg_sound_speed: float = 0.0
    mg_slope: float = 0.0
    mg_gamma: float = 0.0

    def wave_modulus(self, wave_speed: str) -> float:
        """Modulus ``M`` with ``c = sqrt(M / rho)``: ``E`` for the paper's bar-wave speed
        (eq 26), ``K + 4/3 mu`` for the longitudinal (P-wave) speed."""
        if self.model == "bar" or wave_speed == "bar":
            return self.youngs_modulus
        return self.bulk_modulus + 4.0 / 3.0 * self.shear_modulus

    def row(self, wave_speed: str) -> np.ndarray:
        """This material as one row of the kernels' table."""
        r = np.zeros(N_COLUMNS)
        r[RHO0] = self.density
        r[SHEAR] = self.shear_modulus
        r[YIELD] = self.yield_stress
        r[WAVE_MODULUS] = self.wave_modulus(wave_speed)
        if self.eos == "mie_gruneisen":
            a0, b0, c0 = mie_gruneisen_coefficients(
                self.density, self.mg_sound_speed, self.mg_slope)
            r[EOS], r[BULK], r[B0], r[C0], r[GAMMA] = MIE_GRUNEISEN, a0, b0, c0, self.mg_gamma
        else:
            r[EOS], r[BULK] = LINEAR, self.bulk_modulus
        return r


def material_table(materials: list[MaterialModel], wave_speed: str) -> np.ndarray:
    """Stack the materials' rows into the (n_materials, N_COLUMNS) table of the kernels."""
    return np.ascontiguousarray(np.stack([m.row(wave_speed) for m in materials]))
