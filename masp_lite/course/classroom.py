"""A standard nbgrader course folder built from ``solutions/``, for an instructor's grading cycle.

The repository keeps each version of the course in one flat folder (instructor notebooks in
``solutions/``, learner notebooks in ``notebooks/``); nbgrader's commands want one sub-folder
per assignment instead. ::

    .venv/bin/python -m masp_lite.course.classroom init classroom

writes that layout — one assignment per chapter, named after its notebook — and nothing else::

    classroom/
        nbgrader_config.py                              the course's configuration (below)
        gradebook.db                                    nbgrader's database, created empty
        source/03_graph_encoders/03_graph_encoders.ipynb   (a copy of solutions/03_graph_encoders.ipynb)
        ...

after which nbgrader's own commands run the cycle from inside ``classroom/``
(``generate_assignment``, ``release_assignment``/``collect`` or submissions placed in
``submitted/<student>/<chapter>/``, ``autograde``, ``generate_feedback``, ``export``, the
formgrader); the README's instructor section gives them in order.

The folder's ``nbgrader_config.py``

* puts the Python environment's ``bin/`` folder first on ``PATH``: nbgrader runs ``alembic``
  as a command when it creates its database, which fails (``FileNotFoundError: 'alembic'``)
  when ``.venv/bin/nbgrader`` is called without activating the environment;
* adds the course's :class:`~masp_lite.course.generate.TagGradedCells` to
  ``generate_assignment``, so the release equals ``notebooks/`` (graded cells tagged
  ``raises-exception``: "Run All" goes on past an unsolved exercise);
* grades in fast mode (``MASP_LITE_FAST=1``, the budgets the tests use; a graded cell depends
  only on its exercise) with no per-cell time limit (nbgrader's default of 30 s would cut a
  chapter's training cells short);
* keeps nbgrader's exchange in ``classroom/exchange`` instead of ``/srv/nbgrader/exchange``,
  so ``release_assignment``, ``fetch_assignment``, ``submit`` and ``collect`` work on one
  machine without administrator rights;
* grades with :mod:`masp_lite.course.grading`: ``autograde`` runs the release with only the
  submission's answer cells, each screened for forgeries (a screened answer scores zero with
  its reason, or goes to manual grading: ``c.UseReleaseCells.screened``, ``init --screened``),
  and ``export`` prints, beside ``grades.csv``, every deleted, stripped or screened cell.

``init --learners DIR`` also writes the copy of the course learners get
(:func:`learner_copy`): the release notebooks and the library, without ``solutions/``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

from ..files import atomic_write, read_bounded
from .generate import SOLUTIONS

__all__ = ["init", "chapters", "learner_copy", "CONFIG", "LEARNER_FILES", "SCREENED"]

#: What :func:`learner_copy` takes from the repository besides the learner notebooks: the library and
#: the records its chapters read, the files that install it, the README and the course map.
LEARNER_FILES = ("masp_lite", "results", "docs", "pyproject.toml", "environment.txt", "README.md",
                 "notebooks/README.md")
#: What a screened answer gets: ``"zero"`` (its reason in the feedback) or ``"manual"`` grading.
SCREENED = ("zero", "manual")

#: The course folder's ``nbgrader_config.py``.
CONFIG = '''\
"""nbgrader's configuration for this course folder (written by python -m masp_lite.course.classroom init).

Run nbgrader's commands from this folder, e.g. ``../.venv/bin/nbgrader autograde 03_graph_encoders``.
"""
import os
import sys

from nbgrader.converters import Autograde, GenerateAssignment
from nbgrader.preprocessors import Execute, SaveAutoGrades

from masp_lite.course.generate import TagGradedCells
from masp_lite.course.grading import RecordGrading, ReportGrading, UseReleaseCells

c = get_config()  # noqa: F821  (traitlets defines get_config for its configuration files)

# nbgrader runs `alembic` as a command when it creates gradebook.db: find it beside this Python
# even when the environment is not activated.
os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")
# chapters are graded with the tests' small budgets; a graded cell depends only on its exercise
os.environ.setdefault("MASP_LITE_FAST", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

c.CourseDirectory.root = os.path.dirname(os.path.abspath(__file__))
c.CourseDirectory.course_id = {course_id!r}
c.Exchange.root = os.path.join(c.CourseDirectory.root, "exchange")
# the release equals the repository's notebooks/: graded cells tagged raises-exception
c.GenerateAssignment.preprocessors = GenerateAssignment.class_traits()["preprocessors"].default() + [TagGradedCells]
# chapters train and evaluate: no per-cell time limit (nbgrader's default is 30 s)
c.Execute.timeout = None

# grade the release with only the submission's answer cells, each screened for forgeries
# (masp_lite.course.grading); what was deleted, stripped or screened is named in the feedback and by export
c.Autograde.sanitize_preprocessors = [UseReleaseCells] + Autograde.class_traits()["sanitize_preprocessors"].default()
_steps = Autograde.class_traits()["autograde_preprocessors"].default()
_steps.insert(_steps.index(Execute) + 1, ReportGrading)
_steps.insert(_steps.index(SaveAutoGrades) + 1, RecordGrading)
c.Autograde.autograde_preprocessors = _steps
# a screened answer scores "zero" (its one-line reason in the feedback) or goes to "manual" grading
c.UseReleaseCells.screened = {screened!r}
c.ExportApp.plugin_class = "masp_lite.course.grading.ExportWithNotes"
'''


def chapters(solutions: str | Path | None = None) -> list[str]:
    """The chapter names (notebook stems, e.g. ``"03_graph_encoders"``) in ``solutions/``."""
    solutions = Path(solutions) if solutions is not None else SOLUTIONS
    return sorted(p.stem for p in solutions.glob("*.ipynb"))


def _create_gradebook(folder: Path, course_id: str) -> Path:
    """Create nbgrader's empty ``gradebook.db`` (its ``alembic`` subprocess found beside this Python)."""
    from nbgrader.api import Gradebook

    db = folder / "gradebook.db"
    old = os.environ.get("PATH", "")
    os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + old
    try:
        with Gradebook(f"sqlite:///{db}", course_id=course_id):
            pass
    finally:
        os.environ["PATH"] = old
    return db


def learner_copy(dst: str | Path, *, root: str | Path = ".", solutions: str | Path | None = None) -> Path:
    """Write the learners' copy of the course at ``dst``: release notebooks and the library, no solutions.

    ``dst/notebooks/`` gets the learner version of every instructor notebook (generated afresh,
    as ``notebooks/``); :data:`LEARNER_FILES` are copied from the repository at ``root``
    (caches left out). ``solutions/``, the tests and the instructor's nbgrader configuration
    stay behind. ``dst`` must not exist.
    """
    from .generate import generate_all

    root, dst = Path(root).resolve(), Path(dst).resolve()
    solutions = Path(solutions) if solutions is not None else root / SOLUTIONS
    if dst.exists():
        raise ValueError(f"learner_copy: {dst} exists; expected a new folder")
    missing = [name for name in LEARNER_FILES if not (root / name).exists()]
    if missing or not chapters(solutions):
        raise ValueError(f"learner_copy: expected the repository at {str(root)!r} "
                         f"(missing {missing or ['solutions/']})")
    dst.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for name in LEARNER_FILES:
        src, out = root / name, dst / name
        out.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, out, ignore=ignore)
        else:
            shutil.copyfile(src, out)
    generate_all(solutions, dst / "notebooks")
    return dst


def init(folder: str | Path, names: list[str] | None = None, *, solutions: str | Path | None = None,
         course_id: str = "masp-lite", force: bool = False, screened: str = "zero") -> list[Path]:
    """Write an nbgrader course folder at ``folder`` from the instructor notebooks; return the sources.

    ``names`` picks chapters by notebook stem (``"03_graph_encoders"``) or number (``"03"``);
    all chapters by default. An existing source notebook is replaced only with ``force``.
    ``screened`` is what the folder's configuration gives an answer that screening refuses
    (:data:`SCREENED`); change it later in ``nbgrader_config.py`` (``c.UseReleaseCells.screened``).
    """
    if screened not in SCREENED:
        raise ValueError(f"init: screened: expected one of {SCREENED}, got {screened!r}")
    solutions = Path(solutions) if solutions is not None else SOLUTIONS
    available = chapters(solutions)
    if not available:
        raise ValueError(f"init: expected instructor notebooks in {str(solutions)!r}, found none")
    picked = available if not names else []
    for name in names or []:
        match = [c for c in available if c == name or c.split("_", 1)[0] == name]
        if len(match) != 1:
            raise ValueError(f"init: unknown chapter {name!r}; expected one of {available}")
        picked.append(match[0])
    folder = Path(folder).resolve()
    config = CONFIG.format(course_id=course_id, screened=screened).encode()
    targets = {folder / "source" / name / f"{name}.ipynb": solutions / f"{name}.ipynb" for name in picked}
    # every file an instructor may have edited is checked before anything is written: init either finishes
    # or changes nothing
    taken = [dst for dst in targets if dst.exists()]
    cfg = folder / "nbgrader_config.py"
    if cfg.exists() and read_bounded(cfg, what="course configuration") != config:
        taken.append(cfg)
    if taken and not force:
        raise ValueError(f"init: {', '.join(map(str, taken))} exist(s) and would be replaced; nothing was written "
                         "(pass --force to replace them)")
    for dst, src in targets.items():
        dst.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(dst, read_bounded(src, what="instructor notebook"))
    atomic_write(cfg, config)
    if not (folder / "gradebook.db").exists():
        _create_gradebook(folder, course_id)
    return list(targets)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m masp_lite.course.classroom",
                                     description="build an nbgrader course folder from solutions/")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("init", help="write DIR/source/<chapter>/<chapter>.ipynb and DIR/nbgrader_config.py")
    p.add_argument("folder", help="the course folder to write (e.g. classroom)")
    p.add_argument("chapters", nargs="*", help="chapters to include, by name or number (default: all)")
    p.add_argument("--force", action="store_true", help="replace source notebooks that exist")
    p.add_argument("--course-id", default="masp-lite", help="nbgrader's course id (default: masp-lite)")
    p.add_argument("--solutions", default=None, help="instructor notebooks folder (default: solutions/ here)")
    p.add_argument("--screened", choices=SCREENED, default="zero",
                   help="what an answer refused by forgery screening gets: zero (default) or manual grading")
    p.add_argument("--learners", default=None, metavar="DIR",
                   help="also write the learners' copy of the course at DIR: release notebooks and the library, "
                        "no solutions/ (run from the repository root)")
    args = parser.parse_args(argv)
    try:
        written = init(args.folder, args.chapters, solutions=args.solutions, course_id=args.course_id,
                       force=args.force, screened=args.screened)
        if args.learners:
            bundle = learner_copy(args.learners, solutions=args.solutions)
            print(f"wrote {bundle} (the learners' copy: notebooks/ and the library, no solutions/)")
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    folder = Path(args.folder)
    for path in written:
        print(f"wrote {path}")
    print(f"wrote {folder / 'nbgrader_config.py'}")
    nbgrader = os.path.relpath(Path(sys.executable).parent / "nbgrader", folder.resolve())
    print(f"next: cd {folder} && {nbgrader} generate_assignment {written[0].parent.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
