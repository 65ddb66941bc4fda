"""nbgrader's configuration for this course, read by nbgrader's commands and JupyterLab menus.

The course keeps each version in one folder: the instructor notebooks in ``solutions/``
(nbgrader's *source*), the learner notebooks in ``notebooks/`` (its *release*). The release
is made by ``python -m masp_lite.course.generate``, which runs nbgrader's own preprocessors
on every instructor notebook (see ``masp_lite/course/generate.py``); nbgrader's
``generate_assignment`` would want one sub-folder per assignment instead: for autograding,
``python -m masp_lite.course.classroom init DIR`` writes such a course folder (README,
"Grading with nbgrader").
"""
import os
import sys

# nbgrader runs `alembic` as a command when it creates gradebook.db: find it beside this Python
# even when the environment is not activated
os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")

c = get_config()  # noqa: F821  (traitlets defines get_config for its configuration files)

c.CourseDirectory.root = os.path.dirname(os.path.abspath(__file__))
c.CourseDirectory.course_id = "masp-lite"
c.CourseDirectory.source_directory = "solutions"
c.CourseDirectory.release_directory = "notebooks"
