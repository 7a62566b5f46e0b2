"""Issue 11: every stabilisation and contact option on two impacts, a block on a rigid wall and
two blocks colliding: momentum to round-off (the walls' push, constraint included, is booked as
an external impulse) and a total-energy error within 1e-3 (docs/stabilisation.md)."""

from __future__ import annotations

import pytest

from impactsph.loading import validate_case
from impactsph.simulation import Simulation

RHO, E, MU, Y = 7850.0, 2.0e11, 8.0e10, 4.0e8
DX = 1e-3

OPTIONS = {
    "paper": {},
    "velocity_gradient": {"stabilisation": {"gradient_correction": "velocity_gradient"}},
    "forces": {"stabilisation": {"gradient_correction": "velocity_gradient_and_forces"}},
    "forces+hourglass": {"stabilisation": {"gradient_correction":
                                           "velocity_gradient_and_forces", "hourglass": 2.0}},
    "normal_stress": {"contact": {"traction": "normal_stress"}},
    "normal_stress+wall_layer": {"contact": {"traction": "normal_stress", "wall_layer": 0.25}},
    "artificial_stress": {"stabilisation": {"artificial_stress": 0.3}},
    "forces+artificial_stress": {"stabilisation": {"gradient_correction":
                                                   "velocity_gradient_and_forces",
                                                   "artificial_stress": 0.3}},
    # a smoothing length that grows with the stretch (set at each list build; mean h_ij)
    "max_stretch": {"kernel": {"h_over_dx": 1.3, "max_stretch": 1.25}},
}


def impact(kind: str, options: dict, plastic: bool) -> dict:
    material = {"model": "elastic_plastic" if plastic else "elastic", "density": RHO,
                "youngs_modulus": E, "shear_modulus": MU}
    if plastic:
        material["yield_stress"] = Y
    if kind == "wall":
        bodies = [{"name": "block", "material": "m", "velocity": [0.0, -150.0],
                   "geometry": {"origin": [0.0, 0.0], "size": [8 * DX, 8 * DX],
                                "spacing": DX}}]
        walls = [{"point": [0.0, 0.0], "normal": [0.0, 1.0]}]
    else:
        bodies = [{"name": name, "material": "m", "velocity": [v, 0.3 * v],
                   "geometry": {"origin": [x0, y0], "size": [8 * DX, 8 * DX],
                                "spacing": DX}}
                  for name, x0, y0, v in (("a", 0.0, 0.0, 75.0), ("b", 8 * DX, 3 * DX, -75.0))]
        walls = []
    case = validate_case({
        "name": f"{kind}-impact", "dimension": 2, "materials": {"m": material},
        "bodies": bodies, "boundaries": walls, "kernel": {"h_over_dx": 1.3},
        "viscosity": {"alpha1": 1.0, "alpha2": 1.0}, **options,
        "time": {"end": 8e-6, "courant": 0.15}, "output": {"figures": False}})
    sim = Simulation(case)
    sim.run()
    return sim.summary()


@pytest.mark.parametrize("kind", ["wall", "bodies"])
@pytest.mark.parametrize("name", list(OPTIONS))
def test_every_option_conserves(name, kind):
    plastic = "hourglass" not in name  # the hourglass control is for elastic bodies
    s = impact(kind, OPTIONS[name], plastic)
    assert s["failure"] is None
    assert s["momentum_drift"] < 1e-12, s["momentum_drift"]
    assert abs(s["total_energy_relative_error"]) <= 1e-3, s["total_energy_relative_error"]
    if plastic:
        assert s["plastic_work"] > 0.0  # the impact is hard enough to yield
