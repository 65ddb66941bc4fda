"""Learner notebooks are generated from the instructor notebooks with nbgrader's preprocessors.

``solutions/NN_name.ipynb`` (instructor: full solutions between ``### BEGIN SOLUTION`` and
``### END SOLUTION``, graded check cells) becomes ``notebooks/NN_name.ipynb`` (learner:
stubs that raise ``NotImplementedError``) through the same preprocessors, in the same
order, as ``nbgrader generate_assignment`` — minus ``IncludeHeaderFooter`` and
``InstantiateTests`` (header files and ``### AUTOTEST`` templates, which the course does
not use) and ``SaveCells`` (it writes nbgrader's database; a first ``ComputeChecksums``
only fed it):

``LockCells`` → ``ClearSolutions`` → ``ClearOutput`` → ``CheckCellMetadata`` →
``ClearHiddenTests`` → ``ClearMarkScheme`` → ``ComputeChecksums`` → ``CheckCellMetadata``

plus one step of ours, :class:`TagGradedCells`: every graded cell of the learner version
gets Jupyter's standard ``raises-exception`` tag. A graded cell fails (``AssertionError``)
until its exercise is solved; with the tag, "Run All" goes on past it and nbval accepts
the failure, while the instructor version — without the tag — must pass every check.

Regenerate every learner notebook (run from the repository root: the folders default to
``solutions/`` and ``notebooks/`` of the current folder)::

    python -m masp_lite.course.generate            # solutions/*.ipynb -> notebooks/
    python -m masp_lite.course.generate --check    # exit 1 if any shipped one is stale

The test suite regenerates into a temporary folder and compares, so the two versions
cannot drift apart; it also runs the real ``nbgrader generate_assignment`` on the
instructor notebooks and checks that its release equals ours but for the tag.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import nbformat
from nbgrader.preprocessors import (
    CheckCellMetadata,
    ClearHiddenTests,
    ClearMarkScheme,
    ClearOutput,
    ClearSolutions,
    ComputeChecksums,
    LockCells,
)
from nbgrader.preprocessors.base import NbGraderPreprocessor
from nbgrader.utils import is_grade

from ..files import atomic_write, read_bounded

__all__ = ["generate", "generate_all", "learner_notebook", "TagGradedCells", "SOLUTIONS", "NOTEBOOKS"]

#: The default folders, relative to the current folder (the repository root, or any copy of the
#: course): the instructor notebooks and the learner notebooks generated from them. Folders are
#: arguments, so the package never assumes a source checkout around it.
SOLUTIONS, NOTEBOOKS = Path("solutions"), Path("notebooks")

_TAG = "raises-exception"


class TagGradedCells(NbGraderPreprocessor):
    """Add the ``raises-exception`` tag to graded cells (learner version only)."""

    def preprocess_cell(self, cell, resources, cell_index):
        if is_grade(cell):
            tags = list(cell.metadata.get("tags", []))
            if _TAG not in tags:
                cell.metadata["tags"] = tags + [_TAG]
        return cell, resources


def _pipeline():
    return [LockCells(), ClearSolutions(), ClearOutput(), CheckCellMetadata(), ClearHiddenTests(),
            ClearMarkScheme(), ComputeChecksums(), CheckCellMetadata(), TagGradedCells()]


def learner_notebook(nb: nbformat.NotebookNode) -> nbformat.NotebookNode:
    """The learner version of an instructor notebook (a new notebook; ``nb`` is untouched)."""
    nb = nbformat.reads(nbformat.writes(nb), as_version=4)  # a deep copy
    resources: dict = {}
    for pre in _pipeline():
        nb, resources = pre.preprocess(nb, resources)
    return nb


def generate(src: str | Path, dst: str | Path) -> Path:
    """Write the learner version of instructor notebook ``src`` to ``dst``; return ``dst``.

    ``dst`` may be a folder (the file keeps its name) or a file path.
    """
    src, dst = Path(src), Path(dst)
    if src.suffix != ".ipynb" or not src.is_file():
        raise ValueError(f"generate: expected an existing instructor notebook (.ipynb), got {str(src)!r}")
    if dst.is_dir():
        dst = dst / src.name
    nb = nbformat.reads(read_bounded(src, what="instructor notebook").decode("utf-8"), as_version=4)
    learner = learner_notebook(nb)
    nbformat.validate(learner)
    text = nbformat.writes(learner)
    atomic_write(dst, text if text.endswith("\n") else text + "\n")  # what nbformat.write writes, whole or not at all
    return dst


def generate_all(solutions: str | Path | None = None, notebooks: str | Path | None = None) -> list[Path]:
    """Regenerate a learner notebook for every ``solutions/*.ipynb``; return the paths written.

    ``solutions``, ``notebooks``: the folders (default :data:`SOLUTIONS`, :data:`NOTEBOOKS`)."""
    solutions = Path(solutions) if solutions is not None else SOLUTIONS
    notebooks = Path(notebooks) if notebooks is not None else NOTEBOOKS
    sources = sorted(solutions.glob("*.ipynb"))
    if not sources:
        raise ValueError(f"generate_all: expected instructor notebooks in {str(solutions)!r}, found none")
    notebooks.mkdir(parents=True, exist_ok=True)
    return [generate(src, notebooks / src.name) for src in sources]


def stale(solutions: str | Path | None = None, notebooks: str | Path | None = None) -> list[str]:
    """Names of shipped learner notebooks that differ from a fresh generation (or are missing)."""
    import tempfile

    notebooks = Path(notebooks) if notebooks is not None else NOTEBOOKS
    with tempfile.TemporaryDirectory() as tmp:
        out = []
        for fresh in generate_all(solutions, tmp):
            shipped = notebooks / fresh.name
            if not shipped.is_file() or shipped.read_text(encoding="utf-8") != fresh.read_text(encoding="utf-8"):
                out.append(fresh.name)
        return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m masp_lite.course.generate",
                                     description="generate learner notebooks from instructor notebooks")
    parser.add_argument("--solutions", default=None, help="instructor notebooks folder (default: solutions/)")
    parser.add_argument("--notebooks", default=None, help="learner notebooks folder (default: notebooks/)")
    parser.add_argument("--check", action="store_true", help="only report stale learner notebooks")
    args = parser.parse_args(argv)
    try:
        if args.check:
            names = stale(args.solutions, args.notebooks)
            for name in names:
                print(f"stale: {name} (run python -m masp_lite.course.generate)")
            return 1 if names else 0
        for path in generate_all(args.solutions, args.notebooks):
            print(f"wrote {path}")
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
