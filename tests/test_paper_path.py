"""The paper's files hold the paper: variants beside the path, one network class for both worlds, named inputs.

* the reading path (``help(masp_lite)``) branches on no ablation's or baseline's name: their goal
  sources (:mod:`masp_lite.algos.goal_sources`) and network parts (:mod:`masp_lite.nets.variants`)
  are chosen once, from tables;
* :class:`~masp_lite.nets.drones.DroneNets` is :class:`~masp_lite.nets.masp.MASPNets` plus only what
  the drone world changes;
* the executor's inputs travel by name, and a rollout stores them under those names.
"""
import ast
from pathlib import Path

import pytest
import torch

import masp_lite
from masp_lite.algos.goal_sources import SOURCES, HungarianGoals, NoGoals, RandomGoals, goal_source
from masp_lite.config import EXECUTORS, GOAL_MATCHERS
from masp_lite.nets.masp import ExecutorInputs, MASPNets
from masp_lite.policies import METHODS
from masp_lite.training import method_config

PACKAGE = Path(masp_lite.__file__).parent
READING_PATH = [line.split()[1].strip("`") for line in masp_lite.__doc__.splitlines()
                if line[:1].isdigit() and "``" in line]
#: What names a variant: the ablations' and baselines' methods, and the settings that make them (MASP's is graph).
VARIANT_NAMES = {m for m, kinds in METHODS.items() for e in kinds.values() if e.get("group")} | \
    (set(GOAL_MATCHERS) | set(EXECUTORS)) - {"graph"}
SETTINGS = {"goal_matcher", "executor"}


def variant_branches(source: str) -> list[str]:
    """Comparisons that test a variant setting (``x.goal_matcher``, ``x.executor``) or a variant's name."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare):
            names = {c.value for c in ast.walk(node) if isinstance(c, ast.Constant) and isinstance(c.value, str)}
            attrs = {a.attr for a in ast.walk(node) if isinstance(a, ast.Attribute)}
            if names & VARIANT_NAMES or attrs & SETTINGS:
                found.append(ast.unparse(node))
    return found


def test_the_reading_path_has_no_branch_on_a_variant():
    assert len(READING_PATH) >= 10 and "nets/masp.py" in READING_PATH and "policies/masp.py" in READING_PATH
    for name in READING_PATH:
        found = variant_branches((PACKAGE / name).read_text())
        assert not found, f"{name} branches on an ablation or baseline: {found}"


def test_the_variant_check_can_fail():
    assert variant_branches('if c.goal_matcher == "random":\n    pass\n')
    assert variant_branches('x = 1 if name in ("mappo", "darl1n") else 0\n')
    assert variant_branches('if self.nets.config.executor != "graph":\n    pass\n')
    assert not variant_branches('if decode == "independent":\n    pass\n')


def test_every_goal_source_setting_has_one_source_and_a_goal_matcher_has_none():
    assert set(SOURCES) == set(GOAL_MATCHERS) - {"graph", "mlp"}
    assert goal_source("graph") is None and goal_source("mlp") is None
    assert isinstance(goal_source("graph", decode="hungarian"), HungarianGoals)      # the policies' diagnostic
    assert isinstance(goal_source("random", decode="hungarian"), RandomGoals)        # the weights' own comes first
    assert isinstance(goal_source("none", decode="hungarian"), NoGoals)
    assert goal_source("random", resample=True).resample


def test_random_goals_are_held_until_the_team_changes():
    gen = torch.Generator().manual_seed(0)
    obs = {"alive": torch.ones(2, 4, dtype=torch.bool), "landmark_pos": torch.zeros(2, 4, 2),
           "reached": torch.zeros(2, 4, dtype=torch.bool)}
    source = RandomGoals()
    first = source.train(0, obs, None, gen, 3, False)
    assert source.train(1, obs, first, gen, 3, False) is first
    obs["alive"] = torch.tensor([[True, True, True, False]] * 2)
    again = source.train(2, obs, first, gen, 3, False)                 # the team changed: drawn at once
    assert again is not first and (again[:, :3].sort(-1).values < 4).all()
    assert HungarianGoals().train(1, obs, first, gen, 3, False) is first  # between global steps: held


def test_the_drone_networks_add_only_what_differs():
    from masp_lite.nets.drones import DroneNets
    assert issubclass(DroneNets, MASPNets)
    own = {k for k in vars(DroneNets) if not k.startswith("__")}
    assert own == {"world", "dims", "sense", "max_speed", "pair_size", "landmark_size", "inputs_type",
                   "build_executor", "own_features"}
    with pytest.raises(ValueError, match="action 'throttle' is for drone worlds; expected a particle"):
        MASPNets(action="throttle")
    with pytest.raises(ValueError, match="action 'discrete' is for particle worlds; expected a drone"):
        DroneNets()


@pytest.mark.parametrize("method,scenario,own", [("masp", "mpe-5", "obstacles"), ("mappo", "mpe-5", "obstacles"),
                                                 ("masp", "drone-5", "flight")])
def test_a_rollout_stores_the_executor_inputs_by_name(method, scenario, own):
    method, cfg, overrides = method_config(method, ["num_envs=2", "width=8", "horizon=4"], scenario)
    if scenario.startswith("drone"):
        from masp_lite.algos.drone_trainer import DroneMASPTrainer as Trainer
    else:
        from masp_lite.algos.masp_trainer import MASPTrainer as Trainer
    trainer = Trainer(scenario, cfg, seed=0, overrides=overrides)
    _, cae, _ = trainer.collect()
    fields = trainer.nets.inputs_type._fields
    assert fields == ("pair", "groups", "alive", "goal", own)
    assert set(fields) <= set(cae) and not {"goal_f", "extra_f"} & set(cae)
    inputs = trainer.nets.inputs_type(**{k: cae[k][0] for k in fields})       # step 0 of every world, by name
    assert inputs.pair.shape[:3] == (2, 5, 5) and inputs.alive.dtype == torch.bool
    with torch.inference_mode():                                             # (the rollout's tensors are inference's)
        out, _ = trainer.nets.cae_forward(inputs, {k: cae[k][0] for k in trainer.obs_keys}, 4)
    actions = cae["actions"][0]
    if trainer.distribution is None:  # the stored inputs give back the stored log-probabilities
        logp = torch.log_softmax(out, -1).gather(-1, actions.unsqueeze(-1)).squeeze(-1)
    else:
        logp, _ = trainer.distribution(out, actions)
    torch.testing.assert_close(logp, cae["logp"][0])


def test_the_particle_inputs_are_a_named_tuple_the_executor_unpacks():
    from masp_lite.envs import make
    from masp_lite.nets.fusion import random_permutation
    w = make("mpe-5", num_envs=2, seed=0)
    obs = w.reset()
    nets = MASPNets(width=8)
    inputs = nets.cae_inputs(obs, torch.zeros(2, 5, dtype=torch.long), random_permutation(2, 5))
    assert isinstance(inputs, ExecutorInputs) and inputs.obstacles.shape == (2, 5, 3 * nets.config.obstacles_seen)
    assert torch.equal(nets.cae(*inputs), nets.cae_logits(inputs))
