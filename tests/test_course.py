"""Course machinery: exercise checks, fast mode, skeleton of every chapter, learner notebooks in sync."""
import os
import re
import subprocess
import sys
from pathlib import Path

import nbformat
import numpy as np
import pytest
import torch
from IPython.core.inputtransformer2 import TransformerManager

import masp_lite.course as course
from masp_lite.course import authoring, generate

ROOT = Path(__file__).resolve().parents[1]
SOLUTIONS = sorted((ROOT / "solutions").glob("*.ipynb"))


# ------------------------------------------------------------------ check()
def _ref(x, scale=2.0):
    return {"y": x * scale, "n": int(x.numel())}


def _cases(seed):
    g = torch.Generator().manual_seed(seed)
    return (torch.rand(3, 2, generator=g),)


def test_check_passes_and_returns_learners_function(capsys):
    mine = lambda x, scale=2.0: {"n": int(x.numel()), "y": scale * x}  # noqa: E731
    got = course.check(mine, _ref, inputs=_cases, name="scale")
    assert got is mine
    assert capsys.readouterr().out.startswith("✓ scale passed (3 cases)")
    course.assert_passed("scale")


def test_check_failure_names_first_mismatch_and_falls_back(capsys):
    def wrong(x, scale=2.0):
        y = x * scale
        y[1, 0] += 0.5
        return {"y": y, "n": int(x.numel())}

    got = course.check(wrong, _ref, inputs=_cases, name="scale-bad")
    out = capsys.readouterr().out
    assert got is _ref
    assert out.startswith("✗ scale-bad failed on case 0: 1 of 6 entries of output['y'] differ beyond tolerance")
    assert "largest difference 0.5 at output['y'][1, 0]: got" in out
    with pytest.raises(AssertionError, match="scale-bad: failed"):
        course.assert_passed("scale-bad")
    with pytest.raises(AssertionError):
        course.check(wrong, _ref, inputs=_cases, name="scale-bad", strict=True)


def test_check_not_attempted_and_errors_never_raise(capsys):
    def stub(x):
        raise NotImplementedError()

    def broken(x):
        return x.nope

    assert course.check(stub, _ref, inputs=_cases, name="stub") is _ref
    assert "… stub: not attempted yet (NotImplementedError)" in capsys.readouterr().out
    assert course.RESULTS["stub"].status == "not attempted"
    assert course.check(broken, _ref, inputs=_cases, name="broken") is _ref
    assert "raised AttributeError" in capsys.readouterr().out


def test_check_isolates_inputs_between_calls():
    def mutating(x, scale=2.0):
        x.mul_(0)  # in place: must not change what the reference sees
        return {"y": torch.ones(3, 2) * scale, "n": 6}

    course.check(mutating, _ref, inputs=[(torch.ones(3, 2),)], name="mutating")
    assert course.RESULTS["mutating"].passed


def test_check_makes_the_reference_and_what_it_wraps_unavailable(capsys):
    from masp_lite.nets import encoders
    from masp_lite.nets.encoders import s_inter as imported_name

    def cases(seed):
        g = torch.Generator().manual_seed(seed)
        return torch.randn(2, 3, 4, generator=g), torch.randn(2, 3, 4, generator=g)

    original = encoders.s_inter
    for answer in (lambda q, k: encoders.s_inter(q, k), lambda q, k: imported_name(q, k)):
        assert course.check(answer, encoders.s_inter, inputs=cases, name="s") is original
        out = capsys.readouterr().out
        assert out.startswith("✗ s failed: your function called the library's encoders.s_inter, which the check "
                              "makes unavailable")
    assert encoders.s_inter is original and imported_name is original  # put back afterwards
    # a notebook-defined wrapper: what it wraps goes in hide=, methods included
    cross = encoders.CrossEncoder(width=4)

    def wrapper(y_a, y_t, d):
        return cross.scores(y_a, y_t, d)

    def via_forward(y_a, y_t, d):
        return torch.softmax(cross(y_a, y_t, d), dim=-1)

    inputs = [(torch.randn(1, 2, 4), torch.randn(1, 3, 4), torch.rand(1, 2, 3))]
    assert course.check(via_forward, wrapper, inputs=inputs, name="c") is via_forward  # passes: nothing hidden
    hide = [encoders.CrossEncoder.scores, encoders.CrossEncoder.forward]
    course.check(via_forward, wrapper, inputs=inputs, name="c", hide=hide)
    assert "CrossEncoder.forward, which the check makes unavailable" in capsys.readouterr().out.splitlines()[-1]
    assert encoders.CrossEncoder.forward.__name__ == "forward" and cross(*inputs[0]).shape == (1, 2, 3)
    with pytest.raises(ValueError, match="hide: expected a list"):
        course.check(via_forward, wrapper, inputs=inputs, name="c", hide="encoders")


def test_a_warning_inside_the_check_is_a_note_on_stdout_not_stderr(capsys):
    def copies(x, scale=2.0):
        x = torch.tensor(x)  # a tensor copied this way warns (UserWarning), a common honest answer
        print("debug", file=sys.stderr)
        return {"y": x * scale, "n": int(x.numel())}

    assert course.check(copies, _ref, inputs=_cases, name="warns", strict=True) is copies
    out, err = capsys.readouterr()
    assert err == ""                                     # nbgrader would score a cell with stderr zero
    assert "✓ warns passed (3 cases)" in out and "debug" in out
    assert out.count("note: your function warned (UserWarning: To copy construct from a tensor") == 1  # once
    assert "warnings cost no points" in out


def test_check_refuses_the_library_function_itself(capsys):
    from masp_lite.nets import encoders

    inputs = [(torch.randn(2, 3, 4), torch.randn(2, 3, 4))]
    assert course.check(encoders.s_inter, encoders.s_inter, inputs=inputs, name="itself") is encoders.s_inter
    assert "your function is the library's own encoders.s_inter" in capsys.readouterr().out
    assert not course.RESULTS["itself"].passed


def test_reveal_shows_the_reference_only_after_the_check_passes(capsys, monkeypatch):
    from masp_lite.nets import encoders

    shown = []
    monkeypatch.setattr("IPython.display.display", lambda obj, **kw: shown.append((obj, kw)))
    course.RESULTS.pop("rev", None)
    course.REVEALED.discard("rev")
    course.reveal("rev", encoders.s_inter)
    assert shown == [] and "appears here once your check passes (not checked yet" in capsys.readouterr().out
    course.check(lambda q, k: None, encoders.s_inter, inputs=[(torch.ones(1, 2, 3), torch.ones(1, 2, 3))], name="rev")
    course.reveal("rev", encoders.s_inter)
    assert shown == [] and "(failed so far)" in capsys.readouterr().out
    course.reveal("rev", encoders.s_inter, now=True)   # asked for: shown, recorded, marked for the grader
    assert "rev" in course.REVEALED and "your grade records it" in capsys.readouterr().out
    assert len(shown) == 1 and shown[0][1] == {"metadata": {course.checking.REVEAL_MARK: "rev"}}
    assert "def s_inter" in shown[0][0].data
    course.RESULTS["rev"] = course.Outcome("rev", "passed", "✓")  # as a passed check leaves it
    course.reveal("rev", encoders.s_inter)
    assert len(shown) == 2 and shown[1][1] == {} and "def s_inter" in shown[1][0].data
    with pytest.raises(ValueError, match="reveal: expected"):
        course.reveal("rev")


def test_a_failed_graded_cell_is_one_line():
    with pytest.raises(AssertionError) as info:
        course.assert_passed("never-checked-either")
    assert isinstance(info.value, course.ExerciseNotPassed)
    assert info.value._render_traceback_() == [
        "\x1b[0;31mExerciseNotPassed\x1b[0m: never-checked-either: not checked yet; run the check cell above first"]


def test_compare_structures_and_tolerances():
    assert course.compare(np.array([1.0, 2.0]), np.array([1.0, 2.0 + 1e-9])) is None
    assert "got shape (2,), expected (3,)" in course.compare(np.zeros(2), np.zeros(3))
    assert "got 2 items, expected 3" in course.compare([1, 2], [1, 2, 3])
    assert "keys differ" in course.compare({"a": 1}, {"b": 1})
    assert "got a list, expected a tensor" in course.compare([1.0], torch.ones(1))
    assert course.compare(torch.tensor(0.5), 0.5) is None
    assert "expected 0.6" in course.compare(0.5, 0.6)
    assert "got True" in course.compare(torch.tensor([True]), torch.tensor([False]))
    assert course.compare(torch.tensor(3), 3) is None and "expected 4" in course.compare(3, 4)
    assert "expected 'a'" in course.compare(np.zeros(2), "a")
    assert course.compare(float("nan"), float("nan")) is None


def test_check_rejects_bad_arguments():
    with pytest.raises(ValueError, match="expected two functions"):
        course.check(1, _ref, inputs=_cases, name="x")
    with pytest.raises(ValueError, match="non-empty list of cases"):
        course.check(_ref, _ref, inputs=[], name="x")
    with pytest.raises(ValueError, match="exercise name"):
        course.check(_ref, _ref, inputs=_cases, name="")
    with pytest.raises(AssertionError, match="not checked yet"):
        course.assert_passed("never-checked")


# ------------------------------------------------------------ session helpers
def test_fast_mode_reads_environment(monkeypatch):
    monkeypatch.setenv(course.FAST_ENV, "1")
    assert course.fast_mode() is True
    monkeypatch.setenv(course.FAST_ENV, "0")
    assert course.fast_mode() is False
    monkeypatch.delenv(course.FAST_ENV)
    assert course.fast_mode() is False  # learners get full budgets by default
    monkeypatch.setenv(course.FAST_ENV, "maybe")
    with pytest.raises(ValueError, match="expected 1"):
        course.fast_mode()


def test_setup_seeds_everything_and_sets_threads():
    before = torch.get_num_threads()
    try:
        course.setup(seed=3, threads=1)
        a = (torch.rand(2), np.random.rand(2))
        course.setup(seed=3, threads=1)
        b = (torch.rand(2), np.random.rand(2))
        assert torch.equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        assert torch.get_num_threads() == 1
        with pytest.raises(ValueError, match="seed"):
            course.setup(seed=-1)
    finally:
        torch.set_num_threads(before)


def test_show_returns_source_of_library_code():
    shown = course.show(course.check)
    assert "def check(" in getattr(shown, "data", shown)
    with pytest.raises(ValueError, match="with source"):
        course.show(3)


# --------------------------------------------------------- authoring + generate
def _toy_notebook():
    A = authoring
    return A.notebook([
        A.markdown("# Chapter 99: Toy"),
        A.markdown("## Objectives\n- add numbers\n\nPrerequisites: none."),
        A.markdown("## Setup"),
        A.code("import masp_lite.course as course\ncourse.setup(seed=0)\nFAST = course.fast_mode()"),
        A.markdown("## Section 1: Adding (~5 min)"),
        A.code("print(1 + 1)"),
        A.markdown("### Exercise 1: add two numbers"),
        A.solution("def add(a, b):\n    ### BEGIN SOLUTION\n    return a + b\n    ### END SOLUTION", "add"),
        A.graded("added = course.check(add, lambda a, b: a + b, inputs=[(1, 2)], name='add')\n"
                 "course.assert_passed('add')", "check_add", points=1),
        A.markdown("## Section 2: Adding more (~5 min)"),
        A.code("print(added(1, 2) + 3)"),
        A.markdown("## Summary\nDone."),
    ])


def test_toy_notebook_has_the_skeleton_and_a_broken_one_does_not():
    nb = _toy_notebook()
    assert authoring.problems(nb) == []
    nb.cells = [c for c in nb.cells if not c.source.startswith("## Summary")]
    assert any("## Summary" in p for p in authoring.problems(nb))
    nb = _toy_notebook()
    nb.cells[5].source = 'data = open("/home/someone/data.csv")\nwin = r"C:\\Users\\someone"'
    found = [p for p in authoring.problems(nb) if "machine-specific path" in p]
    assert found == ["cell 5: contains a machine-specific path"]
    nb.cells[5].source = 'url = "https://example.org/a/b"'
    assert authoring.problems(nb) == []
    with pytest.raises(ValueError, match="BEGIN SOLUTION"):
        authoring.solution("def f(): pass", "f")
    with pytest.raises(ValueError, match="grade_id"):
        authoring.graded("assert True", "bad id")


def _moved(nb, start, stop, before):
    """``nb`` with its cells ``start:stop`` moved in front of cell ``before`` (indices of the original)."""
    cells = list(nb.cells)
    block, rest = cells[start:stop], cells[:start] + cells[stop:]
    at = rest.index(cells[before]) if before < len(cells) else len(rest)
    nb.cells = rest[:at] + block + rest[at:]
    return nb


def test_exercises_sit_right_after_their_section_not_after_the_summary():
    A = authoring
    # the old layout: the exercise waits under '## Exercises' after the summary
    nb = _moved(_toy_notebook(), 6, 9, before=12)
    nb.cells[-3].source = "## Exercises\n\n### Exercise 1: add two numbers"
    found = authoring.problems(nb)
    assert "cell 9: '## Exercises' after '## Summary': the summary ends the chapter " \
           "(exercises go right after the section they practise)" in found
    assert "cell 10: exercise cells belong inside the section they practise, right after its lesson " \
           "(before '## Summary')" in found
    # a graded check in another section than its solution; a solution without its heading
    nb = _moved(_toy_notebook(), 8, 9, before=10)
    assert any("without its graded check cell after it in the same section" in p for p in authoring.problems(nb))
    nb = _toy_notebook()
    nb.cells[6].source = "Now write it yourself."
    assert any("without a '### Exercise K: ...' heading" in p for p in authoring.problems(nb))
    nb = _toy_notebook()
    nb.cells[6].source = "### Exercise 2: add two numbers"
    assert any("expected '### Exercise 1', '### Exercise 2', ... in order, got [2]" in p
               for p in authoring.problems(nb))
    # an exercise before the first section (in the setup) is out of place too
    nb = _moved(_toy_notebook(), 6, 9, before=4)
    assert any("belong inside the section they practise" in p for p in authoring.problems(nb))
    assert A.problems(_toy_notebook()) == []


def test_learner_version_has_stubs_tags_and_no_solutions(tmp_path):
    src = tmp_path / "99_toy.ipynb"
    nbformat.write(_toy_notebook(), src)
    out = generate.generate(src, tmp_path / "learner")
    learner = nbformat.read(out, as_version=4)
    sol = learner.cells[7]
    assert "return a + b" not in sol.source and "raise NotImplementedError()" in sol.source
    compile(sol.source, "stub", "exec")  # stubs stay valid Python
    grade = learner.cells[8]
    assert "raises-exception" in grade.metadata["tags"]
    assert grade.metadata["editable"] is False and len(grade.metadata["nbgrader"]["checksum"]) == 32
    with pytest.raises(ValueError, match="instructor notebook"):
        generate.generate(tmp_path / "missing.ipynb", tmp_path)


# ------------------------------------------------------------ shipped chapters
@pytest.mark.parametrize("path", SOLUTIONS, ids=[p.stem for p in SOLUTIONS])
def test_chapter_skeleton(path):
    nb = nbformat.read(path, as_version=4)
    assert authoring.problems(nb) == []


@pytest.mark.parametrize("path", SOLUTIONS, ids=[p.stem for p in SOLUTIONS])
def test_shell_commands_say_how_to_run_them(path):
    """A command for a shell is spelt `.venv/bin/python -m ...` (a bare `python` outside the course's
    environment has no torch), and a chapter that gives one says where to run it and how to activate."""
    text = "\n".join(c.source for c in nbformat.read(path, as_version=4).cells)
    bare = [m.group(0) for m in re.finditer(r"(?<![\w/.-])python3? -m [\w.]+", text)]
    assert bare == [], f"spell these as .venv/bin/python -m ...: {bare}"
    if ".venv/bin/python -m" in text:
        assert "repository root" in text and "source .venv/bin/activate" in text


@pytest.mark.parametrize("path", SOLUTIONS, ids=[p.stem for p in SOLUTIONS])
def test_learner_stubs_are_valid_python_without_solutions(path):
    shipped = ROOT / "notebooks" / path.name
    assert shipped.is_file(), f"no learner version of {path.name}: run python -m masp_lite.course.generate"
    learner = nbformat.read(shipped, as_version=4)
    solution_cells = [c for c in learner.cells if c.metadata.get("nbgrader", {}).get("solution")]
    assert solution_cells
    for cell in learner.cells:
        assert "BEGIN SOLUTION" not in cell.source and "END SOLUTION" not in cell.source
        if cell.cell_type == "code":
            python = TransformerManager().transform_cell(cell.source)  # IPython magics -> Python
            compile(python, f"{path.name} cell {cell.id}", "exec")
    assert all("raise NotImplementedError()" in c.source for c in solution_cells)


def test_generate_check_reports_stale_notebooks(tmp_path, capsys):
    (tmp_path / "solutions").mkdir()
    nbformat.write(_toy_notebook(), tmp_path / "solutions" / "99_toy.ipynb")
    args = ["--solutions", str(tmp_path / "solutions"), "--notebooks", str(tmp_path / "notebooks")]
    assert generate.main(args + ["--check"]) == 1
    assert "stale: 99_toy.ipynb" in capsys.readouterr().out
    assert generate.main(args) == 0 and generate.main(args + ["--check"]) == 0
    assert generate.main(["--solutions", str(tmp_path / "nothing")]) == 2


def test_learner_notebooks_are_in_sync_with_solutions():
    assert SOLUTIONS, "expected instructor notebooks in solutions/"
    assert generate.stale(ROOT / "solutions", ROOT / "notebooks") == [], "run: python -m masp_lite.course.generate"
    shipped = sorted(p.name for p in (ROOT / "notebooks").glob("*.ipynb"))
    assert shipped == [p.name for p in SOLUTIONS], "every learner notebook needs an instructor version"


def test_nbgrader_generate_assignment_accepts_solutions_and_agrees(tmp_path):
    """nbgrader's own generate_assignment takes the instructor notebooks and releases exactly
    our learner notebooks, apart from the ``raises-exception`` tag we add to graded cells."""
    source = tmp_path / "source" / "course"
    source.mkdir(parents=True)
    for path in SOLUTIONS:
        (source / path.name).write_bytes(path.read_bytes())
    (tmp_path / "nbgrader_config.py").write_text(
        f"c = get_config()\nc.CourseDirectory.root = {str(tmp_path)!r}\nc.CourseDirectory.course_id = 'masp'\n")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    proc = subprocess.run([sys.executable, "-m", "nbgrader", "generate_assignment", "course", "--force"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for path in SOLUTIONS:
        released = nbformat.read(tmp_path / "release" / "course" / path.name, as_version=4)
        ours = nbformat.read(ROOT / "notebooks" / path.name, as_version=4)
        assert [c.source for c in released.cells] == [c.source for c in ours.cells]
        for r, o in zip(released.cells, ours.cells):
            meta = dict(o.metadata)
            if "nbgrader" in meta and meta["nbgrader"].get("grade"):
                assert meta.pop("tags") == ["raises-exception"]
            assert dict(r.metadata) == meta


def test_every_chapter_is_listed_in_the_course_maps():
    """notebooks/README.md's table, the README's chapter list and chapter 00's course map name every chapter."""
    numbers = [p.stem.split("_", 1)[0] for p in SOLUTIONS]
    table = (ROOT / "notebooks" / "README.md").read_text(encoding="utf-8")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    readme = readme[readme.index("## The course"):readme.index("Every chapter follows the same pattern")]
    tour = nbformat.read(ROOT / "solutions" / "00_tour.ipynb", as_version=4)
    course_map = next(c.source for c in tour.cells if c.cell_type == "markdown" and "| chapter | builds |" in c.source)
    for number, path in zip(numbers, SOLUTIONS):
        assert f"`{path.name}`" in table, f"notebooks/README.md does not list {path.name}"
        listed = f"chapter {number})" in readme or f"chapter {number};" in readme
        assert listed, f"README.md does not list chapter {number}"
        if number != "00":
            assert f"\n| {number} " in course_map, f"chapter 00's course map does not list chapter {number}"
