"""2D axisymmetry (``two_dimensional = "axisymmetric"``, issue 14): x is the radius r, y the
axis z, masses and energies per radian (docs/modelling.md, "Axisymmetry").

- A uniform radial expansion ``v_r = a r`` of an elastic cylinder, infinite along z
  (symmetry planes), is homogeneous away from its free surface: the particles keep their
  velocities and the density and stresses follow the exact solution, next to the axis too.
- A rod hitting a frictionless rigid plane (its mirror) carries the bar wave at
  ``c_0 = sqrt(E / rho)``: the momentum it has lost, over ``rho A V``, is ``c_0 t``.
- The Taylor bar in axisymmetry has the length of the 3D cylinder at the same spacing
  (``tests/test_taylor3d.py`` runs the cylinder; the full-length runs at two resolutions are in
  docs/validation.md).
- Bad input is refused with exit code 2 and one line.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph import Simulation
from impactsph.cli import app
from impactsph.loading import validate_case

E, NU, RHO = 200e9, 0.3, 7850.0
K = E / (3.0 * (1.0 - 2.0 * NU))
MU = E / (2.0 * (1.0 + NU))
C_L = math.sqrt((K + 4.0 * MU / 3.0) / RHO)  # the P-wave speed
STEEL = {"model": "elastic", "density": RHO, "youngs_modulus": E, "poisson_ratio": NU,
         "eos": "linear"}


def axisymmetric_case(size: list[float], spacing: float, velocity: list, boundaries: list,
                      t_end: float, **extra) -> dict:
    return {"name": "axi", "dimension": 2, "two_dimensional": "axisymmetric",
            "materials": {"steel": STEEL},
            "bodies": [{"name": "c", "material": "steel", "velocity": velocity,
                        "geometry": {"origin": [0.0, 0.0], "size": size,
                                     "spacing": spacing}}],
            "boundaries": boundaries, "kernel": {"h_over_dx": 1.2},
            "viscosity": {"scheme": "av"}, "time": {"end": t_end},
            "output": {"figures": False}, **extra}


def expansion(n_radius: int) -> tuple[Simulation, float, float]:
    """An elastic cylinder of radius R, ``n_radius`` particles across it, eight layers between
    two symmetry planes, started at ``v_r = a r``, run for the time a P wave takes to cross
    six spacings."""
    R, a = 0.01, 1000.0
    dx = R / n_radius
    t_end = 6.0 * dx / C_L
    planes = [{"type": "symmetry", "point": [0.0, 0.0], "normal": [0.0, 1.0]},
              {"type": "symmetry", "point": [0.0, 8 * dx], "normal": [0.0, -1.0]}]
    sim = Simulation(validate_case(axisymmetric_case(
        [R, 8 * dx], dx, [f"{a} * x", 0.0], planes, t_end)))
    sim.run()
    return sim, a, t_end


@pytest.mark.parametrize("n_radius", [32, 64])
def test_uniform_radial_expansion_is_exact_away_from_the_surface(n_radius):
    """Exact solution (x = r): every particle keeps ``v_r = a r_0``, so ``r = r_0 (1 + a t)``,
    ``rho = rho_0 / (1 + a t)^2``, ``P = K (rho / rho_0 - 1)`` (linear EOS) and the
    deviator of the Jaumann-rate elasticity with ``D_rr = D_tt = a / (1 + a t)``:
    ``S_rr = S_tt = 2 mu ln(1 + a t) / 3``, ``S_zz = -2 S_rr``.  The release from the free
    surface at r = R has travelled 6 spacings; particles more than 6 spacings plus three
    supports inside it are held to the exact kinematics and deviator (measured: 1e-11 of
    them, the first row next to the axis included), at both resolutions."""
    sim, a, t = expansion(n_radius)
    s = sim.state
    R = 0.01
    dx = R / n_radius
    r0 = s.initial_position[:, 0]
    deep = r0 < R - 12.0 * dx - 3.0 * 2.4 * dx  # twice the wave's way: its precursor
    assert deep.sum() >= 8 * (n_radius // 3)  # a third of the radius at least
    assert r0[deep].min() < dx  # the row next to the axis is among them
    at = a * t
    assert np.abs(s.velocity[deep, 0] - a * r0[deep]).max() < 1e-9 * a * R
    assert np.abs(s.velocity[deep, 1]).max() < 1e-9 * a * R
    assert np.abs(s.position[deep, 0] - r0[deep] * (1 + at)).max() < 1e-9 * dx
    # the density: uniform, and within 1% of its exact change (measured 0.46%: the continuity
    # equation's plain SPH divergence of the r-z velocity, whose kernel moment on this lattice
    # is 0.991, as in plane strain; the velocity gradient's correction does not reach it)
    rho = s.material_density[deep]
    rho_exact = RHO / (1 + at) ** 2
    assert np.ptp(rho) < 1e-9 * RHO
    assert np.abs(rho - rho_exact).max() < 0.01 * (RHO - rho_exact)
    S = s.deviatoric_stress[deep]
    s_rr = 2.0 * MU * math.log(1 + at) / 3.0
    for (i, j), exact in {(0, 0): s_rr, (2, 2): s_rr, (1, 1): -2.0 * s_rr,
                          (0, 1): 0.0}.items():
        assert np.abs(S[:, i, j] - exact).max() < 1e-6 * s_rr, (i, j)
    assert abs(sim.summary()["total_energy_relative_error"]) < 1e-3


def rod_front(n_radius: int) -> float:
    """A steel rod (radius R, length 20 R) moving at 1 m/s onto the symmetry plane z = 0 (a
    frictionless rigid wall), run for the time a bar wave takes to travel 10 R: the
    momentum-equivalent front ``sum over particles of m (v_z + V) / (rho_0 A V)`` (the length
    brought to rest if the rest moved on at V) over ``c_0 t``."""
    R, V = 0.003, 1.0
    dx = R / n_radius
    c0 = math.sqrt(E / RHO)
    t_end = 10.0 * R / c0
    plane = [{"type": "symmetry", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]
    sim = Simulation(validate_case(axisymmetric_case([R, 20 * R], dx, [0.0, -V], plane,
                                                     t_end)))
    sim.run()
    s = sim.state
    assert abs(sim.summary()["total_energy_relative_error"]) < 2e-4
    per_area = RHO * R * R / 2.0  # rho_0 A per radian: the mass per radian and length
    stopped = float(np.sum(s.mass * (s.velocity[:, 1] + V))) / (per_area * V)
    return stopped / (c0 * t_end)


def test_rod_carries_the_bar_wave_speed():
    """The front over ``c_0 t``: measured 0.966, 0.981 and 0.989 with 6, 12 and 24 particles
    across the radius (the error falling about as dx^0.8; plane strain carries its own plate
    speed instead).  Held within 4% at 6 and 2% at 12, the error falling."""
    coarse, fine = rod_front(6), rod_front(12)
    assert abs(coarse - 1.0) < 0.04
    assert abs(fine - 1.0) < 0.02
    assert abs(fine - 1.0) < abs(coarse - 1.0)


ROD = """
name = "rod"
dimension = 2
two_dimensional = "axisymmetric"
[materials.steel]
model = "elastic"
density = 7850.0
youngs_modulus = 200e9
poisson_ratio = 0.3
eos = "linear"
[[bodies]]
name = "rod"
material = "steel"
velocity = [0.0, -1.0]
[bodies.geometry]
origin = [@ORIGIN@, 0.0]
size = [0.003, 0.01]
spacing = 0.001
[time]
end = 1e-6
"""

BAD = {
    "a particle on the axis": ("", "-0.001",
                               "x is the radius, > 0"),
    "a symmetry plane off the axis": (
        '[[boundaries]]\ntype = "symmetry"\npoint = [0.002, 0.0]\nnormal = [1.0, 0.0]\n', "0.0",
        "boundaries.0: in axisymmetry a symmetry plane across r is the axis only"),
    "a wall parallel to the axis": (
        '[[boundaries]]\ntype = "wall"\npoint = [0.004, 0.0]\nnormal = [-1.0, 0.0]\n', "0.0",
        "boundaries.0: in axisymmetry a wall is normal to the axis"),
    "corrected forces": ('[stabilisation]\ngradient_correction = '
                         '"velocity_gradient_and_forces"\n', "0.0",
                         "stabilisation.gradient_correction = 'velocity_gradient_and_forces' "
                         "is not available"),
    "hourglass control": ("[stabilisation]\nhourglass = 1.0\n", "0.0",
                          "stabilisation.hourglass = 1.0 is not available"),
    "friction between bodies": ("[contact]\nfriction = 0.2\n", "0.0",
                                "contact.friction = 0.2 (between bodies) is not available"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_axisymmetric_input_is_refused_with_one_line(name, tmp_path):
    extra, origin, message = BAD[name]
    path = tmp_path / "rod.toml"
    path.write_text(ROD.replace("@ORIGIN@", origin) + extra)
    res = CliRunner().invoke(app, ["check", str(path)])
    assert res.exit_code == 2, res.output
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], res.output


def test_axisymmetric_defaults_leave_out_what_is_not_available():
    """'auto' stabilisation of an elastic body: the velocity-gradient correction only."""
    case = validate_case(axisymmetric_case([0.003, 0.01], 0.001, [0.0, -1.0], [], 1e-6))
    assert case.stabilisation.gradient_correction == "velocity_gradient"
    assert case.stabilisation.hourglass == 0.0
    axis = [b for b in case.boundaries if b.type == "symmetry"]
    assert len(axis) == 1 and list(axis[0].normal) == [1.0, 0.0]


def test_the_set_ups_log_lines_are_in_the_run_log(tmp_path):
    """The device's warning comes while the run is set up, before its run.log is open: the
    run directory's log holds it too, first, once; so does a restart's warning about its
    checkpoint, logged before the directory is taken."""
    import h5py

    from impactsph.runner import run_case

    # (the compatible energy update with the state on the host runs on the CPU only: a
    # warning on any machine)
    spec = axisymmetric_case([0.003, 0.01], 0.001, [0.0, -1.0], [], 2e-8,
                             compute={"device": "gpu", "resident": False})
    spec["time"]["energy_update"] = "compatible"
    case = validate_case(spec)
    out = tmp_path / "run"
    run_case(case, out, figures=False)
    lines = (out / "run.log").read_text().splitlines()
    warned = [n for n, line in enumerate(lines) if "WARNING impactsph.devices: compute.device "
              "= 'gpu' but time.energy_update = 'compatible'" in line]
    assert warned == [0], lines[:3]
    # a checkpoint of an older version (no checksum): told on restart, and in run.log
    from impactsph.checkpoint import write_checkpoint
    sim = Simulation(case)
    sim.run(t_end=1e-8)
    path = write_checkpoint(sim, tmp_path / "old.h5")
    with h5py.File(path, "a") as f:
        del f.attrs["sha256"]
    again = tmp_path / "again"
    run_case(case, again, figures=False, restart=path)
    lines = (again / "run.log").read_text().splitlines()
    assert "read unverified" in lines[0] and "WARNING" in lines[0]
    assert sum("read unverified" in line for line in lines) == 1
    assert any("compute.device = 'gpu' but" in line for line in lines[1:3])


def test_gpu_device_runs_axisymmetry_on_the_gpu():
    """Axisymmetry (whose axis is a symmetry plane) runs on the GPU since 2026-12-07 (its
    whole step there: ``tests/test_gpu_step.py``'s axisymmetric bar); what still runs on the
    CPU only is told before any work, on any machine."""
    from impactsph.simulation import _cpu_only

    case = validate_case(axisymmetric_case([0.003, 0.01], 0.001, [0.0, -1.0], [], 1e-6,
                                           compute={"device": "gpu"}))
    assert _cpu_only(case) is None
    spec = axisymmetric_case([0.003, 0.01], 0.001, [0.0, -1.0], [], 1e-6,
                             compute={"device": "gpu", "resident": False})
    spec["time"]["energy_update"] = "compatible"
    assert _cpu_only(validate_case(spec)).startswith(
        "time.energy_update = 'compatible' with compute.resident = false runs on the CPU only")
