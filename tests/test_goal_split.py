"""The two-level split on drones: MASP's Goal Matcher above the planners' flight, Hungarian goals above its executor."""
import pytest
import torch

from masp_lite import evaluation as ev
from masp_lite.algos.team import hungarian_goals
from masp_lite.cli.evaluate import split_sets
from masp_lite.envs import make
from masp_lite.nets.decoding import joint_argmax
from masp_lite.policies import make_policy
from masp_lite.policies.goal_sources import GOAL_SOURCES, GoalMatcherGoals
from masp_lite.weights import default_checkpoint, load_weights, method_checkpoint

#: Every planner that can fly another goal source's goals.
PLANNERS = ("h-greedy", "h-orca", "h-rrtstar", "h-voronoi")


def _decoded(nets, world, obs):
    """What the Goal Matcher of ``nets`` decodes for ``obs``, computed here without the policies."""
    with torch.inference_mode():
        return joint_argmax(nets.gm_logits(obs, world.scenario.world_size / 2), obs["alive"])


@pytest.mark.parametrize("method", PLANNERS)
def test_planner_flies_exactly_the_goals_the_goal_matcher_decoded(method):
    world = make("drone-20", num_envs=2, seed=0)
    nets, _ = load_weights(None, scenario=world.scenario)          # the shipped masp weights
    policy = make_policy(method, world, goals="masp")
    obs = world.reset(seed=0)
    policy.reset(obs)
    differs = False
    for t in range(7):
        actions = policy.act(obs)
        if t % 3 == 0:                                              # every global step: the Goal Matcher's goals
            want = _decoded(nets, world, obs)
            assert torch.equal(torch.as_tensor(policy.goal_index), want), f"{method}, step {t}"
            target = torch.as_tensor(policy.goal).to(obs["landmark_pos"].dtype)
            assert torch.allclose(target, torch.gather(obs["landmark_pos"], 1, want.unsqueeze(-1).expand(-1, -1, 3)))
            differs |= not torch.equal(want, hungarian_goals(obs["agent_pos"], obs["landmark_pos"], obs["alive"]))
        obs, _ = world.step(actions)
    assert differs, "on these layouts the Goal Matcher's goals must differ from the Hungarian ones"


def test_planner_takes_the_velocity_goal_matcher_and_a_checkpoint():
    world = make("drone-20", num_envs=1, seed=0)
    obs = world.reset(seed=1)
    path = method_checkpoint("masp-velocity", world.scenario, ("drone-5", "drone-20"))
    for policy in (make_policy("h-orca", world, goals="masp-velocity"),
                   make_policy("h-orca", world, goals="masp-velocity", checkpoint=str(path))):
        assert policy.source.policy.nets.config.action == "velocity"
        policy.reset(obs)
        policy.act(obs)
        nets, _ = load_weights(path, scenario=world.scenario)
        assert torch.equal(torch.as_tensor(policy.goal_index), _decoded(nets, world, obs))
    with pytest.raises(ValueError, match="masp-velocity: the checkpoint's networks"):   # masp's weights refused
        make_policy("h-orca", world, goals="masp-velocity", checkpoint=str(default_checkpoint(world.scenario)))


def test_a_dropped_drone_gets_no_goal():
    world = make("drone-5", num_envs=1, seed=0)
    source = GoalMatcherGoals(world)
    obs = world.reset(seed=0)
    obs = {**obs, "alive": obs["alive"].clone()}
    obs["alive"][0, 2] = False
    goals = source(obs)
    assert goals[0, 2] == -1 and bool((goals[0, [0, 1, 3, 4]] >= 0).all())
    alive_goals = goals[0][obs["alive"][0]]
    assert len(set(alive_goals.tolist())) == 4                     # distinct goals for the alive drones


@pytest.mark.parametrize("method", ["masp", "masp-velocity"])
def test_masp_executor_flies_the_hungarian_goals(method):
    world = make("drone-20", num_envs=2, seed=0)
    policy = make_policy(method, world, decode="hungarian")
    obs = world.reset(seed=0)
    policy.reset(obs)
    for t in range(7):
        actions = policy.act(obs)
        if t % 3 == 0:
            want = hungarian_goals(obs["agent_pos"], obs["landmark_pos"], obs["alive"])
            assert torch.equal(policy.goals, want), f"{method}, step {t}"
            assert not torch.equal(want, _decoded(policy.nets, world, obs))   # not the Goal Matcher's
        obs, _ = world.step(actions)


def test_evaluate_records_the_goal_source():
    record = ev.evaluate("h-greedy", "drone-5", episodes=2, seeds=[0], method_options={"goals": "masp"})
    assert record["method_options"] == {"goals": "masp"}
    assert record["sr"]["mean"] >= 0.8                              # the straight flight covers MASP's goals
    assert split_sets(["goals=masp"], "h-orca", "drone-20") == ({}, {"goals": "masp"})
    assert split_sets(["decode=hungarian"], "masp-velocity", "drone-20") == ({}, {"decode": "hungarian"})


def test_bad_goal_sources_are_one_clear_error():
    world = make("drone-5", num_envs=1, seed=0)
    for method in PLANNERS:
        with pytest.raises(ValueError, match=r"goals: expected one of \['hungarian', 'masp', 'masp-velocity'\]"):
            make_policy(method, world, goals="gm")
        with pytest.raises(ValueError, match="checkpoint: the Hungarian goals take no weights"):
            make_policy(method, world, checkpoint="weights.pt")
    with pytest.raises(ValueError, match="h-bottleneck: its min-max assignment is its goal source"):
        make_policy("h-bottleneck", world, goals="masp")
    assert GOAL_SOURCES[0] == "hungarian"
