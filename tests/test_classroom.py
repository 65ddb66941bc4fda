"""The classroom: an instructor's nbgrader cycle on a course folder from ``python -m masp_lite.course.classroom init``.

The README's instructor section, run as written (nbgrader's own commands, from inside the course
folder, without activating the environment) on chapter 02 with ten submissions in one cycle: the
solutions (full marks), the untouched release placed by hand and through nbgrader's exchange
(zero), a partial attempt (its exact points), an honest answer that warns (full marks), deleted
and stripped cells (named in the feedback and by ``export``), forgeries of every family (screened:
zero with the reason in the feedback; edited inputs: graded as released), and a forgery sent to
manual grading by the course folder's config. Then the learners' copy of the course (no
solutions), the forgery screen on its own, and the two JupyterLabs of the README: the learners'
(its first command) without nbgrader's instructor tools or pages, the instructors' with them.
"""
import contextlib
import csv
import html
import json
import os
import re
import shlex
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import nbformat
import pytest

from masp_lite.course import classroom
from masp_lite.course.checking import REVEAL_MARK

ROOT = Path(__file__).resolve().parents[1]
CHAPTER = "02_goal_assignment"
BIN = Path(sys.executable).parent


def _nbgrader(folder, *args, timeout=900):
    # PATH without the environment's bin/: the course folder's config must find alembic by itself
    path = os.pathsep.join(p for p in os.environ.get("PATH", "").split(os.pathsep) if Path(p) != BIN)
    tmp = Path(folder).parent / "tmp"  # autograde's kernels get this test's own temp folder (tests/test_notebooks.py)
    tmp.mkdir(exist_ok=True)
    env = dict(os.environ, PATH=path, TMPDIR=str(tmp))
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
    with pytest.raises(ValueError, match="would be replaced"):
        classroom.init(tmp_path / "course", ["03"], solutions=ROOT / "solutions")
    assert classroom.init(tmp_path / "course", ["03"], solutions=ROOT / "solutions",
                          force=True)[0].parent.name == "03_graph_encoders"
    with pytest.raises(ValueError, match="unknown chapter"):
        classroom.init(tmp_path / "other", ["99"], solutions=ROOT / "solutions")
    assert classroom.main(["init", str(tmp_path / "third"), "nope"]) == 2


def test_init_never_replaces_an_instructors_file_and_either_finishes_or_changes_nothing(tmp_path):
    course = tmp_path / "course"
    classroom.init(course, ["02"], solutions=ROOT / "solutions")
    cfg = course / "nbgrader_config.py"
    edited = cfg.read_text() + "c.Exchange.timezone = 'UTC'  # the instructor's own line\n"
    cfg.write_text(edited)
    before = {p: p.read_bytes() for p in course.rglob("*") if p.is_file()}
    with pytest.raises(ValueError, match="nbgrader_config.py exist.*nothing was written"):
        classroom.init(course, ["03"], solutions=ROOT / "solutions")   # a new chapter, an edited config
    with pytest.raises(ValueError, match="02_goal_assignment.ipynb.*nothing was written"):
        classroom.init(course, ["03", "02"], solutions=ROOT / "solutions")
    assert {p: p.read_bytes() for p in course.rglob("*") if p.is_file()} == before  # not even chapter 03
    cfg.write_text(classroom.CONFIG.format(course_id="masp-lite", screened="zero"))
    assert [p.parent.name for p in classroom.init(course, ["03"], solutions=ROOT / "solutions")] \
        == ["03_graph_encoders"]  # an unchanged config is no instructor's edit


def test_init_builds_the_learners_copy_without_solutions(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "masp_lite.course.classroom", "init", str(tmp_path / "course"),
                           "02", "--learners", str(tmp_path / "learners")], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    bundle = tmp_path / "learners"
    assert "the learners' copy" in proc.stdout
    assert not (bundle / "solutions").exists() and not (bundle / "tests").exists()
    notebooks = sorted(p.name for p in (bundle / "notebooks").glob("*.ipynb"))
    assert notebooks == sorted(p.name for p in (ROOT / "solutions").glob("*.ipynb"))
    for name in notebooks:  # the release, byte for byte
        assert (bundle / "notebooks" / name).read_bytes() == (ROOT / "notebooks" / name).read_bytes()
    assert sorted(p.relative_to(bundle).as_posix() for p in bundle.rglob("*.ipynb")) == \
        [f"notebooks/{n}" for n in notebooks]                     # no other notebook anywhere
    for name in ("pyproject.toml", "environment.txt", "README.md", "notebooks/README.md",
                 "masp_lite/course/checking.py", "masp_lite/course/labconfig/learners.py"):
        assert (bundle / name).is_file(), name
    assert not list(bundle.rglob("__pycache__"))
    solution = nbformat.read(ROOT / "solutions" / f"{CHAPTER}.ipynb", as_version=4)
    answer = _cells_by_id(solution)["my_bottleneck"].source.split("### BEGIN SOLUTION")[1].split("### END")[0]
    assert len(answer) > 200 and not any(answer.strip() in p.read_text(errors="ignore")
                                         for p in bundle.rglob("*") if p.is_file() and p.suffix in (".py", ".ipynb",
                                                                                                   ".md", ".json"))
    with pytest.raises(ValueError, match="exists"):
        classroom.learner_copy(bundle, root=ROOT)


def test_screen_passes_every_answer_of_the_course_and_refuses_each_family():
    from masp_lite.course.grading import screen

    for path in (*sorted((ROOT / "solutions").glob("*.ipynb")), *sorted((ROOT / "notebooks").glob("*.ipynb"))):
        for key, cell in _cells_by_id(nbformat.read(path, as_version=4)).items():
            if cell.metadata["nbgrader"]["solution"]:
                assert screen(cell.source) is None, (path.name, key, screen(cell.source))
    forged = {
        "import importlib\nimport masp_lite.algos.assignment as a\nfresh = importlib.reload(a)": "imports importlib",
        "from masp_lite.algos import assignment\nkeep = [assignment.distance_matrix]": "assigns something other",
        "import types\ndef f(x):\n    return x": "imports types",
        "def f(x):\n    return x.__globals__['assignment']": "attribute .__globals__",
        "@(lambda fn: assignment.distance_matrix)\ndef cost_matrix(a, g):\n    pass": "computed decorator",
        "def f(x):\n    return torch.load('solutions.pt')": "attribute .load",
        "def f(x):\n    return np.loadtxt(x)": "attribute .loadtxt",
        "def f(x):\n    return x['../source/02/02.ipynb']": "names the course's files",
        "from masp_lite.course.checking import RESULTS": "imports masp_lite.course",
        "def f(x):\n    global library_trips\n    library_trips = x": "rebinds names",
        "def f(x):\n    return _i12": "uses _i12",
        "def f(x):\n    return In[-2]": "uses In",
        "%load_ext autoreload\ndef f(x):\n    return x": "is not plain Python",
        "class Always:\n    def __eq__(self, other):\n        return True": "defines a class",
        "def f(x):\n    return getattr(x, 'f_' + 'globals')": "uses getattr",
        "def f(x):\n    return x.f_back": "attribute .f_back",
        "print('hi')\ndef f(x):\n    return x": "runs a expr statement",
        "from masp_lite import course as c": "imports course from masp_lite",
        "def f(x):\n    return torch.os.getcwd()": "attribute .os",
        "def f(x):\n    return torch.from_file('s' + 'olutions', size=9)": "attribute .from_file",
        "def f(x):\n    return '{0.f_globals}'.format(x)": "format field that reads attributes",
        "def f(x):\n    return np.save('masp_lite.py', x)": "attribute .save",
    }
    for source, reason in forged.items():
        got = screen(source)
        assert got is not None and reason in got, (source, got)


#: The forgeries graded in the cycle, by family: each replaces one answer cell of an otherwise solved notebook.
FORGERIES = {
    "copy": {   # the reference copied at run time: its source, a holder made before the check, a rebuilt function
        "hungarian": "import inspect\nexec(inspect.getsource(assignment.hungarian).replace('def hungarian', "
                     "'def my_hungarian'))",
        "choose_action": "def choose_action(vel, desired_vel, _keep=reference.velocity_to_action):\n"
                         "    return _keep(vel, desired_vel)",
        "my_bottleneck": "my_bottleneck = type(team.bottleneck)(team._bottleneck_one.__code__, {'np': np})",
    },
    "run": {   # the instructor's notebook read from the course folder, IPython's hooks rewrite the check cells
               # before they run, the checker patched from the answer cell
        "hungarian": "def my_hungarian(agent_pos, goal_pos, agent_mask, goal_mask):\n"
                     "    with open('../../../source/02_goal_assignment/02_goal_assignment.ipynb') as f:\n"
                     "        raise NotImplementedError(str(f))",
        "choose_action": "get_ipython().input_transformers_post.append(lambda lines: ['pass\\n'])\n"
                         "def choose_action(vel, desired_vel):\n    return vel",
        "my_bottleneck": "import masp_lite.course as c\nc.assert_passed = lambda name: None\n"
                         "def my_bottleneck(dist):\n    return dist",
    },
}


def _release(folder):
    return nbformat.read(folder / "release" / CHAPTER / f"{CHAPTER}.ipynb", as_version=4)


def _solved(folder, answers, **replace):
    """The release with every answer cell solved, then the answer cells in ``replace`` (grade_id -> source)."""
    nb = _release(folder)
    for key, cell in _cells_by_id(nb).items():
        if key in answers:
            cell.source = replace.get(key, answers[key])
    return nb


def _feedback(folder, student):
    """The feedback page's text (HTML entities decoded)."""
    return html.unescape((folder / "feedback" / student / CHAPTER / f"{CHAPTER}.html").read_text(encoding="utf-8"))


@pytest.mark.slow
def test_instructor_cycle_grades_honest_partial_and_forged_submissions(tmp_path):
    folder = tmp_path / "classroom"
    proc = subprocess.run([sys.executable, "-m", "masp_lite.course.classroom", "init", str(folder), CHAPTER],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    _nbgrader(folder, "generate_assignment", CHAPTER)
    release = _release(folder)
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

    _submit(folder, "ada", _solved(folder, answers))                 # every exercise solved
    _submit(folder, "bob", release)                                  # the release, untouched
    distances = "d = np.linalg.norm(a[b, rows][:, None, :] - g[b, cols][None, :, :], axis=-1)"
    assert distances in answers["hungarian"]
    squared = answers["hungarian"].replace(distances, distances + " ** 2")        # squared costs: another assignment
    # a partial attempt: one exercise wrong; the learner asked for the controller's answer before solving it
    cy = _solved(folder, answers, hungarian=squared)
    asked = next(c for c in cy.cells if c.source.startswith('course.reveal("h-greedy controller"'))
    asked.source = asked.source[:-1] + ", now=True)"
    asked.outputs = [nbformat.v4.new_output("display_data", data={"text/plain": "def velocity_to_action(...): ..."},
                                            metadata={REVEAL_MARK: "h-greedy controller"})]
    _submit(folder, "cy", cy)
    # an honest answer that warns (torch.tensor on a tensor: a UserWarning inside the check)
    assert "nxt = vel.unsqueeze(-2)" in answers["choose_action"]
    warns = answers["choose_action"].replace("nxt = vel.unsqueeze(-2)", "nxt = torch.tensor(vel).unsqueeze(-2)")
    _submit(folder, "eve", _solved(folder, answers, choose_action=warns))
    # deleted and stripped cells: the assignment's check deleted (its answer calls the library's version), the
    # controller's answer stripped of its nbgrader metadata (found by its cell id), the min-max answer deleted
    fay = _solved(folder, answers, hungarian=answers["hungarian"].replace(
        "    return torch.from_numpy(out)",
        "    return assignment.hungarian(agent_pos, goal_pos, agent_mask, goal_mask)"))
    del _cells_by_id(fay)["choose_action"].metadata["nbgrader"]
    fay.cells = [c for c in fay.cells if c.metadata.get("nbgrader", {}).get("grade_id")
                 not in ("check_hungarian", "my_bottleneck")]
    _submit(folder, "fay", fay)
    for family, forged in FORGERIES.items():                        # each family of forgery
        _submit(folder, f"forged-{family}", _solved(folder, answers, **forged))
    # the inputs and the reference edited in their (unlocked) cells so that wrong answers pass, a cell added
    # between an answer and its check that patches the checker
    edited = _solved(folder, answers, hungarian=squared,
                     my_bottleneck="def my_bottleneck(dist):\n    return linear_sum_assignment(dist)")
    cells = {c.get("id"): c for c in edited.cells}
    cells["ex1-cases"].source = ("def hungarian_cases(seed):\n"
                                 "    return torch.zeros(1, 1, 2), torch.zeros(1, 1, 2), None, None")
    cells["ex3-cases"].source = cells["ex3-cases"].source.replace(
        "def library_trips(agent_pos, goal_pos):", "library_trips = lambda a, g: trips_of(my_bottleneck)(a, g)\n\n\n"
        "def _unused(agent_pos, goal_pos):")
    at = edited.cells.index(cells["c33"])
    edited.cells.insert(at, nbformat.v4.new_code_cell("course.assert_passed = lambda name: None"))
    _submit(folder, "forged-cells", edited)

    _nbgrader(folder, "autograde", CHAPTER)
    # the instructor sends screened answers to manual grading instead, in the course folder's config
    config = folder / "nbgrader_config.py"
    assert 'c.UseReleaseCells.screened = "zero"' in config.read_text().replace("'", '"')
    config.write_text(config.read_text().replace("screened = 'zero'", "screened = 'manual'"))
    _submit(folder, "gil", _solved(folder, answers, hungarian=FORGERIES["copy"]["hungarian"]))
    _nbgrader(folder, "autograde", CHAPTER, "--student=gil")
    _nbgrader(folder, "generate_feedback", CHAPTER)
    export = _nbgrader(folder, "export")
    with open(folder / "grades.csv", newline="") as f:
        grades = {row["student_id"]: row for row in csv.DictReader(f)}
    score = {s: float(row["score"]) for s, row in grades.items()}
    assert all(float(row["max_score"]) == total for row in grades.values())
    cost, controller = points["check_hungarian"], points["check_choose_action"]
    assert score == {"ada": total, "bob": 0.0, collected[0]: 0.0, "cy": total - cost, "eve": total,
                     "fay": controller, "forged-copy": 0.0, "forged-run": 0.0, "forged-cells": controller,
                     "gil": total - cost}, score
    print("grades:", {s: f"{v:g}/{total:g}" for s, v in score.items()})

    for student in grades:
        page = folder / "feedback" / student / CHAPTER / f"{CHAPTER}.html"
        assert page.is_file() and page.stat().st_size > 10_000
    feedback = _feedback(folder, "bob")
    assert "not attempted yet" in feedback and "ExerciseNotPassed" in feedback
    assert "checking.py" not in feedback  # a failed graded cell ends in one line, not a traceback
    shown_later = "of 'h-greedy controller' appears here once your check passes"
    assert shown_later in feedback and shown_later not in _feedback(folder, "ada")  # bob is not shown the answer
    assert "you asked to see the library's version of 'h-greedy controller'" in _feedback(folder, "cy")
    feedback = _feedback(folder, "eve")
    assert "UserWarning" in feedback and "warnings cost no points" in feedback
    feedback = _feedback(folder, "fay")
    assert "which the check makes unavailable" in feedback
    assert "the check cell 'check_hungarian' was deleted" in feedback
    assert "the answer cell 'choose_action' had lost its nbgrader metadata" in feedback
    assert "the answer cell 'my_bottleneck' was deleted from the submission: graded as not attempted" in feedback
    reasons = {"forged-copy": ["imports inspect", "default argument that is not a constant", "attribute .__code__"],
               "forged-run": ["uses open", "uses get_ipython", "imports masp_lite.course"]}
    for student, expected in reasons.items():
        feedback = _feedback(folder, student)
        for reason in expected:
            assert "ScreenedAnswer" in feedback and reason in feedback, (student, reason)
    feedback = _feedback(folder, "forged-cells")
    assert "differs from the release" in feedback and "you added were not run" in feedback
    assert "Hungarian assignment failed on case 0" in feedback and "min-max assignment failed" in feedback
    assert "sent to manual grading: the answer cell 'hungarian' imports inspect" in _feedback(folder, "gil")

    # export names every deleted, stripped or screened cell, one line each
    out = export.stdout
    assert "fay 02_goal_assignment/02_goal_assignment: ⚑ the check cell 'check_hungarian' was deleted" in out
    assert "fay 02_goal_assignment/02_goal_assignment: ⚑ the answer cell 'choose_action' had lost" in out
    assert "fay 02_goal_assignment/02_goal_assignment: ⚑ the answer cell 'my_bottleneck' was deleted" in out
    assert "forged-run 02_goal_assignment/02_goal_assignment: ⚑ screened, scored zero: the answer cell " \
           "'choose_action' uses get_ipython" in out
    assert "gil 02_goal_assignment/02_goal_assignment: ⚑ screened, sent to manual grading" in out
    assert "cy 02_goal_assignment/02_goal_assignment: ⚑ you asked to see the library's version of " \
           "'h-greedy controller' before your check passed" in out
    assert not any(line.startswith(("ada ", "eve ", "bob ")) for line in out.splitlines())

    # the formgrader of the README's `../.venv/bin/jupyter lab`, started in the course folder, sees the cycle;
    # gil's screened answer waits there for a manual grade
    with _lab([], folder) as get:
        assignments = {a["name"]: a for a in json.loads(get("/formgrader/api/assignments"))}
        submissions = {s["student"]: s for s in json.loads(get(f"/formgrader/api/submissions/{CHAPTER}"))}
    assert assignments[CHAPTER]["num_submissions"] == len(grades) and assignments[CHAPTER]["max_score"] == total
    assert submissions["gil"]["needs_manual_grade"] and not submissions["ada"]["needs_manual_grade"]


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


def _config_of(page):
    found = re.search(r'<script id="jupyter-config-data" type="application/json">(.*?)</script>', page, flags=re.S)
    assert found, "no page config in JupyterLab's /lab page"
    return json.loads(found.group(1))


@pytest.mark.slow
def test_learners_lab_hides_nbgrader_and_instructors_lab_shows_it(tmp_path):
    learner = _readme_command(".venv/bin/jupyter lab")        # the README's first command
    assert "notebooks/00_tour.ipynb" in learner
    args = [a.replace("masp_lite/", f"{ROOT}/masp_lite/", 1) for a in learner[2:] if not a.endswith(".ipynb")]
    with _lab(args, tmp_path) as get:
        config = _config_of(get("/lab"))
        names = [e["name"] for e in config["federated_extensions"]]
        assert "@jupyter/nbgrader" in names                          # installed ...
        assert "@jupyter/nbgrader" in config["disabledExtensions"]   # ... and off: no menu, Validate, Create Assignment
        for page in ("/formgrader", "/formgrader/manage_assignments", "/formgrader/api/assignments",
                     "/formgraders", "/assignments", "/courses", "/assignments/validate"):
            with pytest.raises(urllib.error.HTTPError) as refused:   # and its server pages are not served
                get(page)
            assert refused.value.code == 404, page

    instructor = _readme_command(".venv/bin/jupyter lab --ServerApp.root_dir=.")
    assert not any("app_settings_dir" in a or "--config" in a for a in instructor)
    with _lab([a for a in instructor[2:] if not a.endswith(".ipynb")], tmp_path) as get:
        config = _config_of(get("/lab"))
        assert "Manage Assignments" in get("/formgrader/manage_assignments")   # the formgrader answers here
    assert "@jupyter/nbgrader" in [e["name"] for e in config["federated_extensions"]]
    assert not any(d.startswith("@jupyter/nbgrader") for d in config["disabledExtensions"])
