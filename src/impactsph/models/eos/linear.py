"""Linear equation of state (paper eq 6)::

    P = K (rho / rho0 - 1)

with the bulk modulus ``K = E / (3 (1 - 2 nu))`` of the material (``K = E`` for the 1D bar of
Example 1).  Pressure is positive in compression.  No parameters of its own.
"""

from __future__ import annotations

import numba as nb

from ..registry import EOS, EquationOfState


@nb.njit(inline="always", cache=True)
def pressure(rho: float, e: float, rho0: float, bulk_modulus: float, params) -> float:
    """Eq 6: ``P = K (rho/rho0 - 1)``."""
    return bulk_modulus * (rho / rho0 - 1.0)


LINEAR = EOS.register(EquationOfState(
    name="linear", pressure=pressure, source="Shaw & Reid (2009) eq 6",
    description="P = K (rho/rho0 - 1), K = E / (3 (1 - 2 nu))"))
