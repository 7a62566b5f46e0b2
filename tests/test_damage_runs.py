"""Damage in SPH runs: a brittle bar pulled from a clamp breaks by Grady-Kipp damage on the
model's time scale, keeps its energy, and a failed particle carries no tension.

A plane-strain basalt bar (the library's basalt: Benz & Asphaug 1999 Weibull constants, here
with the ``elastic`` strength model) 20 mm x 2 mm, its left 1 mm clamped, the rest moving
right at ``v``: a tension wave of strain ``v / c`` leaves the clamp.  Every flaw of the
particles it loads is active at that strain, so each particle's damage grows from its first
activation to 1 in between ``2h / (c_g N^(1/3))`` (all of its ``N`` flaws active) and
``2h / c_g`` (one): the test checks the first particle to break does so in that window.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.materials import TableLayout
from impactsph.models.columns import DAMAGE
from impactsph.models.damage.grady_kipp import FLAWS

CASE = """
name = "brittle_bar"
dimension = 2

[materials.rock]
library = "basalt"
model = "elastic"
eos = "linear"

[[bodies]]
name = "bar"
material = "rock"
velocity = [{speed}, 0.0]
[bodies.geometry]
origin = [0.0, 0.0]
size = [0.02, 0.002]
spacing = 0.00025
[bodies.clamped]
origin = [-0.001, -0.001]
size = [0.002, 0.004]

[kernel]
h_over_dx = 1.3

[time]
end = 4.0e-6
courant = 0.3

[output]
figures = false
snapshot_times = [4.0e-6]
"""


def run(tmp_path: Path, speed: float, damage: str = "grady_kipp"):
    text = CASE.format(speed=speed)
    if damage == "none":
        text = text.replace('model = "elastic"', 'model = "elastic"\ndamage = "none"')
    path = tmp_path / f"bar-{damage}.toml"
    path.write_text(text)
    sim = Simulation(load_case(path))
    first_damage, first_failure = [], []

    def watch(s):
        D = s.state.material_state[:, DAMAGE]
        if not first_damage and (D > 0).any():
            first_damage.append(s.state.time)
        if not first_failure and (D >= 1.0).any():
            first_failure.append(s.state.time)

    sim.run(callback=watch)
    return sim, first_damage, first_failure


def test_brittle_bar_breaks_on_the_growth_time(tmp_path):
    sim, first_damage, first_failure = run(tmp_path, speed=20.0)
    s = sim.summary()
    assert s["failure"] is None
    assert abs(s["total_energy_relative_error"]) <= 1e-3, s["total_energy_relative_error"]
    assert first_damage and first_failure, "the bar never broke"
    state = sim.state
    layout = TableLayout.registered()
    flaws = state.material_state[:, layout.damage_state + FLAWS]
    rock = sim.problem.materials[0]
    c_l = math.sqrt((rock.bulk_modulus + 4.0 / 3.0 * rock.shear_modulus) / rock.density)
    c_g = 0.4 * c_l
    h = float(state.smoothing_length[0])
    slowest = 2.0 * h / c_g  # one flaw
    fastest = slowest / flaws.max() ** (1.0 / 3.0)
    dt = max(r["dt"] for r in sim.record.history)
    grow = first_failure[0] - first_damage[0]
    assert fastest - 2 * dt <= grow <= slowest + 2 * dt, (fastest, grow, slowest)
    # the bar broke near the clamp, where the tension is: the failed particles are there
    D = state.material_state[:, DAMAGE]
    x0 = state.initial_position[:, 0]
    assert D.max() == 1.0
    assert x0[D >= 1.0].min() < 0.004
    # failed particles carry no tension and no deviatoric stress (as the forces see them)
    failed = D >= 1.0
    p = sim.solver.pressure(state)
    assert np.all(p[failed] >= 0.0)


def test_without_damage_the_bar_stays_whole(tmp_path):
    sim, first_damage, _ = run(tmp_path, speed=20.0, damage="none")
    assert not first_damage
    assert sim.state.material_state[:, DAMAGE].max() == 0.0
    assert abs(sim.summary()["total_energy_relative_error"]) <= 1e-3


@pytest.mark.parametrize("speed", [0.5])
def test_below_the_weakest_flaw_nothing_breaks(tmp_path, speed):
    """At 0.5 m/s the strain ``v / c`` is below every particle's weakest flaw."""
    sim, first_damage, _ = run(tmp_path, speed=speed)
    layout = TableLayout.registered()
    weakest = sim.state.material_state[:, layout.damage_state + 1].min()
    rock = sim.problem.materials[0]
    c_l = math.sqrt((rock.bulk_modulus + 4.0 / 3.0 * rock.shear_modulus) / rock.density)
    assert speed / c_l < weakest / 2  # the set-up is below threshold, with margin
    assert not first_damage


def test_the_material_state_is_sized_to_the_models_in_use(tmp_path):
    """The material state carries the common columns, then only the blocks of the case's
    models that have a state of their own (TableLayout.state_width_of): the damaged bar its
    damage model's, the same bar without damage and the Taylor bar (plastic) the common
    five (a strength model's own block: tests/test_extension.py); a state too narrow for its
    models is refused before the kernels index past it."""
    from impactsph.models.columns import CARRIED

    layout = TableLayout.registered()
    assert layout.state_width_of(["elastic", "elastic_plastic"], ["none"]) == CARRIED
    assert layout.state_width_of(["elastic"], ["none", "grady_kipp"]) == layout.state_width
    path = tmp_path / "bar.toml"
    path.write_text(CASE.format(speed=1.0))
    damaged = Simulation(load_case(path))
    assert damaged.state.material_state.shape[1] == layout.state_width
    path.write_text(CASE.format(speed=1.0).replace('model = "elastic"',
                                                   'model = "elastic"\ndamage = "none"'))
    whole = Simulation(load_case(path))
    assert whole.state.material_state.shape[1] == CARRIED
    assert Simulation(load_case("taylor")).state.material_state.shape[1] == CARRIED
    damaged.state.material_state = np.ascontiguousarray(damaged.state.material_state[:, :CARRIED])
    full = layout.state_width
    with pytest.raises(ValueError, match=rf"material_state has shape \(\d+, {CARRIED}\); the "
                                         rf"materials' models need \(\d+, k\) with {full} <= "
                                         rf"k <= {full}"):
        damaged.run()
