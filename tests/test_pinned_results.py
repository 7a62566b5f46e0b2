"""No result changes when the code is restructured: the summaries of the bars (AV and AC), a
shortened Taylor bar (AC and AV) and a shortened cantilever, pinned to 1e-12 relative to the
values recorded from the code before the open-core restructuring (3d5868e) by
``tests/pinned_runs.py``.

A number that measures round-off itself (the momentum drift, of the order of 1e-16) is held
to stay at round-off instead (below 1e-13), since any reordering of a sum changes its digits.
The energy balances, fractions of the initial energy that are small differences of the
run's accumulated energies (the total-energy error, the correction's imbalance, 0 in exact
arithmetic, and the budget's residual), are held to 1e-12 of that energy, the standard the
energies themselves are held to; relative to their own small size they carry the energies'
round-off magnified.

The values were re-recorded (``python tests/pinned_runs.py``) when the pair pass stopped
letting LLVM fuse multiply-adds (``FASTMATH`` in :mod:`impactsph.physics.passes`): with
fusion, passes compiled cold and the same passes served from numba's cache differed at
1e-12 relative, so the last digits of a run depended on the cache; the re-recorded values
differ from 3d5868e's by at most 3e-12 relative (the bars' AC profile oscillation, a small
difference), 5e-11 for the shortened cantilever's energy error (3e-5 of the energy).  They
were re-recorded again when the pair pass began to vectorise its neighbour sums (which
reassociates them, ``PAIR_FASTMATH``; issue 16): the new values differ from the previous ones
by at most 2.6e-11 relative (the shortened cantilever's energy error and budget residual),
1.0e-11 (the bars' AC profile oscillation) and 6e-8 for a momentum drift of 1.6e-14.  And
again (the pins' generation 1) when the pair pass's sums began to share their products
(issue 16, 2026-12-05): at most 9.3e-12 relative (the bars' AC profile oscillation) and
1.1e-12 (the shortened cantilever's correction work and heating), 3e-13 elsewhere.  And
again (generation 3, 2026-12-06, on a Zen 4 with 256-bit vectors) when the viscous push
across bodies moved out of the contact loop into a loop of its own, for the CUDA pair
kernel's registers (benchmarks/README.md, "The GPU pair kernel's registers"): the same terms
in the same order, but LLVM reassociates the contact loop's products otherwise without it;
at most 8.3e-12 relative (the bars' AC profile oscillation), 3.2e-12 (the AV bars' energy
error, 1.2e-15 of the energy), 7.7e-13 elsewhere.

The AC runs' last digits also depend on the machine (``tests/pinned_runs.py``): a CPU with a
file of its own is held to it, to the same tolerances, while its file is of the shared file's
generation; after a re-recording elsewhere its AC runs are skipped until its own file is
re-recorded on it (``tests/pinned_runs.py``)."""

from __future__ import annotations

import json

import pytest
from pinned_runs import (
    DATA,
    MACHINE_DEPENDENT,
    RUNS,
    generation,
    pinned_file,
    pinned_values,
    stale_cpu_file,
)

#: this machine's pins (its CPU's own file, if it has one: ``tests/pinned_runs.py``)
PINNED = json.loads(pinned_file().read_text())
ROUND_OFF = {"momentum_drift"}
#: fractions of the initial energy: held to 1e-12 of it
OF_THE_ENERGY = {"total_energy_relative_error", "energy_imbalance", "energy_budget_residual"}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(RUNS))
def test_results_unchanged(name):
    stale = stale_cpu_file()
    if stale is not None and name in MACHINE_DEPENDENT:
        pytest.skip(f"this CPU's pins ({stale.name}) are of generation {generation(stale)}, "
                    f"the shared ones of {generation(DATA)}: re-record them on this CPU with "
                    "python tests/pinned_runs.py --this-cpu")
    expected = PINNED[name]
    got = pinned_values(name)
    assert sorted(got) == sorted(expected), "the pinned quantities changed"
    for key, value in expected.items():
        if key in ROUND_OFF and abs(value) < 1e-13:
            assert abs(got[key]) < 1e-13, key
        elif key in OF_THE_ENERGY:
            assert abs(got[key] - value) <= 1e-12, key
        else:
            assert got[key] == pytest.approx(value, rel=1e-12, abs=1e-300), key


def test_a_cpu_file_of_another_generation_does_not_hold_its_cpu(tmp_path, monkeypatch):
    """A CPU's own pins hold it only while they are of the shared pins' generation."""
    import pinned_runs

    shared = tmp_path / "pinned_results.json"
    shared.write_text('{"generation": 2}')
    own = tmp_path / "pinned_results.testcpu.json"
    monkeypatch.setattr(pinned_runs, "DATA", shared)
    monkeypatch.setattr(pinned_runs, "host_cpu", lambda: "testcpu")
    assert pinned_runs.pinned_file() == shared and pinned_runs.stale_cpu_file() is None
    own.write_text('{"generation": 2}')
    assert pinned_runs.pinned_file() == own and pinned_runs.stale_cpu_file() is None
    for older in ('{"generation": 1}', "{}"):
        own.write_text(older)
        assert pinned_runs.pinned_file() == shared and pinned_runs.stale_cpu_file() == own
