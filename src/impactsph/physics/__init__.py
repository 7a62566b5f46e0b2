"""Physical terms of the SPH solid model: each module states one equation.

- :mod:`.eos` -- pressure from density and internal energy (eqs 6-12),
- :mod:`.strength` -- von Mises perfect plasticity by radial return (eqs 17-18),
- :mod:`.stress_rate` -- Jaumann deviatoric stress rate (eqs 14-16, 25),
- :mod:`.viscosity` -- Monaghan artificial viscosity (eqs 29-30),
- :mod:`.continuity`, :mod:`.momentum`, :mod:`.energy` -- the pair terms of eqs 22, 27, 28,
- :mod:`.contact` -- compression-only interaction between bodies,
- :mod:`.rates` -- the one place where the pair loop applies all of them.
"""
