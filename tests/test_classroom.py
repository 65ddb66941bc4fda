"""The classroom: an instructor's nbgrader cycle on a course folder from ``python -m masp_lite.course.classroom init``.

The README's instructor section, run as written (nbgrader's own commands, from inside the course
folder, without activating the environment) on one chapter with five submissions: the solutions
(full marks), the untouched release placed by hand and the same through nbgrader's exchange
(zero), the solutions with one exercise wrong, and the solutions with one exercise answered by
calling the library (that exercise's points short). And the two JupyterLabs of the README: the
learners' (its first command) without nbgrader's instructor tools, the instructors' with them.
"""
import contextlib
import csv
import json
import os
import re
import shlex
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import nbformat
import pytest

from masp_lite.course import classroom

ROOT = Path(__file__).resolve().parents[1]
CHAPTER = "02_goal_assignment"
BIN = Path(sys.executable).parent


def _nbgrader(folder, *args, timeout=900):
    # PATH without the environment's bin/: the course folder's config must find alembic by itself
    path = os.pathsep.join(p for p in os.environ.get("PATH", "").split(os.pathsep) if Path(p) != BIN)
    env = dict(os.environ, PATH=path)
    env.pop("MASP_LITE_FAST", None)  # the course folder's config sets fast mode for grading
    proc = subprocess.run([str(BIN / "nbgrader"), *args], cwd=folder, env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, f"nbgrader {' '.join(args)}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    assert "Exception while loading config" not in proc.stderr, proc.stderr[-3000:]
    return proc


def _cells_by_id(nb):
    return {c.metadata["nbgrader"]["grade_id"]: c for c in nb.cells if "nbgrader" in c.metadata}


def _submit(folder, student, nb):
    dst = folder / "submitted" / student / CHAPTER / f"{CHAPTER}.ipynb"
    dst.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, dst)


def test_init_writes_an_nbgrader_course_folder(tmp_path):
    written = classroom.init(tmp_path / "course", solutions=ROOT / "solutions")
    assert [p.parent.name for p in written] == classroom.chapters(ROOT / "solutions")
    for p in written:
        assert p == tmp_path / "course" / "source" / p.stem / f"{p.stem}.ipynb"
        assert p.read_bytes() == (ROOT / "solutions" / p.name).read_bytes()
    assert (tmp_path / "course" / "nbgrader_config.py").is_file()
    assert (tmp_path / "course" / "gradebook.db").is_file()
    with pytest.raises(ValueError, match="exists"):
        classroom.init(tmp_path / "course", ["03"], solutions=ROOT / "solutions")
    assert classroom.init(tmp_path / "course", ["03"], solutions=ROOT / "solutions",
                          force=True)[0].parent.name == "03_graph_encoders"
    with pytest.raises(ValueError, match="unknown chapter"):
        classroom.init(tmp_path / "other", ["99"], solutions=ROOT / "solutions")
    assert classroom.main(["init", str(tmp_path / "third"), "nope"]) == 2


@pytest.mark.slow
def test_instructor_cycle_grades_three_submissions(tmp_path):
    folder = tmp_path / "classroom"
    proc = subprocess.run([sys.executable, "-m", "masp_lite.course.classroom", "init", str(folder), CHAPTER],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    _nbgrader(folder, "generate_assignment", CHAPTER)
    release = nbformat.read(folder / "release" / CHAPTER / f"{CHAPTER}.ipynb", as_version=4)
    shipped = nbformat.read(ROOT / "notebooks" / f"{CHAPTER}.ipynb", as_version=4)
    assert [c.source for c in release.cells] == [c.source for c in shipped.cells]  # the release is notebooks/
    assert [c.metadata.get("tags") for c in release.cells] == [c.metadata.get("tags") for c in shipped.cells]

    # nbgrader's exchange on one machine: release, a learner fetches and submits the release untouched, collect
    _nbgrader(folder, "release_assignment", CHAPTER)
    learner = tmp_path / "learner"
    learner.mkdir()
    exchange = [f"--Exchange.root={folder / 'exchange'}", "--course=masp-lite"]
    _nbgrader(learner, "fetch_assignment", CHAPTER, *exchange)
    _nbgrader(learner, "submit", CHAPTER, *exchange)
    _nbgrader(folder, "collect", CHAPTER)
    collected = [p.parent.parent.name for p in (folder / "submitted").glob(f"*/{CHAPTER}/{CHAPTER}.ipynb")]
    assert len(collected) == 1

    source = nbformat.read(ROOT / "solutions" / f"{CHAPTER}.ipynb", as_version=4)
    answers = {k: c.source for k, c in _cells_by_id(source).items() if c.metadata["nbgrader"]["solution"]}
    points = {k: c.metadata["nbgrader"]["points"] for k, c in _cells_by_id(source).items()
              if c.metadata["nbgrader"]["grade"]}
    total = sum(points.values())

    solved = nbformat.read(folder / "release" / CHAPTER / f"{CHAPTER}.ipynb", as_version=4)
    for key, cell in _cells_by_id(solved).items():
        if key in answers:
            cell.source = answers[key]
    _submit(folder, "ada", solved)                                   # every exercise solved
    _submit(folder, "bob", release)                                  # the release, untouched
    half = nbformat.read(folder / "release" / CHAPTER / f"{CHAPTER}.ipynb", as_version=4)
    for key, cell in _cells_by_id(half).items():
        if key in answers:
            cell.source = answers[key]
    wrong = _cells_by_id(half)["cost_matrix"]
    assert "np.sqrt((diff ** 2).sum(axis=-1))" in wrong.source
    wrong.source = wrong.source.replace("np.sqrt((diff ** 2).sum(axis=-1))", "(diff ** 2).sum(axis=-1)")  # squared
    _submit(folder, "cy", half)                                      # one exercise wrong
    cheat = nbformat.read(folder / "release" / CHAPTER / f"{CHAPTER}.ipynb", as_version=4)
    for key, cell in _cells_by_id(cheat).items():
        if key in answers:
            cell.source = answers[key]
    called = _cells_by_id(cheat)["cost_matrix"]
    called.source = called.source.replace("    return np.sqrt((diff ** 2).sum(axis=-1))",
                                          "    return assignment.distance_matrix(agent_pos, goal_pos)")
    assert "assignment.distance_matrix" in called.source
    _submit(folder, "dan", cheat)                                    # one exercise calls the library's version

    _nbgrader(folder, "autograde", CHAPTER)
    _nbgrader(folder, "generate_feedback", CHAPTER)
    _nbgrader(folder, "export")
    with open(folder / "grades.csv", newline="") as f:
        grades = {row["student_id"]: row for row in csv.DictReader(f)}
    assert set(grades) == {"ada", "bob", "cy", "dan", collected[0]}
    score = {s: float(row["score"]) for s, row in grades.items()}
    assert all(float(row["max_score"]) == total for row in grades.values())
    assert score == {"ada": total, "bob": 0.0, "cy": total - points["check_cost_matrix"],
                     "dan": total - points["check_cost_matrix"], collected[0]: 0.0}, score
    print("grades:", {s: f"{v:g}/{total:g}" for s, v in score.items()})
    for student in ("ada", "bob", "cy", "dan"):
        html = folder / "feedback" / student / CHAPTER / f"{CHAPTER}.html"
        assert html.is_file() and html.stat().st_size > 10_000
    feedback = (folder / "feedback" / "bob" / CHAPTER / f"{CHAPTER}.html").read_text(encoding="utf-8")
    assert "not attempted yet" in feedback and "ExerciseNotPassed" in feedback
    assert "checking.py" not in feedback  # a failed graded cell ends in one line, not a traceback
    feedback = (folder / "feedback" / "dan" / CHAPTER / f"{CHAPTER}.html").read_text(encoding="utf-8")
    assert "which the check makes unavailable" in feedback

    # the formgrader of the README's `../.venv/bin/jupyter lab`, started in the course folder, sees the cycle
    with _lab([], folder) as get:
        assignments = {a["name"]: a for a in json.loads(get("/formgrader/api/assignments"))}
    assert assignments[CHAPTER]["num_submissions"] == 5 and assignments[CHAPTER]["max_score"] == total


# ------------------------------------------------------------------ the learners' lab and the instructors'
def _readme_command(prefix):
    """The README's first shell command that runs ``prefix`` (e.g. '.venv/bin/jupyter lab'), as arguments."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            for part in line.split("#")[0].split("&&"):
                if part.strip().startswith(prefix):
                    return shlex.split(part.strip())
    raise AssertionError(f"no command starting {prefix!r} in the README")


@contextlib.contextmanager
def _lab(args, cwd):
    """A JupyterLab started with ``args`` (after ``jupyter lab``) in ``cwd``; yields ``get(path) -> text``."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    token = "masp-lite-test"
    cmd = [str(BIN / "jupyter"), "lab", *args, "--no-browser", f"--port={port}", "--ServerApp.ip=127.0.0.1",
           f"--IdentityProvider.token={token}", "--ServerApp.port_retries=0"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-root")  # CI containers run as root
    env = dict(os.environ, JUPYTER_CONFIG_DIR=str(cwd / ".jupyter-user"), JUPYTER_RUNTIME_DIR=str(cwd / ".runtime"))
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)

    def get(path):
        sep = "&" if "?" in path else "?"
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}{sep}token={token}", timeout=30) as r:
            return r.read().decode("utf-8")

    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                get("/api/status")
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise AssertionError(f"JupyterLab did not start: {' '.join(cmd)}\n{proc.stderr.read()[-3000:]}")
                time.sleep(1)
        yield get
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()


def _page_config(args, cwd):
    """The page config JupyterLab serves on /lab when started with ``args``."""
    with _lab(args, cwd) as get:
        page = get("/lab")
    found = re.search(r'<script id="jupyter-config-data" type="application/json">(.*?)</script>', page, flags=re.S)
    assert found, "no page config in JupyterLab's /lab page"
    return json.loads(found.group(1))


@pytest.mark.slow
def test_learners_lab_hides_nbgrader_and_instructors_lab_shows_it(tmp_path):
    learner = _readme_command(".venv/bin/jupyter lab")        # the README's first command
    assert "notebooks/00_tour.ipynb" in learner
    args = [a.replace("masp_lite/", f"{ROOT}/masp_lite/", 1) for a in learner[2:] if not a.endswith(".ipynb")]
    config = _page_config(args, tmp_path)
    names = [e["name"] for e in config["federated_extensions"]]
    assert "@jupyter/nbgrader" in names                          # installed ...
    assert "@jupyter/nbgrader" in config["disabledExtensions"]   # ... and off: no menu, Validate, Create Assignment

    instructor = _readme_command(".venv/bin/jupyter lab --ServerApp.root_dir=.")
    assert not any("app_settings_dir" in a for a in instructor)
    config = _page_config([a for a in instructor[2:] if not a.endswith(".ipynb")], tmp_path)
    assert "@jupyter/nbgrader" in [e["name"] for e in config["federated_extensions"]]
    assert not any(d.startswith("@jupyter/nbgrader") for d in config["disabledExtensions"])
