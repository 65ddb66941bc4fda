"""The learners' JupyterLab: nbgrader's instructor tools off, in the page and on the server.

The README's first command starts JupyterLab with this file::

    .venv/bin/jupyter lab --config=masp_lite/course/labconfig/learners.py notebooks/00_tour.ipynb

* ``page_config.json`` beside it (JupyterLab's app settings folder) switches off nbgrader's
  JupyterLab extension: no Nbgrader menu, "Validate", "Create Assignment" sidebar;
* nbgrader's server extensions (the formgrader, the assignment and course lists, validation)
  are not loaded, so ``/formgrader/...`` answers 404 instead of the instructor's pages.

Instructors start JupyterLab without it and get nbgrader's tools.
"""
import os

c = get_config()  # noqa: F821  (traitlets defines get_config for its configuration files)

c.LabApp.app_settings_dir = os.path.dirname(os.path.abspath(__file__))
c.ServerApp.jpserver_extensions = {f"nbgrader.server_extensions.{name}": False
                                   for name in ("formgrader", "assignment_list", "course_list", "validate_assignment")}
