"""Geometries of bodies: blocks, disks, rings, cylinders and particles read from CSV or NPZ files;
several bodies of several materials in one case; bad particle files refused before any work."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph.cli import app
from impactsph.config import CaseError
from impactsph.geometry import (
    block_particles,
    body_particles,
    cylinder_particles,
    disk_particles,
    read_particle_file,
    ring_particles,
)
from impactsph.loading import load_case, validate_case
from impactsph.problem import build_problem

runner = CliRunner()

STEEL = ('[materials.steel]\nmodel = "elastic"\ndensity = 7800.0\nyoungs_modulus = 200e9\n'
         'poisson_ratio = 0.3\n')
ALUMINIUM = ('[materials.aluminium]\nmodel = "elastic_plastic"\ndensity = 2700.0\n'
             'youngs_modulus = 70e9\npoisson_ratio = 0.33\nyield_stress = 300e6\n')


def write_case(directory, bodies: str, dimension: int = 2, extra: str = "") -> str:
    """A small case file in ``directory`` with the given ``[[bodies]]`` text."""
    text = (f'name = "shapes"\ndimension = {dimension}\n\n{STEEL}\n{ALUMINIUM}\n{bodies}\n'
            f'[kernel]\nh_over_dx = 1.3\n\n[time]\nend = 1e-6\nmax_steps = 3\n\n'
            f'[output]\nfigures = false\n{extra}')
    path = directory / "case.toml"
    path.write_text(text)
    return str(path)


def body(name: str, material: str, geometry: str, dim: int = 2,
         velocity: list[float] | None = None) -> str:
    v = ", ".join(repr(c) for c in (velocity or [0.0] * dim))
    return (f'[[bodies]]\nname = "{name}"\nmaterial = "{material}"\nvelocity = [{v}]\n'
            f'[bodies.geometry]\n{geometry}\n')


def refused(args: list[str]) -> str:
    """Run the CLI; it must refuse with exit code 2 and one line 'error: ...'; return it."""
    res = runner.invoke(app, args)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert "Traceback" not in res.output
    return lines[0]


# -- lattices ----------------------------------------------------------------------------------


@pytest.mark.parametrize("r_over_dx", [10, 12.5, 17.3, 25])
@pytest.mark.parametrize("centre", [(0.0, 0.0), (0.31, -0.2)])
def test_disk_volume_and_points_inside(r_over_dx, centre):
    dx = 0.001
    r = r_over_dx * dx
    p = disk_particles(list(centre), r, dx)
    assert p.position.shape == (p.n, 2)
    assert p.n == pytest.approx(math.pi * r_over_dx**2, rel=0.03)
    assert p.volume.sum() == pytest.approx(math.pi * r**2, rel=0.03)
    assert np.allclose(p.volume, dx**2) and p.spacing == dx
    d = np.linalg.norm(p.position - centre, axis=1)
    assert d.max() <= r * (1 + 1e-12)
    # the lattice is symmetric about the centre, which is a cell corner
    assert np.allclose(p.position.mean(axis=0), centre, atol=1e-12)
    assert d.min() == pytest.approx(dx / math.sqrt(2))
    assert len(np.unique(np.round(p.position / dx, 6), axis=0)) == p.n


def test_disk_volume_converges():
    errors = [abs(disk_particles([0.0, 0.0], 1.0, 1.0 / k).volume.sum() - math.pi) / math.pi
              for k in (10, 40, 160)]
    assert errors[-1] < 0.002 and errors[-1] < errors[0]


@pytest.mark.parametrize(("inner", "outer"), [(30, 40), (7.3, 12.6), (0.0, 10.0)])
def test_ring_count_volume_and_points_inside(inner, outer):
    """The ring is the disk lattice between the two circles: its count is the outer disk's
    less the points strictly inside the inner circle, its volume pi (r_o^2 - r_i^2) within
    the staircase error, and inner radius 0 gives the disk."""
    dx, centre = 0.001, np.array([0.02, -0.01])
    p = ring_particles(centre.tolist(), inner * dx, outer * dx, dx)
    d = np.linalg.norm(p.position - centre, axis=1)
    assert d.min() >= inner * dx * (1 - 1e-12) and d.max() <= outer * dx * (1 + 1e-12)
    disk = disk_particles(centre.tolist(), outer * dx, dx)
    inside = np.linalg.norm(disk.position - centre, axis=1) < inner * dx * (1 - 1e-12)
    assert p.n == disk.n - inside.sum()
    assert p.n == pytest.approx(math.pi * (outer**2 - inner**2), rel=0.03)
    assert np.allclose(p.volume, dx**2) and p.spacing == dx
    assert np.allclose(p.position.mean(axis=0), centre, atol=1e-12)
    if inner == 30:  # the rubber ring of Gray et al. (2001) at 10 particles through its width:
        assert p.n == 2196  # pi (40^2 - 30^2) = 2199.1


def test_ring_cases_are_checked(tmp_path):
    ring = 'type = "ring"\ncentre = [0.0, 0.0]\ninner_radius = 0.03\nouter_radius = 0.04\n'
    case = load_case(write_case(tmp_path, body("r", "steel", ring + "spacing = 0.001")))
    state = build_problem(case).state
    assert state.n == ring_particles([0.0, 0.0], 0.03, 0.04, 0.001).n
    assert np.allclose(state.mass, 7800.0 * 0.001**2)
    for bad, message in [
            ('type = "ring"\ncentre = [0.0, 0.0]\ninner_radius = 0.04\nouter_radius = 0.03\n'
             'spacing = 0.001', "inner_radius = 0.04 must be less than outer_radius = 0.03"),
            ('type = "ring"\ncentre = [0.0, 0.0]\ninner_radius = 0.03025\n'
             'outer_radius = 0.0303\nspacing = 0.001', "holds no particle at spacing = 0.001")]:
        with pytest.raises(CaseError, match=message):
            load_case(write_case(tmp_path, body("r", "steel", bad)))
    with pytest.raises(CaseError, match="type = 'ring' is for dimension = 2 only"):
        load_case(write_case(tmp_path, body("r", "steel", ring.replace("0.0]", "0.0, 0.0]")
                                            + "spacing = 0.001", dim=3), dimension=3))


@pytest.mark.parametrize("axis", ["x", "y", "z"])
@pytest.mark.parametrize(("r_over_dx", "l_over_dx"), [(10, 15), (14.2, 8)])
def test_cylinder_volume_and_points_inside(axis, r_over_dx, l_over_dx):
    dx = 0.002
    r, length = r_over_dx * dx, l_over_dx * dx
    centre = np.array([0.1, -0.05, 0.3])
    p = cylinder_particles(centre.tolist(), r, length, axis, dx)
    assert p.position.shape == (p.n, 3)
    assert p.volume.sum() == pytest.approx(math.pi * r**2 * length, rel=0.03)
    assert np.allclose(p.volume, dx**3) and p.spacing == dx
    a = "xyz".index(axis)
    across = [k for k in range(3) if k != a]
    rel = p.position - centre
    assert np.linalg.norm(rel[:, across], axis=1).max() <= r * (1 + 1e-12)
    assert rel[:, a].min() > 0 and rel[:, a].max() < length
    # layers of the disk lattice
    layers = np.unique(np.round(rel[:, a] / dx, 6))
    assert len(layers) == l_over_dx
    assert p.n == len(layers) * disk_particles([0.0, 0.0], r, dx).n


@pytest.mark.parametrize("axis", ["x", "z"])
@pytest.mark.parametrize(("r_over_dx", "l_over_dx"), [(10.3, 15.4), (1.2, 3)])
def test_cylinder_of_rings(axis, r_over_dx, l_over_dx):
    """``arrangement = "rings"``: the volume exact, the outermost particles on one round
    surface half a ring inside the radius, each ring's points evenly spaced, the section the
    same at every layer, and mirror-symmetric about both lateral axes with no particle on
    them (the quarter of the Taylor cylinder)."""
    dx = 0.002
    r, length = r_over_dx * dx, l_over_dx * dx
    centre = np.array([0.1, -0.05, 0.3])
    p = cylinder_particles(centre.tolist(), r, length, axis, dx, "rings")
    rings, layers = max(1, round(r_over_dx)), round(l_over_dx)
    dr, dz = r / rings, length / layers
    assert p.volume.sum() == pytest.approx(math.pi * r**2 * length, rel=1e-12)
    assert p.spacing == pytest.approx((dr * dr * dz) ** (1 / 3), rel=1e-12)
    a = "xyz".index(axis)
    across = [k for k in range(3) if k != a]
    rel = p.position - centre
    radius = np.linalg.norm(rel[:, across], axis=1)
    assert radius.max() == pytest.approx(r - dr / 2, rel=1e-12)
    assert np.allclose(np.unique(np.round(radius / dr - 0.5, 9)), np.arange(rings))
    assert np.allclose(np.unique(np.round(rel[:, a] / dz - 0.5, 9)), np.arange(layers))
    section = rel[np.isclose(rel[:, a], dz / 2)][:, across]
    assert p.n == layers * section.shape[0]
    for k in range(rings):  # evenly round each ring, a multiple of 4 points
        ring = section[np.isclose(np.hypot(*section.T), (k + 0.5) * dr)]
        assert ring.shape[0] % 4 == 0
        gaps = np.diff(np.sort(np.arctan2(ring[:, 1], ring[:, 0])))
        assert np.allclose(gaps, 2 * math.pi / ring.shape[0])
    assert np.abs(section).min() > 0.1 * dr
    for mirror in ([-1.0, 1.0], [1.0, -1.0]):
        image = section * np.array(mirror)
        distance = np.linalg.norm(image[:, None, :] - section[None, :, :], axis=2).min(axis=1)
        assert distance.max() < 1e-12 * dr
    q = section[(section[:, 0] > 0) & (section[:, 1] > 0)]
    assert 4 * q.shape[0] == section.shape[0]


def test_a_case_cylinder_of_rings_and_its_spacings(tmp_path):
    """The case file's ``arrangement = "rings"`` reaches the particles; the measures' per-axis
    spacings are the rings' width across the axis and the layers' thickness along it."""
    cyl = ('type = "cylinder"\ncentre = [0.0, 0.0, 0.0]\nradius = 0.0038\nlength = 0.0254\n'
           'axis = "y"\nspacing = 0.0005\narrangement = "rings"')
    case = load_case(write_case(tmp_path, body("c", "steel", cyl, dim=3), dimension=3))
    g = case.bodies[0].geometry
    assert g.spacings() == pytest.approx([0.0038 / 8, 0.0254 / 51, 0.0038 / 8])
    problem = build_problem(case)
    assert problem.state.n == body_particles(g, 3).n
    assert problem.state.mass.sum() == pytest.approx(7800.0 * math.pi * 0.0038**2 * 0.0254,
                                                     rel=1e-12)
    with pytest.raises(CaseError, match="arrangement"):
        load_case(write_case(tmp_path, body("c", "steel", cyl.replace('"rings"', '"hex"'),
                                            dim=3), dimension=3))


def test_block_particles_match_the_lattice():
    p = block_particles([0.0, 1.0], [0.004, 0.002], [0.001, 0.0005])
    assert p.n == 16
    assert np.allclose(p.volume, 0.001 * 0.0005)
    assert p.spacing == pytest.approx(math.sqrt(0.001 * 0.0005))


def test_disk_and_cylinder_cases_set_masses_and_smoothing_lengths(tmp_path):
    path = write_case(tmp_path, body("disk", "steel", 'type = "disk"\ncentre = [0.0, 0.0]\n'
                                     'radius = 0.01\nspacing = 0.001'))
    case = load_case(path)
    state = build_problem(case).state
    assert state.n == disk_particles([0.0, 0.0], 0.01, 0.001).n
    assert np.allclose(state.mass, 7800.0 * 0.001**2)
    assert np.allclose(state.smoothing_length, 1.3 * 0.001)
    (tmp_path / "3d").mkdir()
    path = write_case(tmp_path / "3d", body(
        "rod", "aluminium", 'type = "cylinder"\ncentre = [0.0, 0.0, 0.0]\nradius = 0.005\n'
        'length = 0.01\naxis = "y"\nspacing = 0.001', dim=3), dimension=3)
    state = build_problem(load_case(path)).state
    assert np.allclose(state.mass, 2700.0 * 0.001**3)
    assert state.position[:, 1].min() > 0 and state.position[:, 1].max() < 0.01
    assert state.mass.sum() == pytest.approx(2700.0 * math.pi * 0.005**2 * 0.01, rel=0.05)


# -- particle files ----------------------------------------------------------------------------


def _points(n: int = 30, dim: int = 2, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.01, 0.01, (n, dim))


def test_csv_body_round_trip(tmp_path):
    x = _points()
    volume = np.random.default_rng(2).uniform(0.5e-6, 1.5e-6, len(x))
    (tmp_path / "data").mkdir()
    # columns in any order, comments and blank lines allowed
    rows = [f"{float(v)!r},{float(b)!r},{float(a)!r}" for (a, b), v in
            zip(x, volume, strict=True)]
    lines = ["# particles", "volume, y, x", *rows, ""]
    (tmp_path / "data" / "points.csv").write_text("\n".join(lines))
    path = write_case(tmp_path, body("cloud", "steel", 'type = "file"\npath = "data/points.csv"\n'
                                     'spacing = 0.001'))
    case = load_case(path)
    g = case.bodies[0].geometry
    assert g.path == str(tmp_path / "data" / "points.csv")  # absolute, from the case's folder
    state = build_problem(case).state
    assert np.array_equal(state.position, x)
    assert np.allclose(state.mass, 7800.0 * volume, rtol=1e-15)
    assert np.allclose(state.smoothing_length, 1.3e-3)


def test_csv_without_volume_uses_the_spacing(tmp_path):
    x = _points(dim=1)
    (tmp_path / "line.csv").write_text("x\n" + "\n".join(repr(float(a)) for a in x[:, 0]))
    path = write_case(tmp_path, body("line", "steel", 'type = "file"\npath = "line.csv"\n'
                                     'spacing = 0.0005', dim=1), dimension=1)
    state = build_problem(load_case(path)).state
    assert np.array_equal(state.position, x)
    assert np.allclose(state.mass, 7800.0 * 0.0005)


def test_npz_body_round_trip_and_case_json_records_the_path(tmp_path):
    x = _points(n=40, dim=3)
    volume = np.full(len(x), 2e-9)
    np.savez(tmp_path / "cloud.npz", position=x, volume=volume)
    np.savez(tmp_path / "plain.npz", position=x + 1.0)
    bodies = (body("a", "steel", 'type = "file"\npath = "cloud.npz"\nspacing = 0.001', dim=3)
              + body("b", "aluminium", 'type = "file"\npath = "plain.npz"\nspacing = 0.002',
                     dim=3))
    path = write_case(tmp_path, bodies, dimension=3)
    state = build_problem(load_case(path)).state
    assert np.array_equal(state.position, np.concatenate([x, x + 1.0]))
    assert np.allclose(state.mass[:40], 7800.0 * 2e-9)
    assert np.allclose(state.mass[40:], 2700.0 * 0.002**3)
    assert np.allclose(state.smoothing_length[40:], 1.3 * 0.002)
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", path, "--quiet", "--out", str(out)])
    assert res.exit_code == 0, res.output
    recorded = json.loads((out / "case.json").read_text())["case"]
    assert recorded["bodies"][0]["geometry"]["path"] == str(tmp_path / "cloud.npz")
    assert validate_case(recorded).bodies[1].geometry.path == str(tmp_path / "plain.npz")


def test_relative_path_from_set_is_relative_to_the_current_directory(tmp_path, monkeypatch):
    (tmp_path / "here").mkdir()
    np.savez(tmp_path / "here" / "p.npz", position=_points())
    path = write_case(tmp_path, body("d", "steel", 'type = "disk"\ncentre = [0.0, 0.0]\n'
                                     'radius = 0.003\nspacing = 0.001'))
    monkeypatch.chdir(tmp_path / "here")
    case = load_case(path, ['bodies.0.geometry={ type = "file", path = "p.npz", '
                            'spacing = 0.001 }'])
    assert case.bodies[0].geometry.path == str(tmp_path / "here" / "p.npz")


# -- several bodies and materials --------------------------------------------------------------


def test_two_bodies_of_two_materials(tmp_path):
    bodies = (body("disk", "aluminium", 'type = "disk"\ncentre = [0.0, 0.012]\n'
                   'radius = 0.005\nspacing = 0.0005', velocity=[0.0, -100.0])
              + body("plate", "steel", 'origin = [-0.01, 0.0]\nsize = [0.02, 0.004]\n'
                     'spacing = 0.0005'))
    path = write_case(tmp_path, bodies)
    case = load_case(path)
    problem = build_problem(case)
    s = problem.state
    n_disk = disk_particles([0.0, 0.012], 0.005, 0.0005).n
    assert s.n == n_disk + 40 * 8
    assert problem.body_names == ["disk", "plate"]
    assert [m.name for m in problem.materials] == ["steel", "aluminium"]
    disk, plate = s.body == 0, s.body == 1
    assert disk.sum() == n_disk
    assert np.all(s.material[disk] == 1) and np.all(s.material[plate] == 0)
    assert np.allclose(s.density[disk], 2700.0) and np.allclose(s.density[plate], 7800.0)
    assert np.allclose(s.mass[disk], 2700.0 * 0.0005**2)
    assert np.allclose(s.mass[plate], 7800.0 * 0.0005**2)
    assert np.allclose(s.velocity[disk], [0.0, -100.0]) and np.all(s.velocity[plate] == 0)
    res = runner.invoke(app, ["run", path, "--quiet", "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output


# -- validation --------------------------------------------------------------------------------


def _bad_file_case(tmp_path, name: str, content: str | bytes | None, dim: int = 2) -> str:
    if isinstance(content, bytes):
        (tmp_path / name).write_bytes(content)
    elif content is not None:
        (tmp_path / name).write_text(content)
    geometry = f'type = "file"\npath = "{name}"\nspacing = 0.001'
    return write_case(tmp_path, body("cloud", "steel", geometry, dim=dim), dimension=dim)


@pytest.mark.parametrize(("name", "content", "message"), [
    ("missing.csv", None, "file does not exist"),
    ("one.csv", "x\n0.0\n1.0\n", "has the columns ['x']; dimension = 2 needs x, y and "
                                 "optionally volume"),
    ("three.csv", "x,y,z\n0,0,0\n", "has the columns ['x', 'y', 'z']"),
    ("colour.csv", "x,y,colour\n0,0,1\n", "has the columns ['x', 'y', 'colour']"),
    ("nohead.csv", "0.0,1.0\n1.0,1.0\n", "expected a header naming the columns"),
    ("short.csv", "x,y\n0.0,1.0\n1.0\n", "line 3 has 1 fields; the header names 2"),
    ("nan.csv", "x,y\n0.0,1.0\n1.0,nan\n", "particle 1 has a non-finite position [1.0, nan]"),
    ("inf.csv", "x,y\ninf,1.0\n", "particle 0 has a non-finite position"),
    ("word.csv", "x,y\n0.0,abc\n", "line 2: y = 'abc' is not a number"),
    ("volume.csv", "x,y,volume\n0.0,1.0,0.0\n", "particle 0 has the volume 0.0"),
    ("empty.csv", "x,y\n", "holds no particle"),
    ("blank.csv", "", "is empty"),
    ("latin.csv", b"x,y\n0,1\n" + b"\xff\n", "not valid UTF-8"),
    ("points.txt", "x,y\n0,1\n", "must be .csv or .npz"),
    ("junk.npz", b"not a zip file", "cannot be read"),
])
def test_bad_particle_files_are_refused_before_any_work(tmp_path, name, content, message):
    path = _bad_file_case(tmp_path, name, content)
    line = refused(["check", path])
    assert line.startswith(f"error: bodies.0.geometry.path = {str(tmp_path / name)!r}: "), line
    assert message in line, line
    out = tmp_path / "out"
    assert refused(["run", path, "--quiet", "--out", str(out)]) == line
    assert not out.exists()


@pytest.mark.parametrize(("arrays", "message"), [
    ({"position": np.zeros((4, 3))}, "position has the shape (4, 3); dimension = 2 needs (n, 2)"),
    ({"positions": np.zeros((4, 2))}, "unknown array 'positions'"),
    ({"volume": np.ones(4)}, "holds no array 'position'"),
    ({"position": np.zeros((4, 2)), "volume": np.ones(3)}, "volume has the shape (3,)"),
    ({"position": np.array([[0.0, 1.0], [np.nan, 0.0]])}, "particle 1 has a non-finite"),
    ({"position": np.zeros((2, 2)), "volume": np.array([1.0, -1.0])}, "particle 1 has the "
                                                                      "volume -1.0"),
    ({"position": np.array([["a", "b"]])}, "position has the type <U1"),
])
def test_bad_npz_files_are_refused(tmp_path, arrays, message):
    np.savez(tmp_path / "bad.npz", **arrays)
    path = _bad_file_case(tmp_path, "bad.npz", None)
    line = refused(["check", path])
    assert message in line, line


def test_read_particle_file_takes_a_1d_npz_position(tmp_path):
    np.savez(tmp_path / "line.npz", position=np.arange(5.0))
    x, volume = read_particle_file(tmp_path / "line.npz", 1)
    assert x.shape == (5, 1) and volume is None
    with pytest.raises(CaseError, match="needs \\(n, 2\\)"):
        read_particle_file(tmp_path / "line.npz", 2, where="here")


def _with_geometry(geometry: dict, dimension: int = 2, analysis: str = "none") -> dict:
    velocity = [0.0] * dimension
    return {"name": "g", "dimension": dimension, "analysis": analysis,
            "materials": {"steel": {"model": "elastic", "density": 7800.0,
                                    "youngs_modulus": 2e11}},
            "bodies": [{"name": "b", "material": "steel", "velocity": velocity,
                        "geometry": geometry}],
            "time": {"end": 1e-6}}


@pytest.mark.parametrize(("geometry", "dimension", "message"), [
    ({"type": "disk", "centre": [0.0, 0.0], "radius": -1.0, "spacing": 0.1}, 2,
     "bodies.0.geometry.radius = -1.0: Input should be greater than 0"),
    ({"type": "disk", "centre": [0.0, 0.0], "radius": 0.05, "spacing": 0.1}, 2,
     "bodies.0.geometry: radius = 0.05 holds no particle at spacing = 0.1"),
    ({"type": "disk", "centre": [0.0, 0.0, 0.0], "radius": 1.0, "spacing": 0.1}, 3,
     "bodies.0.geometry: type = 'disk' is for dimension = 2 only"),
    ({"type": "disk", "centre": [0.0], "radius": 1.0, "spacing": 0.1}, 2,
     "bodies.0.geometry.centre has 1 component; dimension = 2 needs 2"),
    ({"type": "disk", "centre": [0.0, 0.0], "radius": 1.0}, 2,
     "bodies.0.geometry.spacing: required field is missing"),
    ({"type": "disk", "centre": [0.0, 0.0], "radius": 1.0, "spacing": 0.1, "size": [1.0]}, 2,
     "bodies.0.geometry.size: unknown key"),
    ({"type": "cylinder", "centre": [0.0, 0.0], "radius": 1.0, "length": 1.0,
      "spacing": 0.1}, 2, "bodies.0.geometry: type = 'cylinder' is for dimension = 3 only"),
    ({"type": "cylinder", "centre": [0.0, 0.0, 0.0], "radius": 1.0, "length": 1.0,
      "axis": "w", "spacing": 0.1}, 3, "bodies.0.geometry.axis = 'w': Input should be 'x', "
                                       "'y' or 'z'"),
    # a key of the geometry's other types: which types have it
    ({"origin": [0.0, 0.0], "size": [1.0, 1.0], "spacing": 0.1, "radius": 1.0}, 2,
     "bodies.0.geometry.radius: unknown key; radius is a field of type = 'disk', 'cylinder' or "
     "'sphere' (this table's type is 'block')"),
    ({"type": "cone", "radius": 1.0}, 2, "bodies.0.geometry.type = 'cone': Input should "
                                         "be 'block', 'disk', 'ring', 'cylinder', 'sphere' "
                                         "or 'file'"),
    ({"type": "file", "path": "", "spacing": 0.1}, 2, "bodies.0.geometry.path = ''"),
    ({"type": "file", "path": "p.csv", "spacing": 0.0}, 2,
     "bodies.0.geometry.spacing = 0.0: Input should be greater than 0"),
])
def test_geometry_errors_name_the_field(geometry, dimension, message):
    with pytest.raises(CaseError) as info:
        validate_case(_with_geometry(geometry, dimension))
    assert str(info.value).startswith(message), str(info.value)


def test_analyses_need_lattice_geometries():
    disk = {"type": "disk", "centre": [0.0, 0.0], "radius": 1.0, "spacing": 0.1}
    validate_case(_with_geometry(disk, analysis="taylor"))  # the Taylor bar measures a disk too
    with pytest.raises(CaseError, match="bodies.0.geometry: analysis = 'bars' needs type = "
                                        "'block', not 'disk'"):
        validate_case(_with_geometry(disk, analysis="bars"))
    block = {"origin": [0.0, 0.0], "size": [1.0, 1.0], "spacing": 0.1}
    assert validate_case(_with_geometry(block)).bodies[0].geometry.type == "block"


def test_body_particles_dispatches_on_the_type():
    case = validate_case(_with_geometry(
        {"type": "disk", "centre": [1.0, 2.0], "radius": 1.0, "spacing": 0.1}))
    p = body_particles(case.bodies[0].geometry, 2)
    assert np.array_equal(p.position, disk_particles([1.0, 2.0], 1.0, 0.1).position)


def test_csv_with_a_byte_order_mark_and_upper_case_header(tmp_path):
    (tmp_path / "p.csv").write_bytes("\ufeffX, Y\n0.5,1.5\n2.5,3.5\n".encode())
    x, volume = read_particle_file(tmp_path / "p.csv", 2)
    assert x.tolist() == [[0.5, 1.5], [2.5, 3.5]] and volume is None
