"""The thread count chosen while a run goes (``compute.threads``; :mod:`impactsph.threads`).

The governor's decisions are checked against a scripted clock and load, so these tests do not
depend on what else the machine is doing; the results' independence of the thread count is
checked on the Taylor bar, in a process of its own with two numba threads."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from impactsph.loading import validate_case
from impactsph.threads import ThreadGovernor, busy_seconds, threads_for


@pytest.mark.parametrize(("other", "usable", "most", "expected"), [
    (0.0, 2, 2, 2), (0.3, 2, 2, 2), (0.7, 2, 2, 1), (1.0, 2, 2, 1), (2.0, 2, 2, 1),
    (5.0, 2, 2, 1), (0.0, 4, 2, 2), (1.2, 4, 4, 3), (0.0, 8, 8, 8)])
def test_threads_for_the_cores_left(other, usable, most, expected):
    assert threads_for(other, usable, most) == expected


class Machine:
    """A scripted machine: a clock, the busy seconds of all cores and this process's own."""

    def __init__(self):
        self.now = 0.0
        self.busy = 0.0
        self.own = 0.0
        self.calls: list[int] = []

    def advance(self, seconds: float, own_cores: float, other_cores: float) -> None:
        self.now += seconds
        self.own += seconds * own_cores
        self.busy += seconds * (own_cores + other_cores)

    def governor(self, setting="auto", busy=None) -> ThreadGovernor:
        return ThreadGovernor(setting, interval=1.0, set_threads=self.calls.append,
                              get_threads=lambda: 2, busy=busy or (lambda: self.busy),
                              own=lambda: self.own, clock=lambda: self.now, usable=2)


def test_the_governor_yields_a_core_and_takes_it_back(monkeypatch):
    """Another process takes a core from 3 s to 8 s: the run drops to one thread at the first
    sample after it started and goes back to two within the first whole second of samples
    after it ended (a sample that straddles the end sees part of the load); samples are taken
    once a second, not at every tick."""
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = m.governor()
    for second in range(12):
        other = 1.0 if 3 <= second < 8 else 0.0
        for _ in range(10):  # ten steps a second
            m.advance(0.1, own_cores=g.threads, other_cores=other)
            g.tick()
    assert m.calls == [1, 2]
    assert [c[2] for c in g.changes] == [1, 2]
    assert g.changes[0][0] == pytest.approx(4.0, abs=0.15)
    assert g.changes[0][1] == pytest.approx(1.0, abs=0.1)
    assert 8.0 < g.changes[1][0] < 10.0
    assert g.changes[1][1] == pytest.approx(0.0, abs=0.1)
    g.close()
    assert g.threads == 2 and m.calls == [1, 2]


def test_the_governor_gives_back_the_starting_count(monkeypatch):
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = m.governor()
    m.advance(1.5, own_cores=2, other_cores=2)
    g.tick()
    assert g.threads == 1
    g.close()
    assert m.calls == [1, 2] and g.threads == 2


def test_a_fixed_count_is_set_once_and_capped(monkeypatch):
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = m.governor(setting=1)
    m.advance(5.0, own_cores=1, other_cores=0)
    g.tick()
    assert m.calls == [1] and not g.auto
    m2 = Machine()
    assert m2.governor(setting=8).threads == 2 and m2.calls == []  # capped at numba's count


def test_without_a_load_reading_auto_keeps_numbas_count(monkeypatch):
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = m.governor(busy=lambda: None)
    m.advance(5.0, own_cores=2, other_cores=2)
    g.tick()
    assert m.calls == [] and not g.auto


def test_busy_seconds_reads_the_machine():
    busy = busy_seconds()
    if busy is None:
        pytest.skip("no /proc/stat here")
    assert busy > 0.0


def test_threads_setting_is_checked():
    base = {"name": "t", "dimension": 1,
            "materials": {"m": {"model": "elastic", "density": 1.0, "youngs_modulus": 1.0}},
            "bodies": [{"name": "b", "material": "m", "velocity": [0.0],
                        "geometry": {"origin": [0.0], "size": [1.0], "spacing": 0.1}}],
            "time": {"end": 1.0}}
    assert validate_case({**base, "compute": {"threads": 3}}).compute.threads == 3
    assert validate_case(base).compute.threads == "auto"
    for bad in (0, -1, "all"):
        with pytest.raises(ValueError, match="threads"):
            validate_case({**base, "compute": {"threads": bad}})


def test_results_do_not_depend_on_the_thread_count():
    """The Taylor bar (AC, a wall) for 150 steps with one and with two threads, in a process
    with two numba threads, and with the passes compiled serial (``$IMPACTSPH_PARALLEL=0``,
    which the rest of the suite runs): positions and velocities bitwise equal."""
    script = textwrap.dedent("""
        import os
        import numpy as np
        from impactsph import Simulation, load_case
        out = []
        for n, parallel in ((1, "1"), (2, "1"), (2, "0")):
            os.environ["IMPACTSPH_PARALLEL"] = parallel
            case = load_case("taylor", ["time.max_steps=150", f"compute.threads={n}",
                                        "output.figures=false"])
            sim = Simulation(case)
            assert sim.solver.backend.options.parallel is (parallel == "1")
            sim.run()
            out.append((sim.state.position.copy(), sim.state.velocity.copy()))
        print(all(np.array_equal(a[0], out[0][0]) and np.array_equal(a[1], out[0][1])
                  for a in out[1:]))
    """)
    import os
    env = {**os.environ, "NUMBA_NUM_THREADS": "2"}
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1] == "True"


def test_auto_keeps_within_the_callers_count(monkeypatch):
    """A caller who set one thread before the run (``numba.set_num_threads(1)``) keeps one:
    "auto" never goes above the count at the start, even on an idle machine."""
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = ThreadGovernor("auto", interval=1.0, set_threads=m.calls.append,
                       get_threads=lambda: 1, busy=lambda: m.busy, own=lambda: m.own,
                       clock=lambda: m.now, usable=2)
    for _ in range(5):
        m.advance(1.0, own_cores=1, other_cores=0)
        g.tick()
    assert m.calls == [] and g.threads == 1


def test_busy_seconds_counts_only_the_given_cpus(tmp_path):
    """The load is read for the CPUs the process may run on: one CPU's busy time is at most
    the two's, and a CPU that is not there gives nothing."""
    both = busy_seconds({0, 1})
    if both is None:
        pytest.skip("no /proc/stat here")
    one = busy_seconds({0})
    assert one is not None and 0.0 < one <= both
    assert busy_seconds({100000}) is None
