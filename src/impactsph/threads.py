"""How many threads the compiled passes use, chosen while a run goes (``compute.threads``).

The passes run in many short parallel regions a step.  On a machine where another process
holds cores, OpenMP's barriers wait for a thread the operating system has descheduled, and a
run with as many threads as cores slows by 3-40 times (benchmarks/README.md, "Steady on a
shared machine").  With ``compute.threads = "auto"`` (the default) a :class:`ThreadGovernor`
samples, about once a second of wall time, how much of the machine other processes used
since the last sample: the busy time of the cores it may run on (``/proc/stat``, the CPUs of
its affinity, so that a container pinned to a few cores of a large host counts only those)
less this process's own CPU time.  It then runs the passes on the cores left,

    threads = clamp(usable - round(other), 1, most)

(``usable``: the cores this process may run on; ``most``: the count numba had when the run
started, ``NUMBA_NUM_THREADS`` unless the caller set fewer with ``numba.set_num_threads``), through
``numba.set_num_threads``, and says so in the log when the count changes.  Two runs started
side by side each settle on their share, and a run takes its threads back when the other
ends.  A fixed ``compute.threads = N`` sets N threads once and samples nothing.

On an idle machine the cores left are not always worth taking: a small run's step is many
parallel regions of a few microseconds each, and a second thread can cost more in hand-overs
than it gives (the 1D bars and plates, 202 and 400 particles, took 1.04-1.47 times as long on
two threads as on one, once 0.70 in a spell; the 2D rings and Taylor bar 0.65-0.96:
benchmarks/README.md, "Small runs: the thread count measured").  Where that lies depends on
the machine, the case and the load, so "auto" does not guess it from the particle count: it
measures it.  A
:class:`ThreadTrial` runs blocks of steps at the count the load allows (``upper``) and at half
of it (``lower``), three blocks each, alternated, each block at least :data:`BLOCK_STEPS`
steps and :data:`BLOCK_SECONDS` of wall time after one step to settle.  It compares each
count's fastest block (another process, or a spell of a shared host, only ever adds time to
a block) and picks ``lower`` only if that was :data:`MARGIN` faster.  The count drops only
when a second trial, run at once, agrees; then half of it is tried.  A trial stops after its
first two blocks where ``lower`` took 1.5 times ``upper``'s time, so that a large run pays for
a few slow steps, not for a whole trial (never early the other way).  Trials are repeated when
the load changes the count, and otherwise after :data:`SPACING` times their own duration (at
most about 2% of a run at a count that is not the best).  The choices are logged (``threads:
2 -> 1 (a step took 295 us on 1 thread against 310 us on 2 threads)``) and listed in
``summary.json``'s ``thread_trials``.  A simulation run in pieces (``sim.run(t)`` called again
and again) keeps one governor: each piece goes on at the count, and with the trials'
schedule, the last one left (:meth:`ThreadGovernor.resume`).

The results do not depend on the thread count: each particle's sums are made by one thread in
a fixed order, and the step is a minimum (``tests/test_threads.py``).  Where ``/proc/stat``
cannot be read (not Linux) "auto" keeps numba's count and only the trials choose below it.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable

log = logging.getLogger("impactsph")

#: wall seconds between two samples of the load
INTERVAL = 1.0
#: a trial's block: at least this many timed steps ...
BLOCK_STEPS = 4
#: ... and this many wall seconds
BLOCK_SECONDS = 0.01
#: a smaller count is kept only if its fastest block took this fraction less time a step
MARGIN = 0.03
#: the next trial comes this many times the last one's duration after it
SPACING = 50.0
#: a trial waits this many steps after the run's start or a change of the load's count
#: (the first steps compile or load passes and build the first lists)
SETTLE_STEPS = 3


def usable_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def busy_seconds(cpus: set[int] | None = None) -> float | None:
    """CPU seconds spent busy since boot (``/proc/stat``: every field but idle and iowait) by
    the CPUs this process may run on (``cpus``, default its affinity), so that a container
    pinned to a few cores of a large host counts only those; None where it cannot be read."""
    if cpus is None:
        try:
            cpus = os.sched_getaffinity(0)
        except AttributeError:  # not Linux
            return None
    try:
        with open("/proc/stat") as f:
            lines = [line.split() for line in f if line.startswith("cpu")]
    except OSError:
        return None
    hertz = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    busy = 0
    counted = 0
    try:
        for fields in lines:
            name = fields[0]
            if name == "cpu" or int(name[3:]) not in cpus:
                continue
            ticks = [int(v) for v in fields[1:9]]
            busy += sum(ticks) - ticks[3] - ticks[4]
            counted += 1
    except (ValueError, IndexError):
        return None
    return busy / hertz if counted else None


def own_seconds() -> float:
    """CPU seconds this process has used (all its threads)."""
    t = os.times()
    return t.user + t.system


def threads_for(other: float, usable: int, most: int) -> int:
    """The thread count for ``other`` cores held by other processes: the cores left,
    ``usable - round(other)``, within ``[1, most]``."""
    return max(1, min(most, usable - int(other + 0.5)))


def _threads(count: int) -> str:
    return f"{count} thread" + ("s" if count != 1 else "")


class ThreadTrial:
    """One comparison of the step's wall time at two thread counts (the module docstring).

    :meth:`tick` is called at the start of every step with the clock's reading; it answers
    the count the next step should run on, and sets :attr:`done` when the trial has decided
    (:attr:`chosen`).  The count changes only between blocks, and the first step of a block
    is not timed (the new count's threads wake up in it)."""

    #: which count (0: ``upper``, 1: ``lower``) each block runs
    ORDER = (0, 1, 0, 1, 0, 1)

    def __init__(self, upper: int, lower: int, now: float, *,
                 block_steps: int = BLOCK_STEPS, block_seconds: float = BLOCK_SECONDS,
                 margin: float = MARGIN) -> None:
        self.counts = (upper, lower)
        #: seconds a step in each block, per count
        self.step_seconds: tuple[list[float], list[float]] = ([], [])
        self.started = now
        self.block_steps, self.block_seconds, self.margin = block_steps, block_seconds, margin
        self.done = False
        self.chosen = upper
        self._block = 0
        self._steps = -1  # the block's first step is not timed
        self._since = now

    @property
    def count(self) -> int:
        """The count the trial runs now."""
        return self.chosen if self.done else self.counts[self.ORDER[self._block]]

    def best(self) -> tuple[float, float]:
        """The shortest step time of each count's blocks so far (NaN for none): what
        another process takes from a block only adds to its time."""
        return tuple(min(t) if t else float("nan")  # type: ignore[return-value]
                     for t in self.step_seconds)

    def tick(self, now: float) -> int:
        """A step starts at ``now``: the count it runs on."""
        if self.done:
            return self.chosen
        self._steps += 1
        if self._steps == 0:
            self._since = now
            return self.count
        if self._steps < self.block_steps or now - self._since < self.block_seconds:
            return self.count
        self.step_seconds[self.ORDER[self._block]].append((now - self._since) / self._steps)
        self._block += 1
        self._steps = -1
        upper, lower = self.best()
        if self._block == 2 and lower > 1.5 * upper:
            self._decide(upper, lower)  # clear after one block each
        elif self._block == len(self.ORDER):
            self._decide(upper, lower)
        return self.count

    def restart_block(self) -> None:
        """Begin the current block again (its steps so far are not counted)."""
        self._steps = -1

    def _decide(self, upper: float, lower: float) -> None:
        self.done = True
        self.chosen = self.counts[1] if lower < (1.0 - self.margin) * upper else self.counts[0]


class ThreadGovernor:
    """Chooses the passes' thread count while a run goes (see the module docstring).

    ``tick()`` is called once a step; it costs one clock read and a few comparisons except
    about once every :data:`INTERVAL` seconds, when it samples the load and may change the
    count, and during a :class:`ThreadTrial`.  ``tune=False`` runs no trials (the passes are
    serial, or the step runs on a GPU)."""

    def __init__(self, setting: int | str = "auto", *, interval: float = INTERVAL,
                 set_threads: Callable[[int], None] | None = None,
                 get_threads: Callable[[], int] | None = None,
                 busy: Callable[[], float | None] = busy_seconds,
                 own: Callable[[], float] = own_seconds,
                 clock: Callable[[], float] = time.monotonic,
                 usable: int | None = None, tune: bool = True,
                 block_steps: int | None = None, block_seconds: float | None = None) -> None:
        import numba

        self._set = set_threads or numba.set_num_threads
        self._get = get_threads or numba.get_num_threads
        #: the ``compute.threads`` setting and whether trials run (:meth:`resumable`)
        self.setting, self.tune = setting, tune
        self._closed_at: float | None = None
        self._trial_started = 0.0
        self._trial_at, self._settle, self._confirming = float("inf"), 0, False
        self.usable = usable_cores() if usable is None else usable
        self.interval = interval
        self._busy, self._own, self._clock = busy, own, clock
        self.auto = setting == "auto"
        #: the thread count the passes use now
        self.threads = self._get()
        self._initial = self.threads
        #: the most threads "auto" gives the passes: the count at the start
        self.most = self.threads
        #: the count the load allows ("auto"; the trials choose at most this)
        self.cap = self.threads
        #: (wall seconds into the run, other processes' cores, new count) at each change the
        #: load made (the seconds of the runs so far, where :meth:`resume` went on)
        self.changes: list[tuple[float, float, int]] = []
        #: each finished trial: wall seconds into the run at its start and its end, the two
        #: counts, their fastest blocks' seconds a step, the count chosen
        self.trials: list[dict[str, object]] = []
        self._start = clock()
        self._trial: ThreadTrial | None = None
        self._steady = self.threads  # the count outside the trials
        self._block = (BLOCK_STEPS if block_steps is None else block_steps,
                       BLOCK_SECONDS if block_seconds is None else block_seconds)
        if not self.auto:
            most = int(numba.config.NUMBA_NUM_THREADS)
            if int(setting) > most:
                log.info("threads: compute.threads = %d, but numba has %d (NUMBA_NUM_THREADS): "
                         "running on %d", int(setting), most, most)
            self._apply(min(int(setting), most), other=float("nan"))
            self._next = float("inf")
            self._tuning = False
            return
        self._tuning = tune
        self._schedule(self._start, settle=True)
        self._last = (clock(), busy(), own())
        if self._last[1] is None:  # nothing to measure the load with: keep numba's count
            self._next = float("inf")
            return
        self._next = self._last[0] + interval

    def _apply(self, threads: int, other: float) -> None:
        if threads == self.threads and not self.auto:
            return
        if self.auto:
            log.info("threads: %d -> %d (other processes used %.2g of %d cores)",
                     self.threads, threads, other, self.usable)
        else:
            log.info("threads: %d (compute.threads)", threads)
        self.changes.append((self._clock() - self._start, other, threads))
        self._use(threads)
        self._steady = threads

    def _use(self, threads: int) -> None:
        if threads != self.threads:
            self._set(threads)
            self.threads = threads

    def _schedule(self, at: float, settle: bool = False) -> None:
        """The next trial: after :data:`SETTLE_STEPS` steps (``settle``) or at ``at``."""
        self._trial = None
        self._confirming = False
        self._trial_at = at
        self._settle = SETTLE_STEPS if settle else 0

    def _tune(self, now: float) -> None:
        trial = self._trial
        if trial is None:
            if self._settle > 0:
                self._settle -= 1
                return
            if now < self._trial_at or self.cap <= 1:
                return
            trial = self._trial = self._new_trial(self.cap, self.cap // 2, now)
            self._trial_started = now
        count = trial.tick(now)
        if not trial.done:
            self._use(count)
            return
        upper, lower = trial.best()
        self.trials.append({"start": trial.started - self._start, "end": now - self._start,
                            "threads": list(trial.counts), "step_seconds": [upper, lower],
                            "chosen": trial.chosen})
        if trial.chosen != self._steady and (self._confirming or trial.chosen != trial.counts[1]):
            log.info("threads: %d -> %d (a step took %.3g us on %s against %.3g us on %s)",
                     self._steady, trial.chosen, 1e6 * lower, _threads(trial.counts[1]),
                     1e6 * upper, _threads(trial.counts[0]))
        upper_count, lower_count = trial.counts
        if trial.chosen == lower_count and not self._confirming:  # once more, to be sure
            self._confirming = True
            self._trial = self._new_trial(upper_count, lower_count, now)
            return
        self._confirming = False
        self._use(trial.chosen)
        self._steady = trial.chosen
        if trial.chosen == lower_count and lower_count > 1:  # half again
            self._trial = self._new_trial(lower_count, lower_count // 2, now)
            return
        self._schedule(now + SPACING * (now - self._trial_started))

    def _new_trial(self, upper: int, lower: int, now: float) -> ThreadTrial:
        return ThreadTrial(upper, lower, now, block_steps=self._block[0],
                           block_seconds=self._block[1])

    def tick(self) -> None:
        """Run the trials; sample the load and set the thread count, if :data:`INTERVAL`
        has passed."""
        now = self._clock()
        if self._tuning:
            self._tune(now)
        if now < self._next:
            return
        busy, own = self._busy(), self._own()
        t0, busy0, own0 = self._last
        self._last = (now, busy, own)
        self._next = now + self.interval
        if busy is None or busy0 is None or now <= t0:
            return
        other = max(0.0, ((busy - busy0) - (own - own0)) / (now - t0))
        cap = threads_for(other, self.usable, self.most)
        if cap != self.cap:
            self.cap = cap
            self._apply(cap, other)
            if self._tuning:
                self._schedule(now, settle=True)

    def close(self) -> None:
        """Give back the thread count the run started with (the calling thread's).  A later
        :meth:`resume` (the simulation's next ``run`` call) takes up the count, the trial and
        the schedule where they were."""
        self._held = self.threads
        self._closed_at = self._clock()
        if self.threads != self._initial:
            self._set(self._initial)
            self.threads = self._initial

    def resumable(self, setting: int | str, tune: bool) -> bool:
        """Whether :meth:`resume` may go on for a run of ``setting`` and ``tune``: the same
        ones, after :meth:`close`, with numba's count what it was at the start."""
        return (self._closed_at is not None and setting == self.setting and tune == self.tune
                and self._get() == self._initial)

    def resume(self) -> None:
        """Go on after :meth:`close`: the count it held, a trial in progress with its block
        begun again, the load sampled afresh; the time between the two is no run's (it is
        left out of the times in :attr:`changes` and :attr:`trials`, and of the trials')."""
        now = self._clock()
        gap = now - self._closed_at
        self._closed_at = None
        self._start += gap
        self._trial_at += gap
        self._trial_started += gap
        if self._trial is not None:
            self._trial.started += gap
            self._trial.restart_block()
        self._use(self._held)
        if self._next != float("inf"):
            self._last = (now, self._busy(), self._own())
            self._next = now + self.interval
