"""The package's imports flow one way and never in a circle (read from the source with ast).

Layers, lowest first: ``files`` (the one atomic write, the one bounded reader) -> ``envs``, ``config`` and
``threads`` -> ``parsing`` -> ``nets`` / ``planners`` -> ``algos`` / ``weights`` -> ``policies`` -> ``evaluation`` /
``training`` / ``viz`` / ``course`` / ``primer`` -> ``recipes`` -> ``budgets`` (a recipe's stage at another budget)
-> ``reproduction`` (the only code that knows the repository: records, paper numbers, the training plan) -> ``bench``
(timings beside the paper's) -> ``cli``; ``evaluation.metrics`` (the metrics' one definition, torch only) sits
below ``algos``, whose trainer measures its rollouts with it. A module
may import its own package and anything in a lower layer; imports inside functions (lazy
ones) count too.
"""
import ast
import functools
import re
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "masp_lite"
LAYER = {"files": -1, "envs": 0, "config": 0, "threads": 0, "parsing": 0.5, "nets": 1, "planners": 1, "algos": 2,
         "weights": 2, "policies": 3, "evaluation": 4, "training": 5, "viz": 5, "course": 5, "primer": 5,
         "recipes": 5.2, "budgets": 5.3, "reproduction": 5.5, "bench": 5.7, "cli": 6, "__main__": 7, "__init__": 7}


#: Modules with a layer below their package's: ``evaluation.metrics``, the one definition of SR, Steps and CR
#: (torch only), which training measures its rollouts with as ``evaluate`` measures a method's.
MODULE_LAYER = {"evaluation.metrics": 1.5}


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


def _layer(name: str) -> float:
    return MODULE_LAYER.get(".".join(name.split(".")[1:3]), LAYER[_top(name)])


def _upward(module: str, targets) -> list[str]:
    src = _top(module)
    return sorted(t for t in targets if _top(t) != src and t != "masp_lite" and _layer(t) >= _layer(module))


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


# --------------------------------------------------------------------------- MuJoCo stays with the drones
#: Modules a particle-world user (training, evaluation, the reading path) loads: none may reach MuJoCo.
PARTICLE_ONLY = ["masp_lite.algos.masp_trainer", "masp_lite.training", "masp_lite.policies.masp",
                 "masp_lite.nets.masp", "masp_lite.envs.particle", "masp_lite.evaluation",
                 "masp_lite.policies.reference", "masp_lite.policies.planners"]
#: The budget of the particle trainer's import closure (lines of ``masp_lite`` loaded by importing it): 4,043
#: lines in 22 modules with MuJoCo before the compact core (issue 37, whose target is 2,500), 2,708 in 17 after;
#: 2,679 once a given start's checks (``envs/start.py``) load only when a reset is given one; 2,616 once the
#: training draw of goals has its own module (``nets/goal_draw.py``: the decoding for acting stays out) and
#: ``hungarian_goals`` lives with the team-size rules (``algos/team.py``); 2,642 with the fusion kernel's
#: ``index_select`` reads; 2,607 once the goal-free baselines' landmark features and coverage reward live with
#: the baselines (``nets/baselines.py``, ``algos/goal_sources.py``); 2,445 once the chunked CPU kernels live in
#: ``nets/kernels.py`` (267 lines), which the encoders and the fusion import at their first chunked forward: a
#: training run loads them at its first update (2,712 lines then), importing or reading MASP's path does not; 2,536
#: once the networks' input features are a module of their own (``nets/features.py``, both worlds' networks read
#: it: a module header more) and the executor's inputs are named (``ExecutorInputs``);
#: then PPO reports its health (approximate KL, clip fraction, explained variance: ``algos/mappo.py``) and the
#: trainer measures SR and Steps with ``evaluation/metrics.py``, which it loads at its first rollout (2,590);
#: then the configuration holds the imitation stage's settings (``ImitationConfig``, ``masp-minmax``: 2,620).
TRAINER_LINES = 2_625


def _top_level_imports(path: Path, name: str) -> set[str]:
    """``masp_lite`` modules and ``mujoco`` imported when ``path`` is imported (not inside functions)."""
    tree = ast.parse(path.read_text())
    outer = ast.Module(body=[n for n in tree.body if not isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))] +
                       [m for c in tree.body if isinstance(c, ast.ClassDef) for m in c.body
                        if not isinstance(m, (ast.FunctionDef, ast.AsyncFunctionDef))], type_ignores=[])
    found = {r for i in _imports(path, ast.unparse(outer), name) if (r := _resolve(i)) and r != name}
    for node in ast.walk(outer):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
            [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
        found |= {"mujoco" for n in names if n.split(".")[0] == "mujoco"}
    return found


def _loads_mujoco(module: str, imports: set | None = None) -> list[str]:
    """The chain of top-level imports from ``module`` to ``mujoco`` (empty when there is none)."""
    graph = {m: _top_level_imports(p, m) for m, p in MODULES.items()}
    if imports is not None:  # a made-up module's top-level imports
        graph[module] = imports
    stack, seen = [(module, [module])], set()
    while stack:
        m, chain = stack.pop()
        if m == "mujoco":
            return chain
        if m in seen or m not in graph:
            continue
        seen.add(m)
        parents = [p for p in (m.rsplit(".", k)[0] for k in range(1, m.count(".") + 1)) if p in graph]
        stack.extend((t, chain + [t]) for t in sorted(graph[m] | set(parents)))
    return []


@pytest.mark.parametrize("module", PARTICLE_ONLY)
def test_a_particle_module_never_imports_mujoco(module):
    chain = _loads_mujoco(module)
    assert not chain, f"{module} loads MuJoCo: {' -> '.join(chain)}"


def test_the_mujoco_check_can_fail():
    """A made-up particle module importing the drone networks at the top is caught, with the chain."""
    chain = _loads_mujoco("masp_lite.algos.fake", {"masp_lite.nets.drones"})
    assert chain[:2] == ["masp_lite.algos.fake", "masp_lite.nets.drones"] and chain[-1] == "mujoco"


def test_the_particle_trainer_loads_no_mujoco_and_little_code():
    code = ("import sys, pathlib, masp_lite.algos.masp_trainer\n"
            "mods = [m for m in sys.modules.values() if getattr(m, '__name__', '').startswith('masp_lite')]\n"
            "lines = sum(len(pathlib.Path(m.__file__).read_text().splitlines()) for m in mods if m.__file__)\n"
            "print('mujoco' in sys.modules, len(mods), lines)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    mujoco, modules, lines = out[0] == "True", int(out[1]), int(out[2])
    assert not mujoco
    assert lines <= TRAINER_LINES, f"the particle trainer loads {modules} modules, {lines} lines"


def test_the_chunked_kernels_load_at_the_first_chunked_forward():
    """Importing the trainer leaves ``nets.kernels`` unloaded; the networks' first forward on observations
    (no gradient into the inputs, as in training) loads it and runs the kernels."""
    code = ("import sys, torch, masp_lite.algos.masp_trainer\n"
            "from masp_lite.nets.masp import MASPNets, gm_inputs\n"
            "from masp_lite.nets.fusion import random_permutation\n"
            "from masp_lite.envs import make\n"
            "print('masp_lite.nets.kernels' in sys.modules)\n"
            "w = make('mpe-5', num_envs=2, seed=0); obs = w.reset(); nets = MASPNets()\n"
            "nets.cae_logits(nets.cae_inputs(obs, torch.zeros(2, 5, dtype=torch.long), random_permutation(2, 5)))\n"
            "print('masp_lite.nets.kernels' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True"]


def test_a_random_start_loads_no_start_checks():
    """Training's resets (random starts) leave ``envs.start`` unloaded; a given start loads and runs it."""
    code = ("import sys, masp_lite.envs as e\n"
            "w = e.make('mpe-5', num_envs=2, seed=0); w.reset(); w.reset(env_ids=[1])\n"
            "print('masp_lite.envs.start' in sys.modules)\n"
            "try:\n    w.reset(options={'agent_pos': [[0.0, 0.0]] * 5})\nexcept ValueError as err:\n"
            "    print('masp_lite.envs.start' in sys.modules, 'same point' in str(err))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True", "True"]


def test_the_reading_path_names_real_files_with_their_line_counts():
    """The package docstring's reading path: every file exists and its count is within 10 % of today's."""
    import masp_lite
    rows = [line.split() for line in masp_lite.__doc__.splitlines() if line[:1].isdigit() and "``" in line]
    assert len(rows) >= 10
    for row in rows:
        path, stated = PACKAGE / row[1].strip("`"), int(row[2])
        actual = len(path.read_text().splitlines())
        assert abs(actual - stated) <= 0.1 * stated, f"{row[1]}: the reading path says {stated} lines, it has {actual}"


# --------------------------------------------------------------------------- the repository in one room
#: Code that may know the source checkout: the reproduction room and its command line.
ROOM = ("masp_lite.reproduction", "masp_lite.cli.reproduce")


def _names_the_repository(path: Path) -> list[str]:
    """String literals (not docstrings) naming ``results/``, and ``Path(__file__)...parents[k]`` climbs."""
    tree = ast.parse(path.read_text())
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and n.body
                  and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    in_paths = {id(x) for n in ast.walk(tree) if isinstance(n, ast.BinOp) and isinstance(n.op, ast.Div)
                for x in (n.left, n.right)}  # ``root / "results"``
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings and \
                (re.search(r"(^|/)results/", node.value) or (node.value == "results" and id(node) in in_paths)):
            found.append(node.value)
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) and \
                node.value.attr == "parents" and "__file__" in ast.unparse(node.value):
            found.append(ast.unparse(node))
    return found


@pytest.mark.parametrize("module", sorted(m for m in MODULES if not m.startswith(ROOM)))
def test_only_the_reproduction_room_knows_the_repository(module):
    found = _names_the_repository(MODULES[module])
    assert not found, f"{module} names the checkout ({found}); that is masp_lite.reproduction's"


def test_the_repository_check_can_fail():
    assert _names_the_repository(PACKAGE / "reproduction" / "__init__.py")  # the room itself names it
    assert _names_the_repository(PACKAGE / "reproduction" / "histories.py")  # a path built from "results"


# --------------------------------------------------------------------------- functions that read in one screen
#: The longest a function of the package may be, in lines (decorators aside).
FUNCTION_LINES = 80


def _long_functions(path: Path, source: str | None = None) -> list[str]:
    tree = ast.parse(source if source is not None else path.read_text())
    return [f"{path.name}:{node.lineno} {node.name} ({node.end_lineno - node.lineno + 1} lines)"
            for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno + 1 > FUNCTION_LINES]


def test_no_function_is_longer_than_a_screen():
    found = [f for p in sorted(PACKAGE.rglob("*.py")) for f in _long_functions(p)]
    assert not found, f"functions over {FUNCTION_LINES} lines: {found}"


def test_the_length_check_can_fail():
    body = "".join(f"    x{k} = {k}\n" for k in range(FUNCTION_LINES))
    assert _long_functions(PACKAGE / "fake.py", f"def f():\n{body}") == [f"fake.py:1 f ({FUNCTION_LINES + 1} lines)"]
    assert _long_functions(PACKAGE / "fake.py", f"def f():\n{body[:-len('    x79 = 79')-1]}") == []
