"""The package's imports flow one way and never in a circle (read from the source with ast).

Layers, lowest first: ``envs`` and ``config`` -> ``nets`` / ``planners`` -> ``algos`` /
``weights`` -> ``policies`` -> ``evaluation`` / ``training`` / ``viz`` / ``bench`` /
``course`` -> ``plan`` (the training plan, over training and evaluation) -> ``cli``. A module
may import its own package and anything in a lower layer; imports inside functions (lazy
ones) count too.
"""
import ast
import functools
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "masp_lite"
LAYER = {"envs": 0, "config": 0, "parsing": 0.5, "nets": 1, "planners": 1, "algos": 2, "weights": 2, "policies": 3,
         "plan": 5.5, "evaluation": 4, "training": 5, "viz": 5, "bench": 5, "course": 5, "cli": 6, "__main__": 7,
         "__init__": 7}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, source: str | None = None, name: str | None = None) -> set[str]:
    """Modules of ``masp_lite`` imported anywhere in ``path`` (absolute names)."""
    name = name or _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(source if source is not None else path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("masp_lite")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.startswith("masp_lite"):
                out.add(mod)
                out |= {f"{mod}.{a.name}" for a in node.names}  # `from pkg import submodule`
    return out


MODULES = {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _resolve(name: str) -> str | None:
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


@functools.cache
def _graph() -> dict[str, set[str]]:
    return {m: {r for i in _imports(p) if (r := _resolve(i)) and r != m} for m, p in MODULES.items()}


def _upward(module: str, targets) -> list[str]:
    src = _top(module)
    return sorted(t for t in targets if _top(t) != src and t != "masp_lite" and LAYER[_top(t)] >= LAYER[src])


def _top(name: str) -> str:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def test_every_top_level_part_has_a_layer():
    assert {_top(m) for m in MODULES} <= set(LAYER), sorted({_top(m) for m in MODULES} - set(LAYER))


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_import_points_up(module):
    bad = _upward(module, _graph()[module])
    assert not bad, f"{module} (layer {LAYER[_top(module)]}) imports {bad} from the same or a higher layer"


def test_no_import_cycles():
    graph = _graph()
    state, cycles = {}, []

    def visit(m, stack):
        state[m] = "open"
        for t in sorted(graph[m]):
            if state.get(t) == "open":
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t, stack + [t])
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, f"import cycles: {cycles}"


def test_the_checker_catches_an_upward_import():
    """The check can fail: a made-up world module importing the policies (lazily) is caught."""
    src = "def f():\n    from ..policies import make_policy\n    from .base import BatchedWorld\n"
    found = {_resolve(i) for i in _imports(PACKAGE / "envs" / "fake.py", src, "masp_lite.envs.fake")}
    assert found == {"masp_lite.policies", "masp_lite.envs.base"}
    assert _upward("masp_lite.envs.fake", found) == ["masp_lite.policies"]
