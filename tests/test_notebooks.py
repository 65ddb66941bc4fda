"""Every chapter runs top to bottom, both versions, in fast mode; the learner versions show no answer early.

Instructor versions run in their own ``pytest --nbval-lax`` subprocess (a fresh kernel from this
environment, ``MASP_LITE_FAST=1``) and must pass every graded check. Learner versions run as
shipped, every exercise a stub, through nbclient (cells tagged ``raises-exception`` — the graded
ones — may fail, no other cell may), and their outputs are then searched for the source of every
exercise's reference (what its check compares with, and what it hides): a learner who has not
solved an exercise must not see its answer (``course.reveal`` shows it only after the check passes).
The same outputs are searched for verdict lines ("SR : MASP 0.990 h-greedy 1.000 -> h-greedy
better"): the words on each must agree with the numbers printed beside them.

nbval stops each kernel by killing it, so a chapter's ``tempfile.TemporaryDirectory`` (chapter
06's ``masp-run-*`` run folder) is never removed by the kernel. Each test gives its kernel a
temporary folder of its own (``TMPDIR``, inside pytest's ``tmp_path``, which pytest rotates), and
the instructor run checks that chapter 06's run folder landed there. No test looks at the system's
shared temporary folder: another process running chapter 06 or 11 at the same moment makes its own
``masp-run-*`` folders there, and they are none of these tests' business. Every other test that starts a
kernel (chapter 08's 3-D section, nbgrader's autograde, the exercises' cheats) does the same, and a test
reads the suite for it.
"""
import ast
import inspect
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient
from test_exercises import _imports

ROOT = Path(__file__).resolve().parents[1]
SOLUTIONS = sorted((ROOT / "solutions").glob("*.ipynb"))
LEARNER = sorted((ROOT / "notebooks").glob("*.ipynb"))
LIMIT_S = 600  # hard stop; a chapter should take about a minute (3 minutes at most) on 2 cores
#: Chapters whose run folder outlives their kernel (a ``TemporaryDirectory`` kept for the whole chapter).
KEEPS_A_RUN_FOLDER = {"06_training_masp"}


@pytest.mark.notebook
@pytest.mark.parametrize("path", SOLUTIONS, ids=[f"solutions/{p.stem}" for p in SOLUTIONS])
def test_instructor_notebook_runs_under_nbval(path, tmp_path):
    own_tmp = tmp_path / "tmp"  # this test's own: nothing another process does can appear here
    own_tmp.mkdir()
    env = dict(os.environ, MASP_LITE_FAST="1", MPLBACKEND="Agg", PYDEVD_DISABLE_FILE_VALIDATION="1",
               TMPDIR=str(own_tmp))
    cmd = [sys.executable, "-m", "pytest", "--nbval-lax", "--nbval-current-env", "-q", "-p", "no:cacheprovider",
           "-p", "no:randomly", "--nbval-cell-timeout", str(LIMIT_S), str(path.relative_to(ROOT))]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=LIMIT_S)
    took = time.perf_counter() - start
    assert proc.returncode == 0, f"{path.name} failed under nbval:\n{proc.stdout[-6000:]}\n{proc.stderr[-2000:]}"
    if path.stem in KEEPS_A_RUN_FOLDER:  # the kernel used this test's temp folder, not the system's
        assert list(own_tmp.glob("masp-run-*")), f"{path.name} made no run folder in its own temp folder {own_tmp}"
    print(f"solutions/{path.name}: {took:.0f} s")


#: What starts a notebook kernel in a test: nbclient, nbval in a subprocess, nbgrader's commands (autograde).
KERNEL_START = re.compile(r"NotebookClient\(|--nbval|/ \"nbgrader\"")


def test_every_kernel_a_test_starts_gets_a_temporary_folder_of_its_own():
    """Each function of the test suite that starts a kernel sets its ``TMPDIR`` (see the module docstring)."""
    shared = []
    for path in sorted(Path(__file__).parent.glob("test_*.py")):
        source = path.read_text(encoding="utf-8")
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.FunctionDef):
                body = ast.get_source_segment(source, node)
                if KERNEL_START.search(body) and "TMPDIR" not in body:
                    shared.append(f"{path.name}::{node.name}")
    assert shared == [], f"kernels started in the machine's shared temporary folder: {shared}"


def references(instructor: nbformat.NotebookNode) -> dict[str, str]:
    """``{expression: source}`` of every exercise's reference and hidden objects, from its graded check cells."""
    namespace = _imports(instructor)  # the chapter's imports, to resolve the references' names
    found = {}
    for cell in instructor.cells:
        if not cell.metadata.get("nbgrader", {}).get("grade"):
            continue
        for node in ast.walk(ast.parse(cell.source)):
            if not (isinstance(node, ast.Call) and ast.unparse(node.func) == "course.check"):
                continue
            exprs = [node.args[1]] + [e for k in node.keywords if k.arg == "hide" for e in k.value.elts]
            for expr in map(ast.unparse, exprs):
                try:
                    found[expr] = inspect.getsource(eval(expr, dict(namespace)))
                except Exception:  # noqa: BLE001 - a notebook-defined wrapper: its library part is in hide=[...]
                    pass
    return found


def _outputs_text(nb) -> str:
    parts = []
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            parts.append(out.get("text", ""))
            parts += [v if isinstance(v, str) else "" for v in (out.get("data") or {}).values()]
    return "\n".join(parts)


#: A verdict line of :func:`masp_lite.reproduction.claims.verdict`: "SR   : MASP   0.990   h-greedy   1.000   -> ..."
VERDICT = re.compile(r"(?P<metric>SR|Steps|CR)\s*: (?P<a>.+?)\s+(?P<va>never|-?\d+\.\d+)\s+(?P<b>.+?)\s+"
                     r"(?P<vb>never|-?\d+\.\d+)\s+-> (?P<word>[\w\- ']+?)\s*$")  # not a docstring's quoted example


def verdict_contradictions(text: str) -> list[str]:
    """The verdict lines of ``text`` whose words disagree with the numbers printed on them.

    The numbers are read as printed: two equal numbers are a tie, a higher SR and a lower Steps
    or CR is better, "never" (no episode covered every landmark) loses to any number."""
    from masp_lite.reproduction.claims import better

    bad = []
    for line in text.splitlines():
        m = VERDICT.search(line)
        if m is None:
            continue
        value = lambda v: None if v == "never" else float(v)  # noqa: E731
        who = better(m["metric"].lower(), value(m["va"]), value(m["vb"]))
        expected = {"a": f"{m['a'].strip()} better", "b": f"{m['b'].strip()} better", "tie": "a tie",
                    "neither": "neither ever covers every landmark"}[who]
        if m["word"].strip() != expected:
            bad.append(f"{line.strip()!r}: the numbers say {expected!r}")
    return bad


def test_the_verdict_search_finds_a_contradiction():
    lines = ["SR   : MASP here   1.000   paper   1.000   -> paper better",        # 0.9996 printed as 1.000
             "Steps: MASP  25.370   h-greedy  26.870   -> MASP better",
             "CR   : MASP   0.261   h-greedy   0.190   -> h-greedy better",
             "SR   : MASP   0.990   h-greedy   1.000   -> a tie",
             "Steps: MASP   never   h-greedy  26.870   -> h-greedy better",
             "    against the paper's MASP: CR   : MASP here   0.300   paper   0.300   -> a tie",
             '    """One line per metric: ``"SR   : MASP   0.990   h-greedy   1.000   -> paper better"``."""']
    found = verdict_contradictions("\n".join(lines))
    assert len(found) == 2 and "paper better" in found[0] and "a tie" in found[1], found
    assert "'a tie'" in found[0] and "'h-greedy better'" in found[1]


@pytest.mark.notebook
@pytest.mark.parametrize("path", LEARNER, ids=[f"notebooks/{p.stem}" for p in LEARNER])
def test_learner_notebook_runs_and_shows_no_answer_early(path, tmp_path, monkeypatch):
    monkeypatch.setenv("MASP_LITE_FAST", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("PYDEVD_DISABLE_FILE_VALIDATION", "1")
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the kernel's own temp folder (see the module docstring)
    nb = nbformat.read(path, as_version=4)
    start = time.perf_counter()
    NotebookClient(nb, timeout=LIMIT_S, kernel_name="python3",  # raises on an error outside raises-exception cells
                   resources={"metadata": {"path": str(path.parent)}}).execute()
    took = time.perf_counter() - start
    shown = _outputs_text(nb)
    refs = references(nbformat.read(ROOT / "solutions" / path.name, as_version=4))
    assert refs, f"{path.name}: no exercise reference found"
    leaked = [expr for expr, source in refs.items() if source.strip() in shown]
    assert leaked == [], f"{path.name}: the learner version shows the answer of an unsolved exercise: {leaked}"
    assert verdict_contradictions(shown) == [], f"{path.name}: verdicts that contradict their numbers"
    print(f"notebooks/{path.name}: {took:.0f} s")


def test_the_leak_search_finds_a_shown_reference():
    """The search above would see a reference: a passed check's reveal shows exactly that source."""
    import masp_lite.course as course
    from masp_lite.algos import assignment

    instructor = nbformat.read(ROOT / "solutions" / "02_goal_assignment.ipynb", as_version=4)
    source = references(instructor)["assignment.hungarian"]
    assert source == inspect.getsource(assignment.hungarian)
    from IPython.core.formatters import DisplayFormatter

    data, _ = DisplayFormatter().format(course.show(assignment.hungarian))
    fake = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(outputs=[
        nbformat.v4.new_output("display_data", data=data)])])
    assert source.strip() in _outputs_text(fake)
