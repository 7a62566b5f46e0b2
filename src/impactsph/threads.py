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

The results do not depend on the thread count: each particle's sums are made by one thread in
a fixed order, and the step is a minimum (``tests/test_threads.py``).  Where ``/proc/stat``
cannot be read (not Linux) "auto" keeps numba's count.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable

log = logging.getLogger("impactsph")

#: wall seconds between two samples of the load
INTERVAL = 1.0


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


class ThreadGovernor:
    """Chooses the passes' thread count while a run goes (see the module docstring).

    ``tick()`` is called once a step; it costs one clock read except about once every
    :data:`INTERVAL` seconds, when it samples the load and may change the count."""

    def __init__(self, setting: int | str = "auto", *, interval: float = INTERVAL,
                 set_threads: Callable[[int], None] | None = None,
                 get_threads: Callable[[], int] | None = None,
                 busy: Callable[[], float | None] = busy_seconds,
                 own: Callable[[], float] = own_seconds,
                 clock: Callable[[], float] = time.monotonic,
                 usable: int | None = None) -> None:
        import numba

        self._set = set_threads or numba.set_num_threads
        self.usable = usable_cores() if usable is None else usable
        self.interval = interval
        self._busy, self._own, self._clock = busy, own, clock
        self.auto = setting == "auto"
        #: the thread count the passes use now
        self.threads = (get_threads or numba.get_num_threads)()
        self._initial = self.threads
        #: the most threads "auto" gives the passes: the count at the start
        self.most = self.threads
        #: (wall seconds into the run, other processes' cores, new count) at each change
        self.changes: list[tuple[float, float, int]] = []
        self._start = clock()
        if not self.auto:
            self._apply(min(int(setting), int(numba.config.NUMBA_NUM_THREADS)),
                        other=float("nan"))
            self._next = float("inf")
            return
        self._last = (clock(), busy(), own())
        if self._last[1] is None:  # nothing to measure the load with: keep numba's count
            self.auto = False
            self._next = float("inf")
            return
        self._next = self._last[0] + interval

    def _apply(self, threads: int, other: float) -> None:
        if threads == self.threads:
            return
        self._set(threads)
        if self.auto:
            log.info("threads: %d -> %d (other processes used %.2g of %d cores)",
                     self.threads, threads, other, self.usable)
        else:
            log.info("threads: %d (compute.threads)", threads)
        self.changes.append((self._clock() - self._start, other, threads))
        self.threads = threads

    def tick(self) -> None:
        """Sample the load and set the thread count, if :data:`INTERVAL` has passed."""
        now = self._clock()
        if now < self._next:
            return
        busy, own = self._busy(), self._own()
        t0, busy0, own0 = self._last
        self._last = (now, busy, own)
        self._next = now + self.interval
        if busy is None or busy0 is None or now <= t0:
            return
        other = max(0.0, ((busy - busy0) - (own - own0)) / (now - t0))
        self._apply(threads_for(other, self.usable, self.most), other)

    def close(self) -> None:
        """Give back the thread count the run started with (the calling thread's)."""
        if self.threads != self._initial:
            self._set(self._initial)
            self.threads = self._initial
