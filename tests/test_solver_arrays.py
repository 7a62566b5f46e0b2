"""What the solver hands the rate passes as each particle's carried state
(``Solver._arrays``): without ghosts and without a viscosity switch, the material state itself
(no copy: 56 bytes a particle and a copy an evaluation saved); with a switch, a copy that adds
the switch's factor and memory.  Either way the passes read the same numbers, so the rates are
the same to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import load_case
from impactsph.models.columns import CARRIED, VISCOSITY_FACTOR, VISCOSITY_MEMORY
from impactsph.simulation import Simulation

CARRIED_ARRAY = 9  # its place in the tuple (x, v, rho, e, S, m, h, material, body, carried)


def _rates(sim):
    return [np.array(r[: sim.state.n]) for r in sim.solver.rates(sim.state)[:4]]


def test_without_ghosts_or_a_switch_the_passes_read_the_material_state_in_place():
    sim = Simulation(load_case("cantilever"))
    sim.run(2e-6)  # a plastic strain, a stress: state worth reading
    assert sim.solver._ext is None and not sim.solver.switched
    carried = sim.solver._arrays(sim.state)[CARRIED_ARRAY]
    assert carried is sim.state.material_state and sim.solver._carried is None
    in_place = _rates(sim)
    # the same state with its material state in Fortran order: the solver copies it
    sim.state.material_state = np.asfortranarray(sim.state.material_state)
    copied = sim.solver._arrays(sim.state)[CARRIED_ARRAY]
    assert copied is sim.solver._carried and copied.flags.c_contiguous
    np.testing.assert_array_equal(copied[:, :CARRIED], sim.state.material_state[:, :CARRIED])
    for a, b in zip(in_place, _rates(sim), strict=True):
        assert a.tobytes() == b.tobytes()


def test_a_switch_gets_a_copy_with_its_factor_and_memory():
    sim = Simulation(load_case("cantilever", ['viscosity.scheme="balsara"']))
    sim.run(2e-6)
    assert sim.solver.switched
    carried = sim.solver._arrays(sim.state)[CARRIED_ARRAY]
    assert carried is sim.solver._carried
    np.testing.assert_array_equal(carried[:, :CARRIED], sim.state.material_state[:, :CARRIED])
    np.testing.assert_array_equal(carried[:, VISCOSITY_FACTOR], sim.state.viscosity_factor)
    np.testing.assert_array_equal(carried[:, VISCOSITY_MEMORY], sim.state.viscosity_memory)


@pytest.mark.parametrize("scheme", ["av", "balsara"])
def test_passes_compiled_for_the_other_answer_to_a_switch_are_refused(scheme):
    """Passes compiled for a switch read the factor and memory from columns 5 and 6 of
    ``carried``, which without a switch are the material state's own; passes without it have
    no switch pass.  Either mismatch is refused (``ViscositySettings.check_compiled``, which
    the GPU backends call too), not run."""
    from impactsph.physics.options import PassOptions
    from impactsph.physics.rates import CpuRates

    sim = Simulation(load_case("cantilever", [f'viscosity.scheme="{scheme}"']))
    switched = sim.solver.switched
    sim.solver.backend = CpuRates(sim.state.dim, PassOptions(viscosity_factor=not switched))
    with pytest.raises(ValueError, match=f"viscosity_factor={switched}"):
        sim.solver.rates(sim.state)


def test_without_a_switch_the_factor_and_memory_are_one_number(tmp_path):
    """A run without a viscosity switch holds the factor (1) and the memory (0), which no pass
    reads, as read-only views of one number (16 B a particle less); its checkpoint keeps them
    and continues; a run with a switch that continues from such a state gets arrays it can
    write."""
    from impactsph.checkpoint import load_checkpoint, write_checkpoint

    sim = Simulation(load_case("bars", ["output.figures=false", "time.end=4e-6"]))
    s = sim.state
    for name, value in (("viscosity_factor", 1.0), ("viscosity_memory", 0.0)):
        field = getattr(s, name)
        assert field.shape == (s.n,) and field.strides == (0,) and not field.flags.writeable
        assert np.all(field == value)
    with pytest.raises(ValueError, match="read-only"):
        s.viscosity_factor[0] = 2.0
    sim.run(t_end=2e-6)
    again = load_checkpoint(write_checkpoint(sim, tmp_path / "c.h5"), sim.case)
    assert again.state.viscosity_factor.strides == (0,)
    again.run()
    sim.run()
    np.testing.assert_array_equal(again.state.position, sim.state.position)
    switched = Simulation(load_case("bars", ['viscosity.scheme="balsara"',
                                             "output.figures=false", "time.end=4e-6"]),
                          state=sim.state)
    assert switched.state.viscosity_factor.flags.writeable
    assert switched.state.viscosity_memory.flags.writeable
    switched.run(t_end=5e-6)
    assert np.all(np.isfinite(switched.state.viscosity_factor))
