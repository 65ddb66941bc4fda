"""Autograding a learner cannot steer: nbgrader preprocessors that grade the release, not the submission.

``nbgrader autograde`` runs a submitted notebook as it is and scores each graded cell by
"did it raise". A learner's notebook can steer that run: edit the unlocked cells that build a
check's inputs or its reference, add cells that patch the checker, strip or delete cells.
The course folder's ``nbgrader_config.py`` (:mod:`masp_lite.course.classroom`) adds three
preprocessors and one export plugin, so that the run is the instructor's:

:class:`UseReleaseCells` (first of autograde's *sanitize* steps)
    rebuilds the submission from the release: every cell comes from
    ``release/<chapter>/<chapter>.ipynb`` except the answer (solution) cells, taken from the
    submission by ``grade_id`` (or, when the learner stripped their nbgrader metadata, by
    cell id). Cells the learner added are dropped and edited cells are graded as released
    (both noted); a deleted answer cell is graded as the release's stub. Each answer cell
    is screened (:func:`screen`); a screened answer is not run: its code is kept as
    comments above the release's stub. What it found goes in
    the notebook's metadata (``masp_lite_grading``) for the next two steps.
:class:`ReportGrading` (right after ``Execute``)
    writes what was found into the graded cells' outputs, which the feedback shows: a
    stdout ``⚑`` note (deleted or stripped cells, added cells dropped, an answer shown
    before it was earned) or, for a screened answer graded zero, an error output with the
    one-line reason (nbgrader scores a cell with an error zero).
:class:`RecordGrading` (right after ``SaveAutoGrades``)
    sends a screened answer's graded cell to manual grading when the instructor chose
    ``c.UseReleaseCells.screened = "manual"`` (the default is ``"zero"``), and keeps every
    note in the gradebook as the answer cell's comment.
:class:`ExportWithNotes` (``c.ExportApp.plugin_class``)
    writes nbgrader's ``grades.csv`` and prints every note, one line each.

:func:`screen` is static: an answer cell may hold imports of the numerical libraries and of
``masp_lite`` (never ``masp_lite.course``), function definitions, constants and docstrings, and no name
or attribute that reaches the checker, the interpreter's internals, IPython or files. This
refuses each family of forgery seen in practice — the reference copied at run time
(introspection, a reloaded module, a default argument or module-level holder, a rebuilt
function), the solutions read from disk, the checker or its results patched, cells rewritten
through IPython's hooks — while the course's own solutions all pass (``tests/test_classroom.py``).
"""
from __future__ import annotations

import ast
import os
import re

import nbformat
from nbgrader.api import Gradebook, MissingEntry
from nbgrader.coursedir import CourseDirectory
from nbgrader.plugins.export import CsvExportPlugin
from nbgrader.preprocessors.base import NbGraderPreprocessor
from nbgrader.utils import is_grade, is_solution
from traitlets import Enum

from ..files import read_bounded
from .checking import REVEAL_MARK

__all__ = ["screen", "UseReleaseCells", "ReportGrading", "RecordGrading", "ExportWithNotes", "NOTE", "META"]

#: Every note the grader writes starts with this mark (feedback, gradebook comments, export's output).
NOTE = "⚑"
#: The notebook metadata key that carries the findings from the sanitize step to the grading steps.
META = "masp_lite_grading"

#: Top-level packages an answer may import.
ALLOWED_IMPORTS = frozenset({"math", "cmath", "itertools", "functools", "collections", "heapq", "bisect",
                             "dataclasses", "typing", "random", "statistics", "numpy", "torch", "scipy",
                             "masp_lite"})
#: Names an answer may not use: the checker, the interpreter's doors to code and files, IPython's history.
FORBIDDEN_NAMES = frozenset({
    "get_ipython", "eval", "exec", "compile", "open", "__import__", "globals", "locals", "vars", "getattr",
    "setattr", "delattr", "breakpoint", "input", "memoryview", "exit", "quit", "help", "__builtins__",
    "os", "sys", "io", "pathlib", "Path", "shutil", "subprocess", "inspect", "importlib", "gc", "types",
    "builtins", "ctypes", "marshal", "pickle", "dill", "nbformat", "json", "IPython", "display",
    "course", "checking", "grading", "RESULTS", "REVEALED", "Outcome", "check", "assert_passed", "reveal",
    "In", "Out", "_ih", "_oh", "_dh", "_i", "_ii", "_iii", "__", "___"})
#: Attributes an answer may not read or write, besides the names above (``torch.os`` is ``os``), every
#: ``__dunder__`` but ``__init__``, and private ``_x``: frames and closures, files, compiled or downloaded code.
FORBIDDEN_ATTRIBUTES = FORBIDDEN_NAMES | frozenset({
    "f_globals", "f_locals", "f_back", "f_code", "gi_frame", "cr_frame", "tb_frame", "cell_contents",
    "co_code", "func_globals", "read", "readline", "readlines", "read_text", "read_bytes", "load", "loads",
    "loadtxt", "genfromtxt", "fromfile", "from_file", "memmap", "loadmat", "listdir", "scandir", "walk", "glob",
    "write", "write_text", "write_bytes", "save", "savetxt", "savez", "tofile", "system", "popen", "getsource",
    "modules", "reload", "load_inline", "load_library", "cpp_extension", "ctypeslib", "hub"})
_HISTORY = re.compile(r"^_(i+|i?\d+)$")  # IPython's _i3, _12, _ii
_DISK = re.compile(r"solutions|\.ipynb|source[/\\]|release[/\\]|autograded|gradebook")


def _bad_name(name: str) -> bool:
    return name in FORBIDDEN_NAMES or bool(_HISTORY.match(name))


def _bad_attribute(attr: str) -> bool:
    if attr == "__init__":
        return False
    return attr in FORBIDDEN_ATTRIBUTES or attr.startswith("_")


def _constant(node) -> bool:
    try:
        ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return False
    return True


def _decorator_ok(node) -> bool:
    """``@name``, ``@a.b`` or ``@a.b(constants)`` (``@torch.no_grad()``), nothing computed."""
    if isinstance(node, ast.Call):
        return _decorator_ok(node.func) and all(_constant(a) for a in node.args) and \
            all(_constant(k.value) for k in node.keywords)
    while isinstance(node, ast.Attribute):
        node = node.value
    return isinstance(node, ast.Name)


def _top_level(node) -> str | None:
    """Why a statement may not stand at an answer cell's top level, or ``None``."""
    if isinstance(node, ast.Import):
        bad = [a.name for a in node.names if not _import_ok(a.name)]
        return f"imports {bad[0]}" if bad else None
    if isinstance(node, ast.ImportFrom):
        return None if node.level == 0 and _import_ok(node.module or "") else f"imports from {node.module or '.'}"
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
        if any(not _decorator_ok(d) for d in node.decorator_list):
            return f"decorates {node.name} with a computed decorator, which can replace it"
        defaults = [d for d in node.args.defaults + node.args.kw_defaults if d is not None]
        if any(not _constant(d) for d in defaults):
            return f"gives {node.name} a default argument that is not a constant (a holder for another function)"
        if node.name.startswith("__") and node.name.endswith("__"):
            return f"defines {node.name}"
        return None
    if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
        return None  # a docstring or a bare constant
    if isinstance(node, ast.Pass):
        return None
    if isinstance(node, (ast.Assign, ast.AnnAssign)):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        if all(isinstance(t, ast.Name) for t in targets) and node.value is not None and _constant(node.value):
            return None
        return "assigns something other than a constant at the top level (a holder kept before the check runs)"
    return f"runs a {type(node).__name__.lower()} statement at the top level (an answer holds imports, defs, constants)"


def _import_ok(module: str) -> bool:
    root = module.split(".")[0]
    return root in ALLOWED_IMPORTS and not (module == "masp_lite.course" or module.startswith("masp_lite.course."))


def screen(source: str) -> str | None:
    """Why answer cell ``source`` looks forged — one short clause — or ``None`` when it may be run.

    >>> screen("def f(x):\\n    return x * 2") is None
    True
    >>> screen("import inspect\\ndef f(x):\\n    return x")
    'imports inspect'
    """
    try:
        tree = ast.parse(source)
    except SyntaxError as e:
        return f"is not plain Python (line {e.lineno}: {e.msg}); magics and shell commands are not answers"
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Module)) and n.body
                  and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and _bad_name(node.id):
            return f"uses {node.id}, which reaches the checker, the interpreter or files"
        if isinstance(node, ast.Attribute) and _bad_attribute(node.attr):
            return f"uses the attribute .{node.attr}, which reaches the checker, the interpreter or files"
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or "."]
            bad = [n for n in names if not _import_ok(n) or (isinstance(node, ast.ImportFrom) and node.level)]
            if bad:
                return f"imports {bad[0]}"
            if isinstance(node, ast.ImportFrom) and any(_bad_name(a.name) or _bad_attribute(a.name)
                                                        for a in node.names):
                return f"imports {', '.join(a.name for a in node.names)} from {node.module}"
        if isinstance(node, (ast.Global, ast.Nonlocal)):
            return f"rebinds names outside its function ({type(node).__name__.lower()} {', '.join(node.names)})"
        if isinstance(node, ast.ClassDef):
            return f"defines a class ({node.name}); an answer is a function"
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            text = node.value
            if _DISK.search(text):
                return f"names the course's files ({text[:40]!r})"
            if re.search(r"__\w+__", text) or re.search(r"\{[^{}]*[.\[][^{}]*\}", text):
                return f"holds {text[:40]!r}, a dunder name or a format field that reads attributes"
            if re.fullmatch(r"[A-Za-z_]\w*", text) and (_bad_name(text) or _bad_attribute(text)):
                return f"spells out {text!r}, a name it may not use"
    for node in tree.body:
        why = _top_level(node)
        if why:
            return why
    return None


# ------------------------------------------------------------------ the sanitize step
def _gid(cell) -> str | None:
    return cell.metadata.get("nbgrader", {}).get("grade_id")


def _exercise_of(release_cells) -> dict[str, str]:
    """Each answer cell's grade_id -> the grade_id of the graded cell that checks it (the next graded cell)."""
    out, pending = {}, []
    for cell in release_cells:
        if is_solution(cell):
            pending.append(_gid(cell))
        elif is_grade(cell):
            for gid in pending:
                out[gid] = _gid(cell)
            pending = []
    return out


def _revealed(submission) -> list[str]:
    """The exercises whose reference the submission's outputs or code show as asked for early."""
    names = []
    for cell in submission.cells:
        for out in cell.get("outputs", []):
            name = (out.get("metadata") or {}).get(REVEAL_MARK)
            if isinstance(name, str) and name not in names:
                names.append(name)
        if cell.cell_type != "code":
            continue
        try:
            tree = ast.parse(cell.source)
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and ast.unparse(node.func).endswith("reveal") and node.args
                    and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
                    and any(k.arg == "now" and not (isinstance(k.value, ast.Constant) and not k.value.value)
                            for k in node.keywords)
                    and node.args[0].value not in names):
                names.append(node.args[0].value)
    return names


def _commented(source: str, why: str) -> str:
    lines = [f"# {NOTE} screened, not run: this answer {why}.", "# The answer as submitted:"]
    lines += [f"#   {line}" for line in source.splitlines()]
    return "\n".join(lines)


def _find(rcell, by_gid, by_id):
    """The submission's cell for release cell ``rcell`` (by grade_id, else by cell id); a note unless by grade_id."""
    gid = _gid(rcell)
    sub = by_gid.get(gid)
    if sub is not None and is_solution(sub) == is_solution(rcell) and is_grade(sub) == is_grade(rcell):
        return sub, None
    what = "answer cell" if is_solution(rcell) else "check cell"
    stripped = by_id.get(rcell.get("id"))
    if stripped is not None and stripped.cell_type == rcell.cell_type and not _gid(stripped):
        then = " and graded" if is_solution(rcell) else "; the release's check was run"
        return stripped, f"{NOTE} the {what} '{gid}' had lost its nbgrader metadata: found by its cell id{then}"
    then = "graded as not attempted" if is_solution(rcell) else "the release's check was run"
    return None, f"{NOTE} the {what} '{gid}' was deleted from the submission: {then}"


class UseReleaseCells(NbGraderPreprocessor):
    """Grade the release with the submission's answer cells (screened), and note what differs."""

    screened = Enum(["zero", "manual"], default_value="zero",
                    help="what a screened answer gets: zero (with its reason in the feedback) or manual grading"
                    ).tag(config=True)

    def _release(self, resources):
        info = resources["nbgrader"]
        coursedir = CourseDirectory(config=self.config)
        path = os.path.join(coursedir.format_path(coursedir.release_directory, ".", info["assignment"]),
                            f"{info['notebook']}.ipynb")
        if not os.path.isfile(path):
            raise FileNotFoundError(f"UseReleaseCells: the release {path} is missing: run nbgrader "
                                    f"generate_assignment {info['assignment']} first")
        return nbformat.reads(read_bounded(path, what="release notebook").decode(), as_version=4)

    def preprocess(self, nb, resources):
        release = self._release(resources)
        by_gid = {_gid(c): c for c in nb.cells if _gid(c)}
        by_id = {c.get("id"): c for c in nb.cells if c.get("id")}
        exercise = _exercise_of(release.cells)
        notes: dict[str, list[str]] = {}   # graded cell grade_id -> notes
        screened: dict[str, str] = {}      # graded cell grade_id -> why
        used, cells = set(), []
        graded_after = {}  # release cell index -> the next graded cell's grade_id
        following = None
        for i in range(len(release.cells) - 1, -1, -1):
            following = _gid(release.cells[i]) if is_grade(release.cells[i]) else following
            graded_after[i] = following
        for i, rcell in enumerate(release.cells):
            cell = nbformat.from_dict(rcell)  # a copy
            gid = _gid(rcell)
            if gid is None:
                sub = by_id.get(rcell.get("id"))
                if sub is not None and not _gid(sub):
                    used.add(id(sub))
                    if sub.source != rcell.source and rcell.cell_type == "code" and graded_after[i]:
                        notes.setdefault(graded_after[i], []).append(
                            f"{NOTE} the cell '{rcell.get('id')}' differs from the release (its inputs or "
                            "reference, say): graded as released")
                cells.append(cell)
                continue
            sub, note = _find(rcell, by_gid, by_id)
            if note:
                notes.setdefault(exercise.get(gid, gid), []).append(note)
            if sub is not None:
                used.add(id(sub))
            if is_solution(rcell) and sub is not None:
                why = screen(sub.source)
                if why:
                    screened[exercise.get(gid, gid)] = f"the answer cell '{gid}' {why}"
                    cell.source = _commented(sub.source, why) + "\n" + rcell.source
                else:
                    cell.source = sub.source
            cells.append(cell)
        added = [c for c in nb.cells if id(c) not in used and c.cell_type == "code" and c.source.strip()]
        graded = [_gid(c) for c in release.cells if is_grade(c)]
        if added and graded:
            notes.setdefault(graded[0], []).append(
                f"{NOTE} {len(added)} code cell(s) you added were not run in grading: "
                "an answer cell must hold everything its function needs")
        for name in _revealed(nb):
            owner = next((_gid(c) for c in release.cells if is_grade(c) and
                          (f'"{name}"' in c.source or f"'{name}'" in c.source)), graded[0] if graded else None)
            if owner:
                notes.setdefault(owner, []).append(f"{NOTE} you asked to see the library's version of '{name}' "
                                                   "before your check passed")
        for owner, why in screened.items():
            self.log.warning("%s: screened: %s", resources["nbgrader"].get("student"), why)
        nb.cells = cells
        nb.metadata[META] = {"notes": notes, "screened": screened, "action": self.screened}
        return nb, resources


# ------------------------------------------------------------------ the grading steps
class ReportGrading(NbGraderPreprocessor):
    """After execution: the notes as stdout in their graded cells, a screened answer's reason as an error."""

    def preprocess(self, nb, resources):
        found = nb.metadata.get(META, {})
        resources[META] = found
        return super().preprocess(nb, resources)

    def preprocess_cell(self, cell, resources, index):
        found = resources.get(META, {})
        gid = _gid(cell)
        if not is_grade(cell) or cell.cell_type != "code":
            return cell, resources
        lines = list(found.get("notes", {}).get(gid, []))
        why = found.get("screened", {}).get(gid)
        if why and found.get("action") == "manual":
            lines.append(f"{NOTE} screened, sent to manual grading: {why}")
        if lines:
            cell.outputs.append(nbformat.v4.new_output("stream", name="stdout", text="\n".join(lines) + "\n"))
        if why and found.get("action") != "manual":
            cell.outputs.append(nbformat.v4.new_output("error", ename="ScreenedAnswer",
                                                       evalue=f"{NOTE} scored zero: {why}", traceback=[
                                                           f"ScreenedAnswer: {NOTE} scored zero: {why}"]))
        return cell, resources


class RecordGrading(NbGraderPreprocessor):
    """After ``SaveAutoGrades``: screened answers to manual grading (when so configured), notes as comments."""

    def preprocess(self, nb, resources):
        found = resources.get(META) or nb.metadata.get(META, {})
        info = resources["nbgrader"]
        answer_of = {}  # graded cell -> its answer cell
        pending = []
        for cell in nb.cells:
            if is_solution(cell):
                pending.append(_gid(cell))
            elif is_grade(cell):
                answer_of[_gid(cell)] = pending[-1] if pending else None
                pending = []
        with Gradebook(info["db_url"]) as gb:
            for gid in found.get("screened", {}) if found.get("action") == "manual" else []:
                grade = gb.find_grade(gid, info["notebook"], info["assignment"], info["student"])
                grade.auto_score = None
                grade.needs_manual_grade = True
            texts = {g: list(n) for g, n in found.get("notes", {}).items()}
            for gid, why in found.get("screened", {}).items():
                verdict = "sent to manual grading" if found.get("action") == "manual" else "scored zero"
                texts.setdefault(gid, []).append(f"{NOTE} screened, {verdict}: {why}")
            for gid, lines in texts.items():
                answer = answer_of.get(gid)
                if answer is None:
                    continue
                try:
                    comment = gb.find_comment(answer, info["notebook"], info["assignment"], info["student"])
                except MissingEntry:
                    continue
                comment.auto_comment = "\n".join(lines)
            gb.db.commit()
        return nb, resources


class ExportWithNotes(CsvExportPlugin):
    """nbgrader's ``grades.csv``, then one line per note (deleted, stripped, screened, looked early) on stdout."""

    def export(self, gradebook):
        super().export(gradebook)
        for student, assignment, notebook, text in _notes(gradebook):
            if self.student and student not in self.student or self.assignment and assignment not in self.assignment:
                continue
            for line in text.splitlines():
                print(f"{student} {assignment}/{notebook}: {line}")


def _notes(gradebook):
    """``(student, assignment, notebook, text)`` for every grading note in the gradebook."""
    from nbgrader.api import Comment

    for comment in gradebook.db.query(Comment).all():
        text = comment.auto_comment or ""
        if NOTE in text:
            nb = comment.notebook
            yield nb.student.id, nb.assignment.name, nb.name, text
