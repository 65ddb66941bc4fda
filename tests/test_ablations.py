"""The paper's ablations as settings of the one MASP: random goals, and an MLP instead of a graph."""
import pytest
import torch

from masp_lite.algos.masp_trainer import MASPTrainer
from masp_lite.config import NetConfig
from masp_lite.envs import make
from masp_lite.evaluation import evaluate
from masp_lite.nets.ablations import FusionMLP, GoalMatcherMLP, agent_first
from masp_lite.nets.masp import MASPNets
from masp_lite.policies import make_policy
from masp_lite.training import parse_config
from masp_lite.weights import save_weights


def test_agent_k_comes_first_then_the_others_in_order():
    assert agent_first(4).tolist() == [[0, 1, 2, 3], [1, 0, 2, 3], [2, 0, 1, 3], [3, 0, 1, 2]]


def test_settings_are_checked():
    with pytest.raises(ValueError, match="goal_matcher: expected one of"):
        NetConfig(goal_matcher="gnn")
    with pytest.raises(ValueError, match="executor: expected one of"):
        NetConfig(executor="transformer")
    with pytest.raises(ValueError, match="needs team_size"):
        MASPNets(goal_matcher="mlp")


def test_the_mlps_take_one_team_size_and_see_every_agent():
    gm = GoalMatcherMLP(8, team_size=5)
    a, g, d = torch.randn(2, 5, 5), torch.randn(2, 5, 4), torch.randn(2, 5, 5, 2)
    alive = torch.ones(2, 5, dtype=torch.bool)
    logits = gm(a, g, d, alive)
    assert logits.shape == (2, 5, 5)
    moved = a.clone()
    moved[:, 4] += 1.0                                          # agent 4 moves: every agent's logits change
    assert (gm(moved, g, d, alive) - logits).abs().sum(-1).min() > 0
    with pytest.raises(ValueError, match="built for 5 agents"):
        gm(torch.randn(2, 6, 5), torch.randn(2, 6, 4), torch.randn(2, 6, 6, 2), torch.ones(2, 6, dtype=torch.bool))
    fusion = FusionMLP(6, 8, team_size=5)
    assert fusion(torch.randn(2, 5, 5, 6), None, alive).shape == (2, 5, 8)
    with pytest.raises(ValueError, match="built for 5 agents"):
        fusion(torch.randn(2, 4, 4, 6), None, torch.ones(2, 4, dtype=torch.bool))


def _trainer(*sets, scenario="mpe-20"):
    cfg, overrides = parse_config([*sets, "num_envs=2"])
    return MASPTrainer(scenario, cfg, seed=0, overrides=overrides)


def test_random_goals_train_only_the_executor():
    t = _trainer("goal_matcher=random")
    before = {k: v.clone() for k, v in t.nets.state_dict().items()}
    row = t.iteration()
    after = t.nets.state_dict()
    changed = {k.split(".")[0] for k in before if not torch.equal(before[k], after[k])}
    assert changed == {"cae", "cae_critic"}
    assert row["gm_reward"] != row["gm_reward"] and row["cae_reward"] == row["cae_reward"]   # NaN: no GM reward


def test_mlp_variants_are_built_for_the_scenarios_team():
    t = _trainer("goal_matcher=mlp", scenario="mpe-5")
    assert t.nets.arch["team_size"] == 5 and isinstance(t.nets.gm, GoalMatcherMLP)
    with pytest.raises(ValueError, match="set to 20 agents"):
        _trainer("executor=mlp", "team_size=20", scenario="mpe-5")


def test_each_method_takes_only_its_own_weights(tmp_path):
    world = make("mpe-5", num_envs=3, seed=0)
    paths = {}
    for name, arch in (("masp", {}), ("gm-mlp", {"goal_matcher": "mlp", "team_size": 5}),
                       ("cae-mlp", {"executor": "mlp", "team_size": 5}), ("masp-rg", {"goal_matcher": "random"})):
        paths[name] = tmp_path / f"{name}.pt"
        save_weights(paths[name], MASPNets(**arch), "mpe-5")
    for name, path in paths.items():
        make_policy(name, world, checkpoint=str(path))
    with pytest.raises(ValueError, match="these are gm-mlp weights: use that method"):
        make_policy("masp", world, checkpoint=str(paths["gm-mlp"]))
    with pytest.raises(ValueError,
                       match="expected {'goal_matcher': 'random', 'executor': 'graph'}; these are masp weights"):
        make_policy("masp-rg", world, checkpoint=str(paths["masp"]))
    with pytest.raises(ValueError, match="built for 5 agents .* evaluate it at N = 5 only"):
        make_policy("gm-mlp", make("mpe-20", num_envs=1, seed=0), checkpoint=str(paths["gm-mlp"]),
                    any_scenario=True)
    rec = evaluate("cae-mlp", "mpe-5", episodes=2, seeds=[0], checkpoint=paths["cae-mlp"])
    assert rec["method"] == "cae-mlp" and 0.0 <= rec["sr"]["mean"] <= 1.0


def test_random_goals_are_distinct_and_held_unless_resampled(tmp_path):
    path = tmp_path / "rg.pt"
    save_weights(path, MASPNets(goal_matcher="random"), "mpe-5")
    world = make("mpe-5", num_envs=8, seed=0)
    for resample, held in ((False, True), (True, False)):
        obs = world.reset(seed=1)
        policy = make_policy("masp-rg", world, checkpoint=str(path), resample=resample)
        policy.reset(obs)
        seen = []
        for _ in range(7):                                       # global steps at t = 0, 3, 6
            policy.act(obs)
            seen.append(policy.goals.clone())
            obs, _ = world.step(torch.zeros(8, 5, dtype=torch.long))
        assert all(sorted(g.tolist()) == list(range(5)) for g in seen[0])              # a permutation per world
        assert all(torch.equal(seen[0], s) for s in seen) == held


def test_curves_of_kept_seeds_are_banded(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    from masp_lite.reproduction.histories import kept_curves
    from masp_lite.viz.progress import plot_seed_bands
    folder = tmp_path / "results" / "training" / "v"
    folder.mkdir(parents=True)
    for seed, sr in ((0, 0.2), (1, 0.4)):
        rows = "".join(f"{i},{i * 100},{sr + 0.01 * i}\n" for i in range(1, 11))
        (folder / f"mpe-20-seed{seed}.progress.csv").write_text("iteration,env_steps,train_sr\n" + rows)
    (folder / "mpe-20-seed2.stage1.progress.csv").write_text("iteration,env_steps,train_sr\n1,100,0.5\n")  # not a seed
    curves = kept_curves("v", root=tmp_path)
    assert sorted(curves) == [0, 1] and kept_curves("none", root=tmp_path) == {}
    ax = plot_seed_bands({"v": curves, "empty": {}}, smooth=3)
    (line,) = ax.get_lines()
    assert len(line.get_xdata()) == 8 and line.get_ydata()[0] == pytest.approx(0.32)   # mean of 0.22 and 0.42
    assert len(ax.collections) == 1 and "2 seeds" in line.get_label()
