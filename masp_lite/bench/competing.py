"""Other work on the machine, for the benchmarks: how busy it is, and a busy program to compete with.

* :func:`other_cpu_use` — how many CPUs other programs keep busy right now (from ``/proc/stat`` over a
  short sample; the one-minute load average where that file does not exist);
* :func:`busy_warning` — the line every target prints when that is enough to move its figures
  (:func:`warn_if_busy` measures and prints it);
* :func:`competing_process` — a program that keeps one CPU busy (a Python loop), started in a
  session of its own: a browser or an editor is another session, and Linux shares CPU time between
  sessions first (autogroups), so a competitor inside the benchmark's own session would only
  compete for the benchmark's share;
* :func:`pinned` — the benchmark and its competitor kept on a few CPUs (Linux), so that a
  many-core machine shows what a 2-core laptop would.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time

__all__ = ["other_cpu_use", "busy_warning", "warn_if_busy", "competing_process", "pinned", "BUSY_CPUS"]

#: Other programs' CPU use (in CPUs) from which a target warns that the machine is busy.
BUSY_CPUS = 0.3

_SPIN = "import sys\nsys.stdout.write('ready\\n')\nsys.stdout.flush()\nwhile True:\n    pass\n"


def _cpu_times() -> tuple[int, int] | None:
    """(busy, total) jiffies of all CPUs since boot, from ``/proc/stat``; None where it does not exist."""
    try:
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    total = sum(fields[:8])  # user nice system idle iowait irq softirq steal (guest time is inside user)
    return total - idle, total


def other_cpu_use(sample_s: float = 0.3) -> float | None:
    """CPUs kept busy by other programs over the next ``sample_s`` seconds (this process sleeps meanwhile).

    From ``/proc/stat`` where it exists; elsewhere the one-minute load average (which lags); None when
    neither is available."""
    before = _cpu_times()
    if before is None:
        try:
            return round(os.getloadavg()[0], 2)
        except (AttributeError, OSError):
            return None
    own = time.process_time()
    time.sleep(sample_s)
    after = _cpu_times()
    busy, total = after[0] - before[0], after[1] - before[1]
    if total <= 0:
        return None
    cpus = os.cpu_count() or 1
    own_cpus = (time.process_time() - own) / sample_s
    return round(max(0.0, busy / total * cpus - own_cpus), 2)


def busy_warning(use: float | None) -> str | None:
    """The warning to print when other programs use ``use`` CPUs (None: not busy, or not known)."""
    if use is None or use < BUSY_CPUS:
        return None
    return (f"warning: the machine is busy: other programs keep {use:.1f} of {os.cpu_count()} CPU(s) busy; "
            f"their work slows every figure below (ratios measured side by side suffer least). For the "
            f"product's own figures, run bench on an otherwise idle machine.")


def warn_if_busy() -> float | None:
    """Measure other programs' CPU use (:func:`other_cpu_use`), print :func:`busy_warning` if any; return the use."""
    use = other_cpu_use()
    if (warning := busy_warning(use)) is not None:
        print(warning)
    return use


@contextlib.contextmanager
def competing_process():
    """A process that keeps one CPU busy for the ``with`` block, in its own session; ended after it."""
    proc = subprocess.Popen([sys.executable, "-c", _SPIN], stdout=subprocess.PIPE, stdin=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        proc.stdout.readline()  # it spins from here on
        yield proc
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def _threads_of_this_process() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


@contextlib.contextmanager
def pinned(cpus: int | None):
    """Keep this process (all its threads) and the processes it starts on ``cpus`` of its CPUs, then restore.

    Yields the number of CPUs in use: ``cpus``, or all of them when ``cpus`` is None, when the machine has
    no more than that, or where CPU affinity cannot be set (not Linux)."""
    if cpus is None or not hasattr(os, "sched_setaffinity"):
        yield len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        return
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) <= cpus:
        yield len(allowed)
        return
    _set_affinity(allowed[:cpus])  # threads started later (torch's) inherit it
    try:
        yield cpus
    finally:
        _set_affinity(allowed)


def _set_affinity(cpus) -> None:
    for t in _threads_of_this_process():
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            os.sched_setaffinity(t, cpus)
