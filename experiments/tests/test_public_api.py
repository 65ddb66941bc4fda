"""The research scripts use masp-lite's public API only: no ``masp_lite`` name starting with ``_``.

Every ``.py`` under ``experiments/`` is parsed (not imported) and three things are refused:

* importing a private name or module: ``from masp_lite.x import _y``, ``import masp_lite._x``,
  ``from masp_lite._x import y``;
* a private attribute of something bound to ``masp_lite``: ``E._rollout`` after
  ``from masp_lite import eval as E``, ``masp_lite.x._y`` after ``import masp_lite.x``,
  ``mod._y`` after ``from masp_lite import mod``;
* the same through ``getattr(masp_lite_name, "_y")``.

Dunder names (``__file__``, ``__version__``) are allowed.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1]
SCRIPTS = sorted(EXPERIMENTS.rglob("*.py"))


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _from_masp_lite(module: str | None) -> bool:
    return module is not None and (module == "masp_lite" or module.startswith("masp_lite."))


def violations(source: str, filename: str = "<string>") -> list[str]:
    """Each private ``masp_lite`` name the code uses, as ``"line: what"``."""
    tree = ast.parse(source, filename)
    bound: set[str] = set()          # local names that stand for masp_lite modules or objects
    found: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if not _from_masp_lite(alias.name):
                    continue
                parts = alias.name.split(".")
                if any(_private(p) for p in parts):
                    found.append(f"{node.lineno}: import {alias.name}")
                bound.add(alias.asname or parts[0])
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and _from_masp_lite(node.module):
            if any(_private(p) for p in node.module.split(".")):
                found.append(f"{node.lineno}: from {node.module} import ...")
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"{node.lineno}: from {node.module} import {alias.name}")
                bound.add(alias.asname or alias.name)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            root = node.value
            while isinstance(root, ast.Attribute):
                root = root.value
            if isinstance(root, ast.Name) and root.id in bound:
                found.append(f"{node.lineno}: {ast.unparse(node)}")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr"
              and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant)
              and isinstance(node.args[1].value, str) and _private(node.args[1].value)):
            root = node.args[0]
            while isinstance(root, ast.Attribute):
                root = root.value
            if isinstance(root, ast.Name) and root.id in bound:
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return sorted(set(found), key=lambda s: int(s.split(":")[0]))


def test_there_are_scripts_to_check():
    names = {p.name for p in SCRIPTS}
    assert {"mpe5_failures.py", "mpe5_oracle.py", "mpe5_distill.py", "contact_breakdown.py"} <= names


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: str(p.relative_to(EXPERIMENTS)))
def test_script_uses_only_public_masp_lite_names(path):
    assert violations(path.read_text(), str(path)) == []


@pytest.mark.parametrize("code", [
    "from masp_lite.evaluation import _rollout",
    "from masp_lite.evaluation import rollout as r, _factory as f",
    "import masp_lite._private",
    "from masp_lite._private import thing",
    "from masp_lite import eval as E\nE._rollout(world, policy, 1, 0)",
    "import masp_lite.evaluation\nmasp_lite.evaluation._rollout",
    "import masp_lite.evaluation as ev\nx = ev.evaluate._stats",
    "from masp_lite import policies\npolicies._factory('masp')",
    "from masp_lite import evaluation\ngetattr(evaluation, '_rollout')",
])
def test_the_check_catches_private_names(code):
    assert violations(code)


@pytest.mark.parametrize("code", [
    "from masp_lite.evaluation import rollout\nrollout.__doc__",
    "import torch\ntorch._C",
    "from experiments.mpe5_oracle import copy_state",
    "from masp_lite.policies import get_factory\nget_factory('masp')",
])
def test_the_check_allows_public_names_and_other_packages(code):
    assert violations(code) == []


def foreign_private_attributes(source: str) -> list[str]:
    """Private attributes read on anything but ``self``/``cls`` (e.g. a world's ``w._keep``).

    Objects the library returns (worlds, policies, networks) are ``masp_lite``'s too, and
    the names above cannot follow them; this stricter rule can: the scripts' own classes
    use ``self._x``, everything else must be public.
    """
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            root = node.value
            if not (isinstance(root, ast.Name) and root.id in ("self", "cls")):
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return found


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: str(p.relative_to(EXPERIMENTS)))
def test_script_reads_no_private_attribute_of_library_objects(path):
    assert foreign_private_attributes(path.read_text()) == []


def test_the_stricter_check_catches_a_world_internal():
    found = sorted(foreign_private_attributes("sim._geometry()\nx = world._keep"))
    assert found == ["1: sim._geometry", "2: world._keep"]
    assert foreign_private_attributes("self._cache = {}") == []
