"""Exercise checks: compare a learner's function with the library's on seeded inputs.

A chapter's exercise asks the learner to re-implement a short library function. Its check
cell calls :func:`check`, which

* runs the learner's function and the library's (the *reference*) on the same inputs —
  each call gets its own deep copy, so an in-place edit by one cannot leak into the other;
* compares the results structurally: tensors and arrays by shape, then values with
  ``allclose(rtol, atol)``; tuples/lists by length and item; dicts by keys and value;
  anything else with ``==``;
* prints exactly one line — ``✓ passed``, ``✗ failed: <first mismatch>`` or
  ``… not attempted yet (NotImplementedError)`` — and
* returns the function the rest of the chapter should use: the learner's when it passed,
  the reference otherwise. A wrong or skipped answer never stops the chapter.

Graded cells (nbgrader's ``grade: true`` cells) additionally call :func:`assert_passed`
(or pass ``strict=True``), which raises ``AssertionError`` unless the check passed, so
``nbgrader autograde`` awards the cell's points only for a correct function.

Why hand-written: nbgrader grades by "did the cell raise", and ``numpy.testing`` /
``torch.testing`` raise on the first difference with messages about arrays rather than
about the exercise; the learner needs a one-line verdict and a fallback instead.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import torch

__all__ = ["check", "assert_passed", "compare", "Outcome", "RESULTS"]


@dataclass(frozen=True)
class Outcome:
    """What one :func:`check` found."""

    name: str
    """The exercise name given to :func:`check`."""
    status: str
    """``"passed"``, ``"failed"`` or ``"not attempted"``."""
    message: str
    """The line :func:`check` printed."""

    @property
    def passed(self) -> bool:
        return self.status == "passed"


#: Latest outcome of every exercise checked in this session, by name.
RESULTS: dict[str, Outcome] = {}


def compare(got, expected, rtol: float = 1e-5, atol: float = 1e-6, where: str = "output") -> str | None:
    """First difference between ``got`` and ``expected`` as a sentence, or ``None``.

    >>> compare((1.0, [2, 3]), (1.0, [2, 4]))
    'output[1][1]: got 3, expected 4'
    """
    if torch.is_tensor(expected) or isinstance(expected, np.ndarray):
        return _compare_arrays(got, expected, rtol, atol, where)
    if isinstance(expected, Mapping):
        if not isinstance(got, Mapping):
            return f"{where}: got a {type(got).__name__}, expected a dict"
        missing, extra = sorted(set(expected) - set(got), key=str), sorted(set(got) - set(expected), key=str)
        if missing or extra:
            return f"{where}: keys differ (missing {missing}, unexpected {extra})"
        for key in expected:
            diff = compare(got[key], expected[key], rtol, atol, f"{where}[{key!r}]")
            if diff:
                return diff
        return None
    if isinstance(expected, (tuple, list)):
        if not isinstance(got, (tuple, list)):
            return f"{where}: got a {type(got).__name__}, expected a {type(expected).__name__}"
        if len(got) != len(expected):
            return f"{where}: got {len(got)} items, expected {len(expected)}"
        for i, (g, e) in enumerate(zip(got, expected)):
            diff = compare(g, e, rtol, atol, f"{where}[{i}]")
            if diff:
                return diff
        return None
    if isinstance(expected, (int, float, np.integer, np.floating)) and not isinstance(expected, (bool, np.bool_)):
        if torch.is_tensor(got) and got.numel() == 1:
            got = float(got.item())
        elif isinstance(got, np.ndarray) and got.size == 1:
            got = float(got.item())
        if not isinstance(got, (int, float, np.integer, np.floating)) or isinstance(got, bool):
            return f"{where}: got a {type(got).__name__}, expected a number"
        if math.isnan(expected) and math.isnan(got):
            return None
        if not math.isclose(got, expected, rel_tol=rtol, abs_tol=atol):
            return f"{where}: got {got:.6g}, expected {expected:.6g}"
        return None
    try:
        same = bool(got == expected)
    except (TypeError, ValueError, RuntimeError):  # e.g. an array compared with a string
        same = False
    return None if same else f"{where}: got {got!r}, expected {expected!r}"


def _compare_arrays(got, expected, rtol, atol, where):
    if not (torch.is_tensor(got) or isinstance(got, np.ndarray)):
        kind = "tensor" if torch.is_tensor(expected) else "numpy array"
        return f"{where}: got a {type(got).__name__}, expected a {kind} of shape {tuple(expected.shape)}"
    g = got.detach().cpu().numpy() if torch.is_tensor(got) else np.asarray(got)
    e = expected.detach().cpu().numpy() if torch.is_tensor(expected) else np.asarray(expected)
    if g.shape != e.shape:
        return f"{where}: got shape {tuple(g.shape)}, expected {tuple(e.shape)}"
    if e.dtype == bool or g.dtype == bool:
        bad = g != e
    elif np.issubdtype(e.dtype, np.number) and np.issubdtype(g.dtype, np.number):
        bad = ~np.isclose(g.astype(np.float64), e.astype(np.float64), rtol=rtol, atol=atol, equal_nan=True)
    else:
        return f"{where}: got dtype {g.dtype}, expected {e.dtype}"
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        at = f"{where}[{', '.join(map(str, idx))}]" if idx else where
        return (f"{at}: got {g[idx].item()!r}, expected {e[idx].item()!r} "
                f"({int(bad.sum())} of {bad.size} entries differ)")
    return None


def _cases(inputs, seeds):
    if callable(inputs):
        return [inputs(seed) for seed in seeds]
    if isinstance(inputs, (str, bytes)) or not isinstance(inputs, Sequence) or len(inputs) == 0:
        raise ValueError("inputs: expected a non-empty list of cases (a tuple of arguments, a dict of "
                         f"keyword arguments, or one argument each) or a function seed -> case, got {inputs!r}")
    return list(inputs)


def _call(fn, case):
    case = copy.deepcopy(case)
    if isinstance(case, tuple):
        return fn(*case)
    if isinstance(case, dict):
        return fn(**case)
    return fn(case)


def check(learner_fn: Callable, reference_fn: Callable, inputs, name: str, *,
          seeds: Sequence[int] = (0, 1, 2), rtol: float = 1e-5, atol: float = 1e-6,
          strict: bool = False) -> Callable:
    """Compare ``learner_fn`` with ``reference_fn``; print the verdict; return the one to use.

    ``inputs`` is a list of cases or a function ``seed -> case`` called for each of
    ``seeds``; a case is a tuple of positional arguments, a dict of keyword arguments,
    or a single argument. Returns ``learner_fn`` if every case matches, else
    ``reference_fn``. With ``strict=True`` a failed or skipped exercise raises
    ``AssertionError`` after printing (for nbgrader's graded cells).
    """
    if not callable(learner_fn) or not callable(reference_fn):
        raise ValueError(f"check({name!r}): expected two functions (learner's, reference), got "
                         f"{type(learner_fn).__name__} and {type(reference_fn).__name__}")
    if not isinstance(name, str) or not name:
        raise ValueError(f"check: expected a non-empty exercise name, got {name!r}")
    cases = _cases(inputs, seeds)
    outcome = None
    for i, case in enumerate(cases):
        expected = _call(reference_fn, case)  # a failing reference is the chapter's bug: let it raise
        try:
            got = _call(learner_fn, case)
        except NotImplementedError:
            outcome = Outcome(name, "not attempted",
                              f"… {name}: not attempted yet (NotImplementedError): "
                              "the library's version is used from here on")
            break
        except Exception as e:  # noqa: BLE001 - any learner error is a verdict, not a crash
            outcome = Outcome(name, "failed", f"✗ {name} failed on case {i}: raised "
                              f"{type(e).__name__}: {e} — the library's version is used from here on")
            break
        diff = compare(got, expected, rtol, atol)
        if diff:
            outcome = Outcome(name, "failed", f"✗ {name} failed on case {i}: {diff} — "
                              "the library's version is used from here on")
            break
    if outcome is None:
        outcome = Outcome(name, "passed", f"✓ {name} passed ({len(cases)} cases): your version is used from here on")
    RESULTS[name] = outcome
    print(outcome.message)
    if strict:
        assert_passed(name)
    return learner_fn if outcome.passed else reference_fn


def assert_passed(name: str) -> None:
    """Raise ``AssertionError`` unless the latest :func:`check` called ``name`` passed."""
    outcome = RESULTS.get(name)
    if outcome is None:
        raise AssertionError(f"{name}: not checked yet; run the check cell above first")
    if not outcome.passed:
        raise AssertionError(f"{name}: {outcome.status} — this graded cell passes once the check prints ✓")
