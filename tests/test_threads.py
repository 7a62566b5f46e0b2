"""The thread count chosen while a run goes (``compute.threads``; :mod:`impactsph.threads`).

The governor's decisions are checked against a scripted clock and load, so these tests do not
depend on what else the machine is doing; the results' independence of the thread count is
checked on the Taylor bar, in a process of its own with two numba threads."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
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

    def governor(self, setting="auto", busy=None, tune=False, threads=2) -> ThreadGovernor:
        return ThreadGovernor(setting, interval=1.0, set_threads=self.calls.append,
                              get_threads=lambda: threads, busy=busy or (lambda: self.busy),
                              own=lambda: self.own, clock=lambda: self.now, usable=threads,
                              tune=tune)

    def run(self, g: ThreadGovernor, steps: int, seconds_on, other_cores=lambda now: 0.0):
        """``steps`` steps, each ``seconds_on(threads)`` long; the counts they ran on."""
        counts = []
        for _ in range(steps):
            g.tick()
            counts.append(g.threads)
            self.advance(seconds_on(g.threads), own_cores=g.threads,
                         other_cores=other_cores(self.now))
        return counts


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


def test_a_fixed_count_is_set_once_and_capped(monkeypatch, caplog):
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = m.governor(setting=1)
    m.advance(5.0, own_cores=1, other_cores=0)
    g.tick()
    assert m.calls == [1] and not g.auto
    m2 = Machine()
    with caplog.at_level("INFO", logger="impactsph"):
        assert m2.governor(setting=8).threads == 2 and m2.calls == []  # capped at numba's
    # ... and the log says so (the count itself does not change: no other line)
    assert [r.getMessage() for r in caplog.records] == [
        "threads: compute.threads = 8, but numba has 2 (NUMBA_NUM_THREADS): running on 2"]


def test_without_a_load_reading_auto_keeps_numbas_count(monkeypatch):
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    m = Machine()
    g = m.governor(busy=lambda: None)
    m.advance(5.0, own_cores=2, other_cores=2)
    g.tick()
    assert m.calls == [] and g.changes == []
    # the trials need no load reading: they time the steps
    g = m.governor(busy=lambda: None, tune=True)
    m.run(g, 2000, {2: 100e-6, 1: 80e-6}.__getitem__)
    assert [t["chosen"] for t in g.trials] == [1, 1] and g.changes == []


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
    """The Taylor bar (AC, a wall) for 150 steps with one and with two threads, with "auto"
    (its trials' blocks shortened to four steps, so that the count changes at least five
    times in the run), in a process with two numba threads, and with the passes compiled serial
    (``$IMPACTSPH_PARALLEL=0``, which the rest of the suite runs): positions and velocities
    bitwise equal."""
    script = textwrap.dedent("""
        import os
        import numpy as np
        import impactsph.threads
        from impactsph import Simulation, load_case
        impactsph.threads.BLOCK_SECONDS = 0.0
        out = []
        for n, parallel in ((1, "1"), (2, "1"), ("auto", "1"), (2, "0")):
            os.environ["IMPACTSPH_PARALLEL"] = parallel
            case = load_case("taylor", ["time.max_steps=150", f"compute.threads={n}",
                                        "output.figures=false"])
            sim = Simulation(case)
            assert sim.solver.backend.options.parallel is (parallel == "1")
            sim.run()
            if n == "auto":
                assert sim.record.thread_trials, "no trial ran"
                assert sim.record.thread_trials[0]["threads"] == [2, 1]
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


# -- the trials: is a smaller count faster? ------------------------------------------------

def _trial_machine(monkeypatch, cores=2):
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", cores)
    m = Machine()
    return m, m.governor(tune=True, threads=cores)


def test_a_trial_keeps_one_thread_where_it_is_faster(monkeypatch, caplog):
    """A step takes 100 us on two threads and 80 us on one (a small run, where the threads'
    hand-overs cost more than the second core gives): after the settling steps, a trial of
    six blocks and a second that confirms it, the run goes on on one thread, the trials are
    recorded and the change logged, and the next trial comes SPACING times the two trials'
    duration later."""
    import logging

    from impactsph import threads as module

    m, g = _trial_machine(monkeypatch)
    with caplog.at_level(logging.INFO, logger="impactsph"):
        counts = m.run(g, 2000, {2: 100e-6, 1: 80e-6}.__getitem__)
    assert counts[:module.SETTLE_STEPS + 1] == [2] * (module.SETTLE_STEPS + 1)
    assert len(g.trials) == 2
    for trial in g.trials:
        assert trial["threads"] == [2, 1] and trial["chosen"] == 1
        assert trial["step_seconds"] == pytest.approx([100e-6, 80e-6])
    assert counts[-1] == 1 and g.threads == 1
    # the blocks run 2 1 2 1 2 1 twice: eleven changes of the count, then it stays at 1
    changes = [k for k in range(1, len(counts)) if counts[k] != counts[k - 1]]
    assert [counts[k] for k in changes] == [1, 2] * 5 + [1]
    assert all(c == 1 for c in counts[changes[-1]:])
    assert "threads: 2 -> 1 (a step took 80 us on 1 thread against 100 us on 2 threads)" \
        in caplog.text
    assert g.changes == []  # the load changed nothing
    duration = g.trials[1]["end"] - g.trials[0]["start"]
    m.run(g, int(module.SPACING * duration / 80e-6) + 2000, {2: 100e-6, 1: 80e-6}.__getitem__)
    assert len(g.trials) == 4 and g.trials[2]["chosen"] == 1
    assert g.trials[2]["start"] == pytest.approx(g.trials[1]["end"] + module.SPACING * duration,
                                                 abs=2e-4)
    g.close()
    assert g.threads == 2 and m.calls[-1] == 2


def test_a_trial_keeps_the_threads_where_they_pay(monkeypatch):
    """A step takes 100 us on two threads and 180 us on one: the trial stops after one block
    of each (one took more than 1.5 times the other) and keeps two; one thread ran only that
    block."""
    m, g = _trial_machine(monkeypatch)
    counts = m.run(g, 1000, {2: 100e-6, 1: 180e-6}.__getitem__)
    assert [t["chosen"] for t in g.trials] == [2]
    assert counts.count(1) <= 1 + max(4, int(0.01 / 180e-6) + 1)
    assert counts[-1] == 2 and m.calls == [1, 2]


@pytest.mark.parametrize("one", [100e-6, 98.5e-6])
def test_a_trial_needs_the_margin_to_take_fewer_threads(monkeypatch, one):
    """The same step time, or 1.5% less (within MARGIN), on one thread: the run keeps two."""
    m, g = _trial_machine(monkeypatch)
    counts = m.run(g, 1000, {2: 100e-6, 1: one}.__getitem__)
    assert [t["chosen"] for t in g.trials] == [2] and counts[-1] == 2


def test_a_spell_in_one_block_does_not_decide_a_trial(monkeypatch):
    """Two threads take 100 us a step and one 140 us, but the machine is three times slower
    while the first two-thread block runs (another process, a noisy neighbour on a shared
    host), and again over most of the second: a trial that stopped early on the first two
    blocks, or compared the medians, would take one thread; each count's fastest block
    decides, so the run keeps two."""
    m, g = _trial_machine(monkeypatch)

    def seconds_on(threads):
        slow = 3.0 if 0.0004 < m.now < 0.0103 or 0.021 < m.now < 0.029 else 1.0
        return slow * {2: 100e-6, 1: 140e-6}[threads]

    m.run(g, 1500, seconds_on)
    trial = g.trials[0]
    assert trial["chosen"] == 2
    assert trial["step_seconds"] == pytest.approx([100e-6, 140e-6])


def test_a_second_trial_must_agree_before_the_count_drops(monkeypatch):
    """Two threads take 100 us a step and one 120 us, but every two-thread block of the first
    trial runs in a spell that makes them 150 us: the first trial picks one thread, the second
    does not agree, and the run keeps two."""
    m, g = _trial_machine(monkeypatch)
    spell = []

    def seconds_on(threads):
        if threads == 2 and not g.trials:
            spell.append(m.now)
            return 150e-6
        return {2: 100e-6, 1: 120e-6}[threads]

    counts = m.run(g, 2000, seconds_on)
    assert [t["chosen"] for t in g.trials] == [1, 2]
    assert spell and counts[-1] == 2 and g.threads == 2


def test_trials_halve_the_count_while_it_gets_faster(monkeypatch):
    """Four cores; a step takes 100, 70 and 90 us on 4, 2 and 1 threads: the trials go
    4 -> 2 (confirmed), then keep 2 against 1."""
    m, g = _trial_machine(monkeypatch, cores=4)
    counts = m.run(g, 4000, {4: 100e-6, 2: 70e-6, 1: 90e-6}.__getitem__)
    assert [(t["threads"], t["chosen"]) for t in g.trials] == [([4, 2], 2), ([4, 2], 2),
                                                                ([2, 1], 2)]
    assert counts[-1] == 2 and set(counts) == {1, 2, 4}


def test_the_load_ends_a_trial_and_the_trials_stay_under_its_count(monkeypatch):
    """Another process takes a core from the first milliseconds to 3 s, while the first
    trial runs: the run drops to one thread at the first sample (1 s), the trial is dropped
    unrecorded, and no trial runs while the load leaves one core; when the load goes, the run
    takes two threads back at the next samples and tries again."""
    m, g = _trial_machine(monkeypatch)
    seconds_on = {2: 0.1, 1: 0.099}.__getitem__  # a trial's blocks take 0.5 s
    counts = m.run(g, 100, seconds_on, lambda now: 1.0 if 0.01 < now < 3.0 else 0.0)
    assert [c[2] for c in g.changes] == [1, 2]
    assert 1.0 <= g.changes[0][0] < 1.2 and 3.0 < g.changes[1][0] < 4.5
    starts = np.cumsum([0.0] + [seconds_on(c) for c in counts[:-1]])
    assert 1 in counts[:10]  # the first trial had begun its second block
    assert set(counts[k] for k in range(len(counts))
               if g.changes[0][0] - 1e-9 < starts[k] < g.changes[1][0] - 1e-9) == {1}
    assert len(g.trials) == 1 and g.trials[0]["start"] >= g.changes[1][0]
    assert g.trials[0]["threads"] == [2, 1] and g.trials[0]["chosen"] == 2
    assert counts[-1] == 2


def test_no_trials_for_a_fixed_count_or_serial_passes(monkeypatch):
    m, g = _trial_machine(monkeypatch)
    g2 = m.governor(setting=2, tune=True)
    m.run(g2, 1000, {2: 100e-6, 1: 50e-6}.__getitem__)
    assert g2.trials == [] and g2.threads == 2
    g3 = m.governor(tune=False)
    m.run(g3, 1000, {2: 100e-6, 1: 50e-6}.__getitem__)
    assert g3.trials == [] and g3.threads == 2


def test_a_run_in_pieces_keeps_its_count_and_its_trials(monkeypatch):
    """A simulation run in pieces (``sim.run(t)`` again and again) resumes its governor: the
    count its trials chose holds from the next piece's first step, with no trial until the
    spacing has passed in run time (the time between the pieces not counted), and a trial
    cut by the end of a piece begins its block again, so the gap is in no block."""
    from impactsph import threads as module

    m, g = _trial_machine(monkeypatch)
    seconds_on = {2: 100e-6, 1: 80e-6}.__getitem__
    m.run(g, 2000, seconds_on)
    assert [t["chosen"] for t in g.trials] == [1, 1] and g.threads == 1
    g.close()
    assert g.threads == 2 and g.resumable("auto", True)
    assert not g.resumable(1, True) and not g.resumable("auto", False)
    m.now += 100.0  # the caller's own work between the pieces
    g.resume()
    assert g.threads == 1 and m.calls[-1] == 1
    counts = m.run(g, 500, seconds_on)
    assert set(counts) == {1} and len(g.trials) == 2
    due = g.trials[1]["end"] + module.SPACING * (g.trials[1]["end"] - g.trials[0]["start"])
    m.run(g, int(due / 80e-6) + 1000, seconds_on)
    assert len(g.trials) == 4 and g.trials[2]["start"] == pytest.approx(due, abs=2e-4)

    # a trial cut in the middle of its first one-thread block: that block begins again
    # after the gap (counted in it, the gap would make one thread look 1.5 times slower and
    # stop the trial at once, keeping two)
    m2, g2 = _trial_machine(monkeypatch)
    m2.run(g2, 150, seconds_on)
    assert g2.threads == 1 and g2._trial is not None
    g2.close()
    m2.now += 50.0
    g2.resume()
    m2.run(g2, 2000, seconds_on)
    assert [t["chosen"] for t in g2.trials] == [1, 1]
    assert g2.trials[0]["step_seconds"] == pytest.approx([100e-6, 80e-6])
    assert g2.trials[0]["end"] - g2.trials[0]["start"] < 1.0

    # a fixed count: set again for each piece, no trials
    m3 = Machine()
    g3 = m3.governor(setting=1, tune=True)
    m3.run(g3, 100, seconds_on)
    g3.close()
    assert g3.threads == 2 and g3.resumable(1, True)
    g3.resume()
    assert set(m3.run(g3, 100, seconds_on)) == {1} and g3.trials == [] and m3.calls == [1, 2, 1]


def test_a_simulation_resumes_its_governor(monkeypatch):
    """``Simulation.run`` called twice keeps one governor, and a second simulation gets its
    own; each call's record adds only the trials of that call (the governor here records
    one at the first step of each call)."""
    from impactsph import Simulation, load_case
    from impactsph import simulation as module

    made = []

    class Recording(module.ThreadGovernor):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)
            self._fresh = True

        def resume(self):
            super().resume()
            self._fresh = True

        def tick(self):
            if self._fresh:
                self.trials.append({"call": len(self.trials)})
                self._fresh = False
            super().tick()

    monkeypatch.setattr(module, "ThreadGovernor", Recording)
    sim = Simulation(load_case("bars", ["output.figures=false"]))
    sim.run(t_end=2e-6)
    sim.run(t_end=4e-6)
    assert len(made) == 1
    Simulation(load_case("bars", ["output.figures=false"])).run(t_end=1e-6)
    assert len(made) == 2
    assert sim.record.thread_trials == [{"call": 0}, {"call": 1}] == made[0].trials
