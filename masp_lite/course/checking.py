"""Exercise checks: compare a learner's function with the library's on seeded inputs.

A chapter's exercise asks the learner to re-implement a short library function. Its check
cell calls :func:`check`, which

* runs the learner's function and the library's (the *reference*) on the same inputs —
  each call gets its own deep copy, so an in-place edit by one cannot leak into the other;
* makes the reference (and what it wraps, ``hide=[...]``) unavailable while the learner's
  function runs: an answer that calls the library's version fails and is told so;
* compares the results structurally: tensors and arrays by shape, then values with
  ``allclose(rtol, atol)``; tuples/lists by length and item; dicts by keys and value;
  anything else with ``==``;
* prints exactly one line — ``✓ passed``, ``✗ failed: <the mismatch>`` (for arrays: how many
  entries differ beyond tolerance and the largest difference) or
  ``… not attempted yet (NotImplementedError)`` — and
* returns the function the rest of the chapter should use: the learner's when it passed,
  the reference otherwise. A wrong or skipped answer never stops the chapter;
* runs both functions with warnings recorded and ``sys.stderr`` sent to ``sys.stdout``, and
  prints each distinct warning as a ``note:`` line after the verdict: ``nbgrader autograde``
  scores a graded cell zero for *any* stderr output, and a warning (torch's
  ``torch.tensor(tensor)`` copy, say) is no mistake.

:func:`reveal` shows the library's version after the check, only once it has passed (or when
the learner asks for it with ``now=True``, which :data:`REVEALED` records and
``nbgrader autograde`` reports, see :mod:`masp_lite.course.grading`).

Graded cells (nbgrader's ``grade: true`` cells) additionally call :func:`assert_passed`
(or pass ``strict=True``), which raises :class:`ExerciseNotPassed` (an ``AssertionError``
shown as one line, not a traceback) unless the check passed, so ``nbgrader autograde``
awards the cell's points only for a correct function.

Why hand-written: nbgrader grades by "did the cell raise", and ``numpy.testing`` /
``torch.testing`` raise on the first difference with messages about arrays rather than
about the exercise; the learner needs a one-line verdict and a fallback instead.
"""
from __future__ import annotations

import contextlib
import copy
import math
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import torch

__all__ = ["check", "assert_passed", "compare", "unavailable", "reveal", "Outcome", "RESULTS", "REVEALED",
           "LibraryUnavailable", "ExerciseNotPassed", "REVEAL_MARK"]


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

#: The exercises whose library version the learner asked to see before passing (``reveal(..., now=True)``).
REVEALED: set[str] = set()

#: The output metadata key that marks a reference shown before its check passed (read by the grader).
REVEAL_MARK = "masp_lite_revealed"


def compare(got, expected, rtol: float = 1e-5, atol: float = 1e-6, where: str = "output") -> str | None:
    """The difference between ``got`` and ``expected`` as a sentence, or ``None``.

    Arrays: how many entries differ beyond tolerance and the largest difference (where, got,
    expected); containers: the first item that differs.

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
        count = int(bad.sum())
        if e.dtype == bool or g.dtype == bool:
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            what = "first"
        else:  # the largest difference, so a real error is not mistaken for rounding
            gap = np.abs(g.astype(np.float64) - e.astype(np.float64))
            gap = np.where(bad, np.nan_to_num(gap, nan=np.inf, posinf=np.inf), -1.0)
            idx = tuple(int(i) for i in np.unravel_index(int(np.argmax(gap)), gap.shape))
            what = f"largest difference {float(gap[idx]):.3g}"
        at = f"{where}[{', '.join(map(str, idx))}]" if idx else where
        return (f"{count} of {bad.size} entries of {where} differ beyond tolerance (rtol={rtol:g}, atol={atol:g}); "
                f"{what} at {at}: got {g[idx].item()!r}, expected {e[idx].item()!r}")
    return None


def _cases(inputs, seeds):
    if callable(inputs):
        return [inputs(seed) for seed in seeds]
    if isinstance(inputs, (str, bytes)) or not isinstance(inputs, Sequence) or len(inputs) == 0:
        raise ValueError("inputs: expected a non-empty list of cases (a tuple of arguments, a dict of "
                         f"keyword arguments, or one argument each) or a function seed -> case, got {inputs!r}")
    return list(inputs)


def _call(fn, case, notes: list[str] | None = None):
    """``fn`` on a deep copy of ``case``; its warnings go to ``notes`` and its stderr to stdout."""
    case = copy.deepcopy(case)
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stderr(sys.stdout):
        warnings.simplefilter("always")
        if isinstance(case, tuple):
            out = fn(*case)
        elif isinstance(case, dict):
            out = fn(**case)
        else:
            out = fn(case)
    for w in caught:
        line = f"{w.category.__name__}: {str(w.message).splitlines()[0] if str(w.message) else ''}"
        if notes is not None and line not in notes:
            notes.append(line)
    return out


class LibraryUnavailable(RuntimeError):
    """Raised when the learner's function calls a library function that its check made unavailable."""


class ExerciseNotPassed(AssertionError):
    """A graded cell's failure: shown as its one-line message, without a traceback.

    IPython prints an exception's ``_render_traceback_()`` instead of the traceback, so the
    graded cell ends in one line; it is still an error output, which nbgrader scores zero.
    """

    def _render_traceback_(self):
        return [f"\x1b[0;31m{type(self).__name__}\x1b[0m: {self}"]


def _label(obj) -> str:
    module = getattr(obj, "__module__", None) or ""
    return f"{module.rsplit('.', 1)[-1]}.{getattr(obj, '__qualname__', repr(obj))}".lstrip(".")


def _targets(objects) -> list:
    """The objects to hide: each one, what it wraps (``__wrapped__``) and the function of a bound method."""
    out = []
    for obj in objects:
        while obj is not None and not any(obj is o for o in out):
            out.append(obj)
            obj = getattr(obj, "__func__", None) or getattr(obj, "__wrapped__", None)
    return out


def _functions(learner_fn, depth: int = 2) -> list:
    """The learner's function and the functions its closure holds (``trips_of(my_fn)`` holds ``my_fn``)."""
    found, todo = [], [(learner_fn, 0)]
    while todo:
        fn, level = todo.pop()
        fn = getattr(fn, "__wrapped__", fn)
        if not callable(fn) or any(fn is f for f in found):
            continue
        found.append(fn)
        if level < depth:
            todo += [(c.cell_contents, level + 1) for c in (getattr(fn, "__closure__", None) or ())
                     if _filled(c) and callable(c.cell_contents)]
    return found


def _filled(cell) -> bool:
    try:
        cell.cell_contents  # noqa: B018 - an empty cell raises ValueError
    except ValueError:
        return False
    return True


def _namespaces(learner_fn) -> list[dict]:
    """Where a learner's function can find a library function: the library's modules, the notebook's globals."""
    spaces = [vars(m) for key, m in list(sys.modules.items())
              if m is not None and (key == "masp_lite" or key.startswith("masp_lite.") or key == "__main__")]
    for fn in _functions(learner_fn):
        g = getattr(fn, "__globals__", None)
        if isinstance(g, dict) and not any(g is s for s in spaces):
            spaces.append(g)
    return spaces


@contextlib.contextmanager
def unavailable(objects, learner_fn=None):
    """Make library ``objects`` (functions, classes, methods) raise :class:`LibraryUnavailable` while inside.

    Every module of the library, the learner's globals and the names its function closes over
    that hold one of them get a stand-in; a method is replaced on its class. Everything is put
    back on exit.
    """
    targets = _targets(objects)
    swaps = []  # (holder, key, original, is_class_attribute)

    def stand_in(obj):
        label = _label(obj)

        def unavailable_here(*args, **kwargs):
            raise LibraryUnavailable(f"your function called the library's {label}, which the check makes "
                                     "unavailable while it runs your function: write it without it")
        unavailable_here.__qualname__ = unavailable_here.__name__ = getattr(obj, "__name__", "unavailable")
        return unavailable_here

    try:
        for obj in targets:
            stub = stand_in(obj)
            for space in _namespaces(learner_fn):
                for key, value in list(space.items()):
                    if value is obj:
                        swaps.append((space, key, value, False))
                        space[key] = stub
            for fn in _functions(learner_fn):  # names the learner's function closes over
                for cell in getattr(fn, "__closure__", None) or ():
                    if _filled(cell) and cell.cell_contents is obj:
                        swaps.append((cell, "cell_contents", obj, True))
                        cell.cell_contents = stub
            qualname = getattr(obj, "__qualname__", "")
            module = sys.modules.get(getattr(obj, "__module__", None) or "")
            if "." in qualname and "<locals>" not in qualname and module is not None:
                holder = module
                for part in qualname.split(".")[:-1]:
                    holder = getattr(holder, part, None)
                attr = qualname.rsplit(".", 1)[1]
                if isinstance(holder, type) and holder.__dict__.get(attr) is obj:
                    swaps.append((holder, attr, obj, True))
                    setattr(holder, attr, stub)
        yield
    finally:
        for holder, key, value, on_class in reversed(swaps):
            if on_class:
                setattr(holder, key, value)
            else:
                holder[key] = value


def check(learner_fn: Callable, reference_fn: Callable, inputs, name: str, *,
          seeds: Sequence[int] = (0, 1, 2), rtol: float = 1e-5, atol: float = 1e-6,
          strict: bool = False, hide: Sequence = ()) -> Callable:
    """Compare ``learner_fn`` with ``reference_fn``; print the verdict; return the one to use.

    ``inputs`` is a list of cases or a function ``seed -> case`` called for each of
    ``seeds``; a case is a tuple of positional arguments, a dict of keyword arguments,
    or a single argument. Returns ``learner_fn`` if every case matches, else
    ``reference_fn``. With ``strict=True`` a failed or skipped exercise raises
    ``AssertionError`` after printing (for nbgrader's graded cells).

    While ``learner_fn`` runs, ``reference_fn`` and the library objects in ``hide`` (what a
    notebook-defined reference wraps, e.g. ``hide=[team.bottleneck]``) are
    :func:`unavailable`: an answer that calls the library's version fails, and says so.
    """
    if not callable(learner_fn) or not callable(reference_fn):
        raise ValueError(f"check({name!r}): expected two functions (learner's, reference), got "
                         f"{type(learner_fn).__name__} and {type(reference_fn).__name__}")
    if not isinstance(name, str) or not name:
        raise ValueError(f"check: expected a non-empty exercise name, got {name!r}")
    if isinstance(hide, (str, bytes)) or not isinstance(hide, Sequence) or not all(callable(h) for h in hide):
        raise ValueError(f"check({name!r}): hide: expected a list of library functions or classes, got {hide!r}")
    cases = _cases(inputs, seeds)
    outcome, notes = None, []
    library = _targets([reference_fn, *hide])
    if any(fn is t for fn in _targets([learner_fn]) for t in library):  # it, or what it wraps, is the reference
        outcome = Outcome(name, "failed", f"✗ {name} failed: your function is the library's own "
                          f"{_label(reference_fn)} — write it yourself; the library's version is used from here on")
    for i, case in enumerate(cases if outcome is None else []):
        expected = _call(reference_fn, case)  # a failing reference is the chapter's bug: let it raise
        try:
            with unavailable([reference_fn, *hide], learner_fn):
                got = _call(learner_fn, case, notes)
        except NotImplementedError:
            outcome = Outcome(name, "not attempted",
                              f"… {name}: not attempted yet (NotImplementedError): "
                              "the library's version is used from here on")
            break
        except LibraryUnavailable as e:
            outcome = Outcome(name, "failed", f"✗ {name} failed: {e} — the library's version is used from here on")
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
    for note in notes[:3]:  # stdout: nbgrader scores a cell that writes to stderr zero
        print(f"  note: your function warned ({note}); warnings cost no points")
    if strict:
        assert_passed(name)
    return learner_fn if outcome.passed else reference_fn


def assert_passed(name: str) -> None:
    """Raise :class:`ExerciseNotPassed` (an ``AssertionError``, shown as one line) unless ``name``'s check passed."""
    outcome = RESULTS.get(name)
    if outcome is None:
        raise ExerciseNotPassed(f"{name}: not checked yet; run the check cell above first")
    if not outcome.passed:
        raise ExerciseNotPassed(f"{name}: {outcome.status} — this graded cell passes once the check prints ✓")


def reveal(name: str, *objects, now: bool = False):
    """Show the source of ``objects`` (the library's version of exercise ``name``) once its check passed.

    Before the check of ``name`` has passed, prints where the answer will appear instead, unless
    ``now=True``: then the source is shown anyway, ``name`` joins :data:`REVEALED`, and the
    display carries the :data:`REVEAL_MARK` metadata, so a submission that looked at the answer
    before earning it says so in its grade (``nbgrader autograde``, :mod:`masp_lite.course.grading`).
    """
    from IPython.display import display

    from .session import show

    if not isinstance(name, str) or not name or not objects:
        raise ValueError(f"reveal: expected an exercise name and the library objects to show, "
                         f"got {name!r}, {objects!r}")
    outcome = RESULTS.get(name)
    if outcome is not None and outcome.passed:
        for obj in objects:
            display(show(obj))
        return None
    if not now:
        state = "not checked yet" if outcome is None else outcome.status
        print(f"… the library's version of {name!r} appears here once your check passes ({state} so far). "
              f"To see it now: course.reveal({name!r}, ..., now=True) — your grade records that you looked.")
        return None
    REVEALED.add(name)
    print(f"⚑ the library's version of {name!r}, shown before your check passed (your grade records it):")
    for obj in objects:
        display(show(obj), metadata={REVEAL_MARK: name})
    return None
