"""Course machinery: exercise checks, fast mode, learner-notebook generation, the nbgrader course folder.

Authoring recipe (every chapter follows it)
-------------------------------------------
**Files.** Write the instructor version ``solutions/NN_name.ipynb`` (``NN`` = chapter
number, e.g. ``03_graph_encoders.ipynb``). Never edit ``notebooks/NN_name.ipynb`` by hand:
it is generated. ``notebooks/README.md`` is the course map.

**Skeleton** (checked by :func:`masp_lite.course.authoring.problems`)::

    # Chapter NN: Title                      (markdown, first cell)
    ## Objectives                            (what the learner will be able to do; prerequisites)
    ## Setup                                 (first code cell below, exactly:)
        import masp_lite.course as course
        course.setup(seed=0)       # seeds random/NumPy/torch, 2 torch threads
        FAST = course.fast_mode()  # small budgets under the tests; FAST = False for full size
    ## Section 1: Title (~10 min)            (as many sections as needed, with time estimates)
    ### Exercise 1: ...                      (right after the lesson it practises, inside its
                                              section: solution cell + graded check cell)
    ## Section 2: ...
    ## Summary                               (the end: nothing follows it)

Show library code with ``course.show(fn)`` (``inspect.getsource``); never paste it, and
never show an exercise's reference before the exercise. After the graded check, show it with
``course.reveal("exercise name", fn)``: the source appears only once the check has passed
(``reveal(..., now=True)`` shows it anyway, and the grade records it); ``tests/test_exercises.py``
and the learner runs of ``tests/test_notebooks.py`` enforce it.
Scale every budget with ``FAST`` (``episodes = 3 if FAST else 100``): in fast mode a
chapter must run in about a minute on 2 cores (3 minutes at most).

**An exercise** sits at the end of the section that teaches its concept, as in
Neuromatch's tutorials, never in a block after the summary: a ``### Exercise K: …``
markdown cell (numbered through the chapter), then two cells. The solution cell
(nbgrader ``solution: true``)::

    def my_contact_force(delta, dist, dist_min):
        \"\"\"...what to compute, which paper equation...\"\"\"
        ### BEGIN SOLUTION
        ...the 10-30 lines...
        ### END SOLUTION

and the graded check cell (nbgrader ``grade: true``, ``points``)::

    contact_fn = course.check(my_contact_force, particle.contact_force,
                              inputs=contact_cases, name="contact force")
    course.assert_passed("contact force")

:func:`check` prints ``✓``/``✗``/``…`` and returns the learner's function when it passed,
the library's otherwise — later cells use ``contact_fn``, so a learner who skips still
runs the chapter. Bind the result to a *new* name: re-running the cell must compare the
learner's function again, not the fallback with itself. :func:`assert_passed` makes the
cell fail for ``nbgrader autograde`` until the exercise is solved; in the learner version
the generator tags graded cells ``raises-exception`` so "Run All" and nbval go on past
them. ``inputs`` is a list of cases (tuple = positional arguments, dict = keyword
arguments) or a function ``seed -> case`` (called for seeds 0, 1, 2); ``rtol``/``atol``
set the tolerance. Choose cases that a plausible wrong answer fails (try one!).
Build cells with :mod:`masp_lite.course.authoring` (``markdown``, ``code``,
``solution``, ``graded``, ``notebook``) or in JupyterLab with the same metadata.

**Regenerate and test**::

    python -m masp_lite.course.generate              # solutions/ -> notebooks/
    python -m pytest tests/test_course.py            # skeleton + learner notebooks in sync
    python -m pytest tests/test_notebooks.py -k NN   # run chapter NN, both versions, under nbval
    python -m pytest tests/test_exercises.py         # no reference shown early; call-the-library answers fail
    python -m pytest tests/test_classroom.py         # nbgrader's cycle on a course folder; the two labs

**Grading** (:mod:`masp_lite.course.classroom`): ``python -m masp_lite.course.classroom init DIR``
writes an nbgrader course folder from ``solutions/``; nbgrader's own commands then run the
cycle (README, "Grading with nbgrader"), with :mod:`masp_lite.course.grading`'s preprocessors:
only the answer cells come from a submission, each is screened for forgeries, and whatever
was deleted, stripped or screened is named in the feedback and by ``nbgrader export``. An
answer cell holds only imports, function definitions and constants: a helper goes in the same cell.

Ship notebooks without outputs (``jupyter nbconvert --clear-output --inplace``, or build
them with :func:`masp_lite.course.authoring.notebook`).
"""
from .checking import (
                       RESULTS,
                       REVEALED,
                       ExerciseNotPassed,
                       LibraryUnavailable,
                       Outcome,
                       assert_passed,
                       check,
                       compare,
                       reveal,
                       unavailable,
)
from .session import FAST_ENV, fast_mode, setup, show

__all__ = ["check", "assert_passed", "compare", "unavailable", "reveal", "Outcome", "RESULTS", "REVEALED",
           "LibraryUnavailable", "ExerciseNotPassed", "fast_mode", "setup", "show", "FAST_ENV"]
