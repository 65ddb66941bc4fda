"""Torch's threads on a shared laptop: waiting passively, and how many threads each kind of work gets.

Torch computes on OpenMP threads. By default an OpenMP thread that finishes its share of an
operation *spins* (busy-waits) for the next one instead of sleeping. On a machine where another
program keeps a core busy (a browser, JupyterLab, another run) a spinning thread and the
descheduled thread it waits for fight that program for the core, and every operation waits for a
scheduler time slice: two torch threads then ran the particle world 25-50x slower than one thread
(research log, 2026-12-07). With ``OMP_WAIT_POLICY=PASSIVE`` a waiting thread sleeps at once and
gives the core back; the collapse is gone. OpenMP reads the setting once, when torch is first
imported, so it has to be in the environment before that moment:

* importing :mod:`masp_lite` sets it (``masp_lite/__init__.py``), unless the user set
  ``OMP_WAIT_POLICY`` themselves or torch is already loaded (``python -m masp_lite``, the
  ``masp-lite`` command and every chapter's ``import masp_lite.course`` all import the package
  before torch);
* :func:`passive_wait` says afterwards whether it took effect (it cannot when torch was imported
  first): :func:`masp_lite.course.setup` warns when it did not.

How many threads: one, for everything (:data:`EVALUATE_THREADS`, :data:`TRAIN_THREADS`). A second
thread buys nothing for the world's step and for one team's decision (small tensors: the threads'
hand-over costs what the split saves). For training it paid only while its threads spun: on a quiet
2-core machine a MASP iteration on ``mpe-20`` ran 0.6 per second at two spinning threads against 0.4
at one (32 worlds), but two spinning threads lose a quarter of that as soon as another program is busy,
and two passive threads are slower than one even on a quiet machine (0.3 against 0.4-0.5 per second
at 32 worlds; 0.6 against 1.1 at 8 worlds; ``bench busy --loops train --threads N``, research log,
2026-12-07). ``train --threads 2`` and ``course.setup(threads=2)`` remain for a machine with idle cores.

Nothing here imports torch, so any module may import this one before torch is loaded.
"""
from __future__ import annotations

import os
import sys

__all__ = ["WAIT_POLICY_ENV", "EVALUATE_THREADS", "TRAIN_THREADS", "passive_wait"]

#: The environment variable OpenMP (and so torch's CPU threads) reads its wait policy from.
WAIT_POLICY_ENV = "OMP_WAIT_POLICY"
#: Torch threads for evaluation and benchmarks of the world's step and of a decision: a second buys nothing.
EVALUATE_THREADS = 1
#: Torch threads for training (``train --threads``) and the chapters (``course.setup``): passive, a second costs.
TRAIN_THREADS = 1


def passive_wait() -> bool:
    """Whether torch's OpenMP threads in this process wait passively (sleep instead of spinning).

    True when ``OMP_WAIT_POLICY`` was ``PASSIVE`` (any case) when :mod:`masp_lite` was imported, before
    torch; False for another policy, and when torch was imported before :mod:`masp_lite` (the policy
    torch read then cannot be known here; the unknown counts as False)."""
    import masp_lite  # the package records the policy at its import (kept there: it must run before torch)
    policy = masp_lite._torch_wait_policy
    if policy is None and "torch" not in sys.modules:  # neither loaded torch yet: torch will read the environment
        policy = os.environ.get(WAIT_POLICY_ENV)
    return (policy or "").strip().upper() == "PASSIVE"
