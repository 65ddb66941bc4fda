"""The imitation stage of ``masp-minmax`` (:mod:`masp_lite.algos.imitation`): its losses, its trainer, its recipe."""
import hashlib
import itertools

import pytest
import torch

from masp_lite.algos.imitation import (
    TEACHERS,
    ImitationTrainer,
    decoding_margin_loss,
    draw_nll,
    random_rank,
    teacher_goals,
    within_longest_trip,
)
from masp_lite.algos.team import bottleneck
from masp_lite.cli import main
from masp_lite.config import TEACHERS as TEACHER_SETTINGS
from masp_lite.envs import make
from masp_lite.nets.decoding import joint_argmax
from masp_lite.policies import make_policy
from masp_lite.recipes import IMITATION, RECIPES, Recipe, stage_config
from masp_lite.training import method_config, train
from masp_lite.weights import default_checkpoint, load_weights

TINY = ["train_executor=false", "num_envs=4", "width=8", "eval_every=0", "eval_episodes=2", "checkpoint_every=1"]


def onehot_logits(assignment, scale=4.0) -> torch.Tensor:
    """Logits (1, N, N) that favour ``assignment`` by ``scale`` nats for every agent."""
    return scale * torch.nn.functional.one_hot(torch.tensor([assignment]), len(assignment)).float()


def test_every_teacher_setting_has_one_teacher():
    assert set(TEACHERS) == set(TEACHER_SETTINGS) - {"none"}


@pytest.mark.parametrize("order", ["independent", "first", "reversed", "random"])
def test_the_loss_is_least_at_the_teachers_assignment(order):
    target = (2, 0, 3, 1)
    alive = torch.ones(1, 4, dtype=torch.bool)
    rank = {"independent": None, "first": torch.tensor([[0, 1, 2, 3]]), "reversed": torch.tensor([[3, 2, 1, 0]]),
            "random": random_rank(1, 4, torch.Generator().manual_seed(1))}[order]
    losses = {p: draw_nll(onehot_logits(p), torch.tensor([target]), alive, rank)[0].item()
              for p in itertools.permutations(range(4))}
    best = min(losses, key=losses.get)
    assert best == target and sorted(losses.values())[1] > losses[best] + 0.5


def test_descending_the_sequential_loss_makes_the_decoding_return_the_teacher():
    target = torch.tensor([[3, 1, 0, 4, 2]])
    alive = torch.ones(1, 5, dtype=torch.bool)
    logits = torch.zeros(1, 5, 5, requires_grad=True)
    opt = torch.optim.Adam([logits], lr=0.1)
    g = torch.Generator().manual_seed(0)
    first = None
    for _ in range(100):
        loss, _ = draw_nll(logits, target, alive, random_rank(1, 5, g))
        first = loss.item() if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.05 * first
    assert torch.equal(joint_argmax(logits.detach(), alive), target)


def test_agents_without_a_teacher_goal_are_left_out_and_block_nothing():
    logits = onehot_logits((0, 1, 2))
    rank = torch.tensor([[2, 0, 1]])                      # agent 1 draws first, then agent 2, then agent 0
    everyone = torch.ones(1, 3, dtype=torch.bool)
    left_out = draw_nll(logits, torch.tensor([[0, -1, 2]]), everyone, rank)[0]
    dropped = draw_nll(logits, torch.tensor([[0, 1, 2]]), torch.tensor([[True, False, True]]), rank)[0]
    labelled = draw_nll(logits, torch.tensor([[0, 1, 2]]), everyone, rank)[0]
    # agent 2 chooses among all goals, agent 0 among those agent 2 left; agent 1 is neither counted nor blocking
    logp = torch.log_softmax(logits[0], -1)
    by_hand = -(logp[2, 2] + torch.log_softmax(logits[0, 0, :2], -1)[0]) / 2
    assert left_out.item() == pytest.approx(by_hand.item()) == pytest.approx(dropped.item())
    assert labelled.item() != pytest.approx(left_out.item())
    with pytest.raises(ValueError, match="expected targets and alive of shape"):
        draw_nll(logits, torch.tensor([[0, 1]]), everyone)


def test_the_decoding_margin_is_zero_only_when_the_decoding_keeps_the_longest_trip_short():
    a = torch.tensor([[[0.0, 0.0], [0.0, 2.0]]])           # the min-sum and min-max assignments differ
    g = torch.tensor([[[3.0, 3.0], [2.0, 3.0]]])
    obs = {"agent_pos": a, "landmark_pos": g, "alive": torch.ones(1, 2, dtype=torch.bool)}
    target = teacher_goals("h-bottleneck", obs)
    assert target.tolist() == [[1, 0]]
    over = ~within_longest_trip(obs, target)
    assert over.tolist() == [[[True, False], [False, False]]]  # 4.24 m is past the longest min-max trip, 3.61 m
    good, bad = decoding_margin_loss(onehot_logits((1, 0), 6.0), over, obs["alive"])[0], \
        decoding_margin_loss(onehot_logits((0, 1), 6.0), over, obs["alive"])[0]
    assert good.item() == 0.0 and bad.item() > 1.0
    assert joint_argmax(onehot_logits((1, 0), 6.0), obs["alive"]).tolist() == [[1, 0]]


def test_descending_the_decoding_margin_finds_a_min_max_assignment():
    w = make("mpe-20", num_envs=2, seed=100)
    obs = w.reset()
    target = bottleneck(obs["agent_pos"], obs["landmark_pos"], obs["alive"])
    over = ~within_longest_trip(obs, target)
    logits = torch.zeros(2, 20, 20, requires_grad=True)
    opt = torch.optim.Adam([logits], lr=0.05)
    for _ in range(300):
        loss, _ = decoding_margin_loss(logits, over, obs["alive"], margin=1.0)
        if loss.item() == 0.0:
            break
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() == 0.0
    goals = joint_argmax(logits.detach(), obs["alive"])
    d = torch.cdist(obs["agent_pos"], obs["landmark_pos"])
    longest = lambda x: torch.gather(d, -1, x.unsqueeze(-1)).squeeze(-1).amax(-1)  # noqa: E731
    torch.testing.assert_close(longest(goals), longest(target))


def _held_out_loss(trainer, obs):
    with torch.no_grad():
        targets = teacher_goals("h-bottleneck", obs)
        return trainer.loss(trainer.nets.gm_logits(obs, trainer.scale), obs, targets, None)[0].item()


def test_a_few_imitation_steps_reduce_the_loss_on_layouts_not_trained_on():
    _, cfg, _ = method_config("masp-minmax", [*TINY, "num_envs=16", "lr=0.01", "imitate=h-bottleneck"], "mpe-5")
    trainer = ImitationTrainer("mpe-5", cfg, seed=0)
    held_out = make("mpe-5", num_envs=64, seed=100).reset()
    before = _held_out_loss(trainer, held_out)
    executor = {k: v.clone() for k, v in trainer.nets.cae.state_dict().items()}
    for _ in range(50):
        row = trainer.iteration()
    assert _held_out_loss(trainer, held_out) < 0.85 * before
    assert row["gm_policy_loss"] >= 0 and row["env_steps"] == 0  # episode starts: nothing simulated
    assert all(torch.equal(v, trainer.nets.cae.state_dict()[k]) for k, v in executor.items())  # the executor kept


def _digest(path) -> str:
    nets = torch.load(path, weights_only=True)["nets"]
    return hashlib.sha256(b"".join(nets[k].numpy().tobytes() for k in sorted(nets))).hexdigest()


def test_an_imitation_run_resumed_ends_where_an_uninterrupted_one_does(tmp_path):
    sets = [*TINY, "imitate=h-bottleneck"]
    _, cfg, _ = method_config("masp-minmax", [*sets, "updates=3"], "mpe-5")
    train("mpe-5", cfg, tmp_path / "a", seed=1, progress=False, method="masp-minmax")
    _, first, _ = method_config("masp-minmax", [*sets, "updates=1"], "mpe-5")
    train("mpe-5", first, tmp_path / "b", seed=1, progress=False, method="masp-minmax")
    train("mpe-5", cfg, tmp_path / "b", seed=1, resume=True, progress=False, method="masp-minmax")
    assert _digest(tmp_path / "a" / "state.pt") == _digest(tmp_path / "b" / "state.pt")


def _tiny_minmax() -> Recipe:
    real = RECIPES["masp-minmax"]
    return Recipe(real.name, real.method, tuple(s.__class__(**{**s.__dict__, "iterations": 2, "worlds": 2})
                                                for s in real.stages), real.about)


def test_the_recipes_imitation_stage_runs_from_masps_weights_and_is_kept(tmp_path, monkeypatch, capsys):
    recipe = RECIPES["masp-minmax"]
    _, cfg, _ = stage_config(recipe, recipe.stage("imitate-mpe-50"))
    assert cfg.imitation.imitate == "h-bottleneck" and not cfg.run.train_executor
    for p, start in (("mpe-5", "mpe-5"), ("mpe-20", "mpe-20-both"), ("mpe-50", "mpe-20-both")):
        stage = recipe.stage(f"imitate-{p}")
        assert stage.start == start and stage.keep == f"masp-minmax/{p}" and stage.settings.items() >= IMITATION.items()
    assert [s.name for s in recipe.stages if s.keep] == ["imitate-mpe-50", "imitate-mpe-20", "imitate-mpe-5"]
    monkeypatch.setitem(RECIPES, "masp-minmax", _tiny_minmax())
    out, init = tmp_path / "r", default_checkpoint("mpe-5")
    assert main(["train", "--recipe", "masp-minmax", "--stage", "imitate-mpe-5", "--init", str(init), "--out",
                 str(out), "--set", "eval_episodes=2", "--quiet"]) == 0
    weights = out / "imitate-mpe-5" / "weights.pt"
    state = torch.load(weights, weights_only=True)
    gm = [k for k in state["state_dict"] if k.startswith("gm.")]
    shipped = torch.load(init, weights_only=True)["state_dict"]
    assert any(not torch.equal(state["state_dict"][k], shipped[k]) for k in gm)          # the Goal Matcher learnt
    assert all(torch.equal(state["state_dict"][k], shipped[k]) for k in shipped if k.startswith("cae."))
    world = make("mpe-5", num_envs=1, seed=100)
    make_policy("masp-minmax", world, checkpoint=str(weights))                            # evaluate's policy
    assert load_weights(weights)[0].config.goal_matcher == "graph"
    capsys.readouterr()


def test_masp_minmax_packages_a_goal_matcher_per_preset_and_shares_masps_executor():
    from masp_lite.weights import method_checkpoint
    presets = ("mpe-5", "mpe-20", "mpe-50")
    files = {sc: method_checkpoint("masp-minmax", sc, presets) for sc in (*presets, "mpe-20to10", "mpe-50to20")}
    assert files["mpe-20to10"] == files["mpe-20"] and files["mpe-50to20"] == files["mpe-50"]
    make_policy("masp-minmax", make("mpe-50", num_envs=1, seed=100))       # packaged: no checkpoint (raised before)
    masp = torch.load(default_checkpoint("mpe-20"), weights_only=True)["state_dict"]
    mine = torch.load(files["mpe-50"], weights_only=True)["state_dict"]
    assert any(not torch.equal(mine[k], masp[k]) for k in mine if k.startswith("gm."))      # its own Goal Matcher
    assert all(torch.equal(mine[k], masp[k]) for k in mine if k.startswith("cae."))         # MASP's executor


@pytest.mark.parametrize("sets,scenario,message", [
    (["imitate=h-nope"], "mpe-5", r"imitate: expected one of \['none', 'h-bottleneck'\], got 'h-nope'"),
    (["imitation_margin=-1"], "mpe-5", r"imitation_margin: expected a finite number >= 0.0, got -1.0"),
    (["imitation_rate=1"], "mpe-5", r"--set imitation_rate: unknown; expected one of the training settings "
                                    r"\[.*'imitate', 'imitation_margin'"),
])
def test_a_bad_imitation_setting_is_one_clear_error(sets, scenario, message):
    with pytest.raises(ValueError, match=message):
        method_config("masp-minmax", sets, scenario)


def test_imitation_refuses_what_it_cannot_train(tmp_path):
    _, cfg, _ = method_config("masp-minmax", [*TINY, "imitate=h-bottleneck", "train_executor=true"], "mpe-5")
    with pytest.raises(ValueError, match="trains the Goal Matcher alone; expected --set train_executor=false"):
        train("mpe-5", cfg, tmp_path / "a", progress=False, method="masp-minmax")
    _, cfg, _ = method_config("masp-rg", [*TINY, "imitate=h-bottleneck"], "mpe-5")
    with pytest.raises(ValueError, match="no Goal Matcher to train"):
        train("mpe-5", cfg, tmp_path / "b", progress=False, method="masp-rg")
    _, cfg, _ = method_config("masp", [*TINY, "imitate=h-bottleneck"], "drone-5")
    with pytest.raises(ValueError, match="the imitation stage is for particle worlds"):
        train("drone-5", cfg, tmp_path / "c", progress=False, method="masp")
    assert not (tmp_path / "c").exists()
