"""Building chapter notebooks with correct nbgrader metadata, and checking their skeleton.

Cell builders (:func:`markdown`, :func:`code`, :func:`solution`, :func:`graded`,
:func:`notebook`) write nbgrader 0.9.6's cell metadata (schema version 3) so that
``nbgrader generate_assignment`` and ``nbgrader autograde`` accept the instructor
notebooks as they are:

=============  ============================================================================
cell           ``metadata.nbgrader``
=============  ============================================================================
solution       ``{grade: false, solution: true, locked: false, grade_id, schema_version: 3}``
graded check   ``{grade: true, solution: false, locked: true, points, grade_id, schema_version: 3}``
=============  ============================================================================

:func:`problems` lists what a chapter is missing from the course skeleton (Neuromatch
style): a ``# Chapter NN: …`` title (``NN``: two digits, with a letter after them for a
chapter slotted in between, ``04b``); ``## Objectives`` (naming the prerequisites);
``## Setup`` whose first code cell calls ``course.setup(`` and ``course.fast_mode()``;
one or more ``## Section N: … (~M min)``; ``## Summary`` as the last level-2 heading.
Each exercise sits right after the section that teaches it, inside that section: a
``### Exercise K: …`` heading (K = 1, 2, … through the chapter), its solution cell
(``### BEGIN SOLUTION`` … ``### END SOLUTION``) and, before the next section, its
graded check cell — so no exercise waits at the end of the chapter, far from its concept.
Notebooks are shipped without outputs and without machine-specific paths.
"""
from __future__ import annotations

import re

import nbformat
from nbgrader.nbgraderformat import MetadataValidator, ValidationError

__all__ = ["markdown", "code", "solution", "graded", "notebook", "problems", "HEADINGS"]

#: The level-2 headings every chapter has, in this order (sections go between Setup and Summary, exercises
#: inside the sections they practise; nothing follows the Summary).
HEADINGS = ("Objectives", "Setup", "Section", "Summary")

_SECTION = re.compile(r"^## Section \d+: .+\(~?\s*\d+\s*min(utes)?\)\s*$")
_EXERCISE = re.compile(r"^### Exercise (\d+): \S", re.MULTILINE)
_PATHS = re.compile(r"""["'](?:/|[A-Za-z]:\\+)[\w.-]+[/\\]""")  # a quoted absolute path


def markdown(text: str) -> nbformat.NotebookNode:
    """A plain markdown cell."""
    return nbformat.v4.new_markdown_cell(text.strip("\n"))


def code(text: str) -> nbformat.NotebookNode:
    """A plain code cell (run in both versions; not graded)."""
    return nbformat.v4.new_code_cell(text.strip("\n"))


def _grade_id(grade_id):
    if not isinstance(grade_id, str) or not re.fullmatch(r"[a-zA-Z0-9_\-]+", grade_id):
        raise ValueError(f"grade_id: expected letters, digits, '_' or '-', got {grade_id!r}")
    return grade_id


def solution(text: str, grade_id: str) -> nbformat.NotebookNode:
    """An exercise cell: the solution between ``### BEGIN SOLUTION`` / ``### END SOLUTION``."""
    if "### BEGIN SOLUTION" not in text or "### END SOLUTION" not in text:
        raise ValueError(f"solution {grade_id!r}: expected '### BEGIN SOLUTION' and '### END SOLUTION' markers")
    cell = code(text)
    cell.metadata["nbgrader"] = {"grade": False, "solution": True, "locked": False,
                                 "grade_id": _grade_id(grade_id), "schema_version": 3}
    return cell


def graded(text: str, grade_id: str, points: float = 1) -> nbformat.NotebookNode:
    """A graded check cell, worth ``points`` when it runs without raising."""
    if not isinstance(points, (int, float)) or isinstance(points, bool) or points <= 0:
        raise ValueError(f"graded {grade_id!r}: expected points > 0, got {points!r}")
    cell = code(text)
    cell.metadata["nbgrader"] = {"grade": True, "solution": False, "locked": True, "points": points,
                                 "grade_id": _grade_id(grade_id), "schema_version": 3}
    return cell


def notebook(cells) -> nbformat.NotebookNode:
    """A Python 3 notebook of ``cells`` with stable cell ids (``c00``, ``c01``, …)."""
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"display_name": "Python 3", "language": "python", "name": "python3"}
    nb.metadata["language_info"] = {"name": "python"}
    nb.cells = list(cells)
    for i, cell in enumerate(nb.cells):
        cell["id"] = f"c{i:02d}"
    nbformat.validate(nb)
    MetadataValidator().validate_nb(nb)
    return nb


def _headings(cell):
    return [line.strip() for line in cell.source.splitlines() if line.startswith("## ")]


def _exercise_problems(cells, sols, grades) -> list[str]:
    """Where the exercises sit: each inside a section, headed, followed by its check; nothing after the Summary."""
    out, section, summary = [], {}, False  # section: cell index -> the cell of the '## Section' it lies in (or None)
    current = None
    for i, cell in enumerate(cells):
        for h in _headings(cell) if cell.cell_type == "markdown" else []:
            if summary:
                out.append(f"cell {i}: {h!r} after '## Summary': the summary ends the chapter "
                           "(exercises go right after the section they practise)")
            summary = summary or h.startswith("## Summary")
            current = i if h.startswith("## Section") else None
        section[i] = current
    numbers, headed = [], False  # headed: an '### Exercise K:' heading waits for its solution cell
    for i, cell in enumerate(cells):
        if cell.cell_type == "markdown":
            headed = headed and not _headings(cell)
            found = [int(k) for k in _EXERCISE.findall(cell.source)]
            numbers += found
            headed = headed or bool(found)
        if (i in sols or i in grades) and section[i] is None:
            out.append(f"cell {i}: exercise cells belong inside the section they practise, right after its "
                       "lesson (before '## Summary')")
        if i in sols:
            if not headed:
                out.append(f"cell {i}: solution cell without a '### Exercise K: ...' heading above it in its section")
            headed = False
            check = next((j for j in grades if j > i), None)
            later = next((j for j in sols if j > i), len(cells))
            if check is None or check > later or section[check] != section[i]:
                out.append(f"cell {i}: solution cell without its graded check cell after it in the same section")
    if numbers != list(range(1, len(numbers) + 1)):
        out.append(f"exercise headings: expected '### Exercise 1', '### Exercise 2', ... in order, got {numbers}")
    return out


def problems(nb: nbformat.NotebookNode) -> list[str]:
    """What ``nb`` (an instructor notebook) lacks from the course skeleton; empty when complete."""
    out: list[str] = []
    cells = nb.cells
    if not cells or cells[0].cell_type != "markdown" or not re.match(r"# Chapter \d\d[a-z]?: ", cells[0].source):
        out.append("first cell: expected a markdown title '# Chapter NN: ...'")
    try:
        MetadataValidator().validate_nb(nb)
    except ValidationError as e:
        out.append(f"nbgrader metadata: {e}")
    # where each skeleton heading first appears
    first: dict[str, int] = {}
    for i, cell in enumerate(cells):
        if cell.cell_type != "markdown":
            continue
        for h in _headings(cell):
            key = next((k for k in HEADINGS if h.startswith(f"## {k}")), None)
            if key is None:
                continue
            if key == "Section" and not _SECTION.match(h):
                out.append(f"cell {i}: section heading {h!r}: expected '## Section N: title (~M min)'")
            first.setdefault(key, i)
            if key == "Objectives" and "prerequisite" not in cell.source.lower():
                out.append(f"cell {i}: the objectives should name the prerequisites")
    missing = [k for k in HEADINGS if k not in first]
    if missing:
        out.append(f"missing heading(s) {['## ' + k for k in missing]}")
        return out
    order = [first[k] for k in HEADINGS]
    if order != sorted(order):
        out.append(f"headings out of order: expected {['## ' + k for k in HEADINGS]}")
    setup = next((c for c in cells[first["Setup"]:] if c.cell_type == "code"), None)
    if setup is None or "course.setup(" not in setup.source or "fast_mode()" not in setup.source:
        out.append("setup: the first code cell after '## Setup' should call course.setup(...) and course.fast_mode()")
    sols = [i for i, c in enumerate(cells) if c.metadata.get("nbgrader", {}).get("solution")]
    grades = [i for i, c in enumerate(cells) if c.metadata.get("nbgrader", {}).get("grade")]
    if not sols:
        out.append("exercises: expected at least one solution cell")
    if not grades:
        out.append("exercises: expected at least one graded check cell")
    for i in sols:
        src = cells[i].source
        if "### BEGIN SOLUTION" not in src or "### END SOLUTION" not in src:
            out.append(f"cell {i}: solution cell without '### BEGIN SOLUTION' / '### END SOLUTION'")
    for i in grades:
        if "check(" not in cells[i].source and "assert" not in cells[i].source:
            out.append(f"cell {i}: graded cell should call course.check(...) / course.assert_passed(...)")
    out += _exercise_problems(cells, sols, grades)
    for i, cell in enumerate(cells):
        if cell.cell_type == "code" and (cell.get("outputs") or cell.get("execution_count")):
            out.append(f"cell {i}: expected no outputs (ship notebooks cleared)")
        if _PATHS.search(cell.source):
            out.append(f"cell {i}: contains a machine-specific path")
    return out
