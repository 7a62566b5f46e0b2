"""The perforation analysis on a small plane-strain steel disk through an aluminium plate
(the sphere-plate example's materials, 2D): it perforates, its residual velocity and the hole
are measured, energy and momentum are kept; the half model with a symmetry plane gives the
same measures; the sphere geometry holds 4/3 pi r^3 up to its staircase."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest

from impactsph import Simulation
from impactsph.geometry import sphere_particles
from impactsph.loading import read_case_dict, validate_case
from impactsph.problems import analyse


def case(half: bool = False):
    data = read_case_dict(Path(__file__).resolve().parent.parent / "examples"
                          / "sphere_plate3d.toml")
    data["dimension"] = 2
    data["name"] = "disk_plate"
    data["bodies"][0]["velocity"] = [0.0, -3100.0]
    data["bodies"][0]["geometry"] = {"type": "disk", "centre": [0.0, 0.0027],
                                     "radius": 0.0025, "spacing": 0.0005}
    data["bodies"][1]["velocity"] = [0.0, 0.0]
    data["bodies"][1]["geometry"] = {"origin": [-0.01, -0.001], "size": [0.02, 0.001],
                                     "spacing": 0.0005}
    data["time"]["end"] = 3e-6
    data["output"] = {"figures": False}
    if half:
        data = copy.deepcopy(data)
        data["bodies"][0]["geometry"] = {"type": "block", "origin": [0.0, 0.0002],
                                         "size": [0.0025, 0.005], "spacing": 0.0005}
        data["bodies"][1]["geometry"]["origin"] = [0.0, -0.001]
        data["bodies"][1]["geometry"]["size"] = [0.01, 0.001]
        data["boundaries"] = [{"type": "symmetry", "point": [0.0, 0.0], "normal": [1.0, 0.0]}]
    return validate_case(data)


def test_disk_perforates_the_plate():
    sim = Simulation(case())
    sim.run()
    m = analyse("perforation", sim)
    assert m["perforated"]
    assert 0.5 < m["residual_velocity_ratio"] < 1.0
    assert m["hole_diameter"] > 0.005  # at least the projectile's diameter
    assert 0.0 < m["ejected_plate_mass_fraction"] < 0.5
    s = sim.summary()
    assert abs(s["total_energy_relative_error"]) < 1e-3
    assert s["momentum_drift"] < 1e-12


def test_half_block_model_measures_like_the_whole():
    """A square projectile (a block, symmetric about x = 0): half and whole agree."""
    whole_data = case(half=True).model_dump(mode="json")
    whole_data["boundaries"] = []
    whole_data["bodies"][0]["geometry"].update(origin=[-0.0025, 0.0002], size=[0.005, 0.005])
    whole_data["bodies"][1]["geometry"].update(origin=[-0.01, -0.001], size=[0.02, 0.001])
    whole = Simulation(validate_case(whole_data))
    whole.run()
    half = Simulation(case(half=True))
    half.run()
    mw, mh = analyse("perforation", whole), analyse("perforation", half)
    for key in ("residual_velocity", "hole_diameter", "ejected_plate_mass_fraction"):
        assert mh[key] == pytest.approx(mw[key], rel=1e-9, abs=1e-12), key


def test_sphere_geometry_volume():
    for radius, spacing in ((0.005, 0.0005), (0.005, 0.00025)):
        p = sphere_particles([0.0, 0.0, 0.0], radius, spacing)
        assert p.volume.sum() == pytest.approx(4 / 3 * math.pi * radius**3, rel=0.03)
        assert np.allclose(p.position.mean(axis=0), 0.0, atol=1e-15)


def test_sphere_shells_are_round_and_exact():
    """The shell arrangement: the volume exact, the outermost particles on a round surface
    half a spacing inside, neighbours about a spacing apart, the centre of mass at the
    centre."""
    from scipy.spatial import cKDTree

    from impactsph.geometry import sphere_shell_particles

    for radius, spacing in ((0.005, 0.0005), (0.005, 0.00025)):
        p = sphere_shell_particles([1.0, 2.0, 3.0], radius, spacing)
        assert p.volume.sum() == pytest.approx(4 / 3 * math.pi * radius**3, rel=1e-12)
        r = np.linalg.norm(p.position - [1.0, 2.0, 3.0], axis=1)
        assert r.max() == pytest.approx(radius - p.spacing / 2, rel=1e-12)
        assert np.allclose(p.position.mean(axis=0), [1.0, 2.0, 3.0], atol=0.05 * spacing)
        nearest, _ = cKDTree(p.position).query(p.position, k=2)
        assert 0.7 * p.spacing < nearest[:, 1].min() and nearest[:, 1].max() < 1.05 * p.spacing
        assert p.volume.min() > 0.98 * p.spacing**3 and p.volume.max() < 1.06 * p.spacing**3
        # round: the outermost shell on one sphere, and no facet: one particle lowest, where
        # the lattice's lowest layer is flat (32 particles at r = 10 dx)
        outer = r > radius - p.spacing
        np.testing.assert_allclose(r[outer], radius - p.spacing / 2, rtol=1e-12)
        z = p.position[:, 2]
        assert (z < z.min() + 1e-9 * spacing).sum() == 1
    lattice = sphere_particles([0.0, 0.0, 0.0], 0.005, 0.0005).position[:, 2]
    assert (lattice < lattice.min() + 1e-12).sum() == 32
