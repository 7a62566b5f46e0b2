"""Initial stress from a particle file (issue 14): a strip held in uniform uniaxial compression
and released pushes its halves apart with the force the stress says (the right half's momentum
is sigma_0 H t until the release waves meet: to 8e-5 and 7e-7 at two spacings) at the speed of
1D wave theory; the set-up holds the stress exactly (the density at which the EOS gives the
pressure, the deviator); bad stresses refused with exit code 2 and one line."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph import Simulation, load_case
from impactsph.cli import app

E, NU, RHO = 200e9, 0.3, 7850.0
L, H = 0.04, 0.004
SIGMA = 100e6  # Pa, the compression along the strip
K = E / (3 * (1 - 2 * NU))

CASE = f"""
name = "released_strip"
dimension = 2
@MODE@

[materials.steel]
model = "elastic"
density = {RHO}
youngs_modulus = {E}
poisson_ratio = {NU}
eos = "linear"

[[bodies]]
name = "strip"
material = "steel"
velocity = [0.0, 0.0]
[bodies.geometry]
type = "file"
path = "strip.csv"
spacing = @DX@

[kernel]
h_over_dx = 1.3

[viscosity]
alpha1 = 0.5
alpha2 = 0.5

[time]
end = 2.6e-6

[output]
figures = false
"""


def write_strip(folder: pathlib.Path, dx: float, stress=(-SIGMA, 0.0, -NU * SIGMA, 0.0),
                columns: str = "sigma_xx,sigma_yy,sigma_zz,sigma_xy", mode: str = ""
                ) -> pathlib.Path:
    """The strip's particles with a uniform stress (plane strain: sigma_zz = nu sigma_xx
    keeps eps_zz = 0 under the uniaxial load) and its case file."""
    xs, ys = np.arange(dx / 2, L, dx), np.arange(dx / 2, H, dx)
    x, y = (a.ravel() for a in np.meshgrid(xs, ys, indexing="ij"))
    values = ",".join(repr(float(s)) for s in stress)
    lines = [f"x,y,{columns}"] + [f"{float(a)!r},{float(b)!r},{values}"
                                  for a, b in zip(x, y, strict=True)]
    (folder / "strip.csv").write_text("\n".join(lines) + "\n")
    path = folder / "strip.toml"
    path.write_text(CASE.replace("@DX@", repr(dx)).replace("@MODE@", mode))
    return path


def test_the_set_up_holds_the_file_stress(tmp_path):
    sim = Simulation(load_case(write_strip(tmp_path, 0.0005)))
    s = sim.state
    pressure = SIGMA * (1 + NU) / 3
    np.testing.assert_allclose(sim.solver.pressure(s), pressure, rtol=1e-10)
    np.testing.assert_allclose(s.density, RHO * (1 + pressure / K), rtol=1e-12)  # linear EOS
    np.testing.assert_allclose(s.mass, s.density * 0.0005**2, rtol=1e-12)
    deviator = np.diag([-SIGMA + pressure, pressure, -NU * SIGMA + pressure])
    np.testing.assert_allclose(s.deviatoric_stress, np.broadcast_to(deviator, (s.n, 3, 3)),
                               atol=1e-6)


def released(folder: pathlib.Path, dx: float) -> tuple[float, float, float]:
    """The right half's momentum over sigma_0 H t, the mean velocity of the released zone's
    outer half over sigma_0 / (rho c), and the largest speed at the middle."""
    sim = Simulation(load_case(write_strip(folder, dx)))
    sim.run()
    s = sim.state
    c = math.sqrt(E / (RHO * (1 - NU**2)))  # the long-wave speed of a plane-strain strip
    assert 0.3 < s.time * c / L < 0.45  # the release waves have not met
    x0 = s.initial_position[:, 0]
    right = x0 > L / 2
    momentum = float((s.mass[right] * s.velocity[right, 0]).sum()) / (SIGMA * H * s.time)
    zone = x0 > L - 0.5 * c * s.time
    speed = float(s.velocity[zone, 0].mean()) / (SIGMA / (RHO * c))
    assert abs(float((s.mass * s.velocity[:, 0]).sum())) < 1e-12 * SIGMA * H * s.time
    return momentum, speed, float(np.abs(s.velocity[np.abs(x0 - L / 2) < 2 * dx]).max())


def test_a_released_strip_pushes_its_halves_apart(tmp_path):
    """Until the release waves from the two ends meet, the middle is at rest and carries the
    initial stress, so the right half gains the momentum sigma_0 H t exactly; the error falls
    with the spacing (8e-5, 7e-7 measured).  The released zone moves at sigma_0 / (rho c),
    c the strip's long-wave speed, within 1.5% (measured -1.0% and -1.5%: the strip is 3.5
    widths behind the front, where its lateral inertia still slows the front)."""
    errors = []
    for dx in (0.0005, 0.00025):
        folder = tmp_path / f"dx{dx}"
        folder.mkdir()
        momentum, speed, middle = released(folder, dx)
        assert speed == pytest.approx(1.0, abs=0.025), (dx, speed)
        # at rest to 0.4% and 0.003% of the released speed (measured)
        assert middle < 0.01 * SIGMA / (RHO * math.sqrt(E / (RHO * (1 - NU**2)))), (dx, middle)
        errors.append(abs(momentum - 1.0))
    assert errors[0] < 1e-3 and errors[1] < errors[0] / 10, errors


runner = CliRunner()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"columns": "sigma_xx,sigma_yy,sigma_zz,sigma_yz"}, "has the columns"),
    ({"stress": (-SIGMA, 0.0, -NU * SIGMA, float("nan"))}, "particle 0 has a non-finite stress"),
    ({"stress": (3 * K, 3 * K, 3 * K, 0.0)}, "pressure"),
    ({"mode": 'two_dimensional = "plane_stress"'}, "in plane stress it is 0"),
])
def test_bad_initial_stress_refused(tmp_path, kwargs, message):
    result = runner.invoke(app, ["check", str(write_strip(tmp_path, 0.0005, **kwargs))])
    assert result.exit_code == 2, result.output
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and message in lines[0], result.output
