"""What every chapter's setup cell calls: seeding, threads, fast mode, showing source.

* :func:`setup` seeds Python's ``random``, NumPy and torch and sets torch's thread count,
  so a chapter prints the same numbers on every run. Its threads wait passively (importing
  :mod:`masp_lite` before torch arranges it, :mod:`masp_lite.threads`), so a browser or another
  kernel busy beside the chapter does not make them collapse; when torch was imported first,
  ``setup`` says so and how to fix it.
* :func:`fast_mode` reads the environment variable ``MASP_LITE_FAST``. Learners get full
  budgets by default (``"0"``); the test suite sets ``"1"`` so every notebook runs in
  about a minute on two cores. Chapters scale their budgets with it, e.g.
  ``episodes = 5 if FAST else 100``.
* :func:`show` displays a library object's source in the notebook, so chapters show the
  code they teach without pasting it (pasted code goes stale; imported code cannot).
"""
from __future__ import annotations

import inspect
import os
import random
import warnings

import numpy as np
import torch

from ..threads import TRAIN_THREADS, passive_wait

__all__ = ["setup", "fast_mode", "show", "FAST_ENV"]

#: Environment variable switching the course's small budgets on ("1") or off ("0").
FAST_ENV = "MASP_LITE_FAST"

_TRUE, _FALSE = {"1", "true", "yes", "on"}, {"0", "false", "no", "off", ""}


def fast_mode() -> bool:
    """True when ``MASP_LITE_FAST`` asks for small budgets (unset means full budgets).

    To run a chapter at full size from a shell: ``MASP_LITE_FAST=0 jupyter lab``; inside
    a notebook, simply set ``FAST = False`` after the setup cell.
    """
    value = os.environ.get(FAST_ENV, "0").strip().lower()
    if value in _TRUE:
        return True
    if value in _FALSE:
        return False
    raise ValueError(f"{FAST_ENV}={value!r}: expected 1 (small budgets) or 0 (full budgets)")


def setup(seed: int = 0, threads: int = TRAIN_THREADS) -> None:
    """Seed ``random``, NumPy and torch with ``seed`` and use ``threads`` torch threads.

    With more than one thread and torch's threads spinning while they wait (torch imported before
    :mod:`masp_lite`, or ``OMP_WAIT_POLICY`` set to another policy), a warning says how to avoid the
    slowdown another busy program would cause."""
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed: expected a non-negative int, got {seed!r}")
    if not isinstance(threads, (int, np.integer)) or isinstance(threads, bool) or threads < 1:
        raise ValueError(f"threads: expected a positive int, got {threads!r}")
    random.seed(int(seed))
    np.random.seed(int(seed))
    torch.manual_seed(int(seed))
    torch.set_num_threads(int(threads))
    if threads > 1 and not passive_wait():
        warnings.warn(f"torch's {threads} threads spin while they wait (torch was imported before masp_lite, or "
                      "OMP_WAIT_POLICY is not PASSIVE): with another program busy they can run many times slower. "
                      "Restart the kernel and import masp_lite before torch, or call setup(threads=1).",
                      RuntimeWarning, stacklevel=2)


def show(obj):
    """The source of a library function, class or module, as a highlighted notebook display.

    Outside IPython (plain Python) the source text itself is returned.
    """
    try:
        source = inspect.getsource(obj)
    except (TypeError, OSError) as e:
        raise ValueError(f"show: expected a library function, class or module with source, got {obj!r}") from e
    try:
        from IPython.display import Code
    except ImportError:  # pragma: no cover - IPython ships with the course requirements
        return source
    return Code(source, language="python")
