"""Training CLI: resume after an interruption reproduces an uninterrupted run; Ctrl-C; bad input; weights files."""
import json
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from masp_lite.__main__ import main
from masp_lite.config import TrainConfig
from masp_lite.envs import get_scenario
from masp_lite.nets.masp import MASPNets
from masp_lite.training import parse_config, train
from masp_lite.weights import load_weights, save_weights

TINY = dict(num_envs=3, updates=4, checkpoint_every=2, eval_every=2, eval_episodes=2, ppo_epochs=1,
            num_minibatches=2, width=8)


def MAPPOConfig(**flat) -> TrainConfig:  # noqa: N802  (the tests' tiny configurations, by flat names)
    return TrainConfig.from_flat(flat)


class Killed(Exception):
    pass


def _kill_at(n):
    def hook(trainer):
        if trainer.iterations == n:
            raise Killed
    return hook


def test_interrupted_and_resumed_run_ends_with_the_same_parameters(tmp_path):
    cfg = MAPPOConfig(**TINY)
    whole = train("mpe-5", cfg, tmp_path / "whole", seed=3, progress=False)
    with pytest.raises(Killed):  # killed after iteration 3; the last checkpoint is iteration 2
        train("mpe-5", cfg, tmp_path / "cut", seed=3, progress=False, on_iteration=_kill_at(3))
    assert not (tmp_path / "cut" / "manifest.json").exists()
    resumed = train("mpe-5", cfg, tmp_path / "cut", seed=3, resume=True, progress=False)
    a = torch.load(tmp_path / "whole" / "state.pt", weights_only=True)
    b = torch.load(tmp_path / "cut" / "state.pt", weights_only=True)
    assert a["iterations"] == b["iterations"] == 4
    for k in a["nets"]:
        assert torch.equal(a["nets"][k], b["nets"][k]), k
    assert torch.equal(a["generator"], b["generator"])
    assert whole["env_steps"] == resumed["env_steps"] == 4 * 3 * 18
    assert whole["final_eval"] == {**resumed["final_eval"], "decision_ms": whole["final_eval"]["decision_ms"]}
    rows = (tmp_path / "cut" / "progress.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["1", "2", "3", "4"]
    m = json.loads((tmp_path / "cut" / "manifest.json").read_text())
    assert m["seed"] == 3 and m["scenario"] == "mpe-5" and m["wall_clock_s"] > 0 and m["config"]["updates"] == 4


def test_a_fixed_size_variant_resumes(tmp_path):
    """An mlp variant's state records the team size the trainer set; resuming with the same settings works."""
    cfg = MAPPOConfig(**{**TINY, "updates": 2, "goal_matcher": "mlp", "executor": "mlp"})
    with pytest.raises(Killed):
        train("mpe-5", cfg, tmp_path / "cut", progress=False, on_iteration=_kill_at(2))
    m = train("mpe-5", MAPPOConfig(**{**TINY, "updates": 3, "goal_matcher": "mlp", "executor": "mlp"}),
              tmp_path / "cut", resume=True, progress=False)
    assert m["env_steps"] == 3 * 3 * 18


def test_ctrl_c_during_train_keeps_the_checkpoint_and_prints_the_resume_command(tmp_path, capsys):
    """A real SIGINT to a tiny ``train`` in a subprocess, once its first checkpoint is written."""
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "run"
    sets = dict(num_envs=2, updates=1000, checkpoint_every=1, eval_every=0, eval_episodes=2, ppo_epochs=1,
                num_minibatches=1, width=8, horizon=6)
    cmd = [sys.executable, "-m", "masp_lite", "train", "--scenario", "mpe-5", "--out", str(out), "--threads", "1",
           "--quiet", *(x for k, v in sets.items() for x in ("--set", f"{k}={v}"))]
    # a shell that starts jobs in the background ignores SIGINT; the command itself must get it
    proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not (out / "state.pt").exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert (out / "state.pt").exists(), "no checkpoint appeared"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    done = int(re.search(r"the last checkpoint, iteration (\d+) of 1000, is whole in", err).group(1))
    assert done >= 1 and torch.load(out / "state.pt", weights_only=True)["iterations"] == done
    resume = shlex.split(err.split("Resume the run with:")[1].strip().splitlines()[0])
    assert resume[1:4] == ["-m", "masp_lite", "train"] and resume[-1] == "--resume"
    assert main([*resume[3:], "--set", f"updates={done + 1}"]) == 0  # the printed command, one iteration more
    m = json.loads((out / "manifest.json").read_text())
    assert m["iterations"] == done + 1 and m["overrides"] == {"horizon": 6}
    rows = (out / "progress.csv").read_text().splitlines()[1:]
    assert [int(r.split(",")[0]) for r in rows] == list(range(1, done + 2))
    assert "final evaluation (deterministic, 2 episodes): SR" in capsys.readouterr().out


def test_progress_bar_tells_training_rollouts_from_the_evaluation(tmp_path, capsys):
    train("mpe-5", MAPPOConfig(**{**TINY, "updates": 2, "eval_every": 1}), tmp_path / "run", progress=True)
    bar = capsys.readouterr().err
    assert "training rollouts (sampled): SR" in bar and "evaluation (deterministic) at 2: SR" in bar
    assert "sr=" not in bar


def test_resume_errors_leave_files_alone(tmp_path):
    cfg = MAPPOConfig(**{**TINY, "updates": 2})
    with pytest.raises(ValueError, match="--resume"):
        train("mpe-5", cfg, tmp_path / "none", progress=False, resume=True)
    out = tmp_path / "run"
    train("mpe-5", cfg, out, progress=False)
    before = (out / "state.pt").read_bytes()
    with pytest.raises(ValueError, match="exists"):
        train("mpe-5", cfg, out, progress=False)
    with pytest.raises(ValueError, match="trained on"):
        train("mpe-20", cfg, out, progress=False, resume=True)
    with pytest.raises(ValueError, match="differs in"):
        train("mpe-5", MAPPOConfig(**{**TINY, "updates": 2, "lr": 1e-3}), out, progress=False, resume=True)
    assert (out / "state.pt").read_bytes() == before
    (out / "state.pt").write_bytes(before[: len(before) // 2])
    with pytest.raises(ValueError, match="could not read"):
        train("mpe-5", cfg, out, progress=False, resume=True)


def test_weights_checks(tmp_path):
    torch.manual_seed(0)
    nets = MASPNets(width=8)
    path = tmp_path / "w.pt"
    save_weights(path, nets, "mpe-20")
    loaded, rec = load_weights(path, scenario="mpe-20to10")       # a team change uses its N1 weights
    assert rec["scenario"] == "mpe-20" and loaded.arch == nets.arch
    for k, v in nets.state_dict().items():
        assert torch.equal(loaded.state_dict()[k], v)
    with pytest.raises(ValueError, match="trained for 'mpe-20'"):
        load_weights(path, scenario="mpe-5")
    raw = torch.load(path, weights_only=True)
    raw["arch"]["width"] = 16
    torch.save(raw, tmp_path / "arch.pt")
    with pytest.raises(ValueError, match="architecture"):
        load_weights(tmp_path / "arch.pt", scenario="mpe-20")
    (tmp_path / "cut.pt").write_bytes(path.read_bytes()[:1000])
    with pytest.raises(ValueError, match="could not read"):
        load_weights(tmp_path / "cut.pt")
    torch.save({"format": "other"}, tmp_path / "other.pt")
    with pytest.raises(ValueError, match="format"):
        load_weights(tmp_path / "other.pt")
    with pytest.raises(ValueError, match="existing"):
        load_weights(tmp_path / "missing.pt")


def test_parse_config_and_cli_errors(tmp_path, capsys):
    cfg, over = parse_config(["updates=7", "lr=0.001", "num_obstacles=2"])
    assert cfg.run.updates == 7 and cfg.ppo.lr == 0.001 and over == {"num_obstacles": 2}
    with pytest.raises(ValueError, match="unknown"):
        parse_config(["bogus=1"])
    with pytest.raises(ValueError, match="expected an int"):
        parse_config(["updates=many"])
    assert parse_config(["train_executor=False"])[0].run.train_executor is False
    assert parse_config(["train_executor=true"])[0].run.train_executor is True
    with pytest.raises(ValueError, match="expected true or false"):
        parse_config(["train_executor=0"])
    assert parse_config(["team_after=none"])[1] == {"team_after": None}  # the grammar of every command
    assert parse_config(["team_after=10"])[1] == {"team_after": 10}
    assert main(["train", "--method", "nope", "--scenario", "mpe-5", "--out", str(tmp_path / "x")]) == 2
    assert "not a method trained on particle worlds" in capsys.readouterr().err
    assert main(["train", "--scenario", "mpe-5", "--out", str(tmp_path / "y"), "--resume", "--quiet"]) == 2
    assert not (tmp_path / "y").exists()


def test_shipped_weights_load_and_act():
    """Every shipped weights file, and every packaged one of the other learned methods, loads and acts."""
    from masp_lite.envs import make
    from masp_lite.policies import METHODS, make_policy
    from masp_lite.weights import MANIFEST, read_manifest
    if not MANIFEST.exists():
        pytest.skip("no shipped weights in this version")
    assert all((MANIFEST.parent / e["file"]).stat().st_size < 1_000_000 for e in read_manifest().values())
    runs = [("masp", name) for name in read_manifest()]
    runs += [(m, preset) for m, kinds in METHODS.items() for e in kinds.values()
             if isinstance(e.get("weights"), tuple) for preset in e["weights"]]
    assert len(runs) >= 24
    for method, name in runs:
        w = make(name, num_envs=2, seed=0, **({"horizon": 5} if name.startswith("drone") else {}))
        pol = make_policy(method, w)
        obs = w.reset()
        pol.reset(obs)
        shape = (2, w.num_agents, 4) if w.scenario.kind == "drone" else (2, w.num_agents)
        assert pol.act(obs).shape == shape, (method, name)  # drones: motor commands


def test_shipped_file_that_differs_from_manifest_is_refused(tmp_path, monkeypatch):
    import masp_lite.weights as ck
    monkeypatch.setattr(ck, "HERE", tmp_path)
    monkeypatch.setattr(ck, "MANIFEST", tmp_path / "manifest.json")
    save_weights(tmp_path / "mpe-5.pt", MASPNets(width=8), "mpe-5")
    (tmp_path / "manifest.json").write_text(json.dumps({"mpe-5": {"file": "mpe-5.pt", "sha256": "0" * 64}}))
    with pytest.raises(ValueError, match="differ from manifest"):
        load_weights(None, scenario="mpe-5")
    with pytest.raises(ValueError, match="no shipped weights"):
        load_weights(None, scenario="mpe-20")


def test_goal_matcher_only_fine_tuning_leaves_the_executor_untouched(tmp_path):
    from masp_lite.algos.masp_trainer import MASPTrainer
    cfg = MAPPOConfig(**{**TINY, "train_executor": False})
    t = MASPTrainer("mpe-5", cfg, seed=1)
    before = {k: v.clone() for k, v in t.nets.state_dict().items()}
    norm_before = {k: v.clone() for k, v in t.cae_norm.state_dict().items()}
    row = t.iteration()
    after = t.nets.state_dict()
    frozen = [k for k in before if k.startswith(("cae.", "cae_critic."))]
    trained = [k for k in before if k.startswith(("gm.", "gm_critic."))]
    assert frozen and trained
    assert all(torch.equal(before[k], after[k]) for k in frozen)
    assert any(not torch.equal(before[k], after[k]) for k in trained)
    assert all(torch.equal(v, t.cae_norm.state_dict()[k]) for k, v in norm_before.items())
    assert row["cae_policy_loss"] != row["cae_policy_loss"] and row["gm_policy_loss"] == row["gm_policy_loss"]
    with pytest.raises(ValueError, match="train_executor"):
        MAPPOConfig(train_executor="no")


def test_ship_run_keeps_every_stage_and_ships_only_where_told(tmp_path):
    from masp_lite.reproduction.shipping import ship_run
    weights_dir, history = tmp_path / "weights", tmp_path / "history"
    cfg = MAPPOConfig(**{**TINY, "updates": 2})
    first = train("mpe-5", cfg, tmp_path / "first", seed=0, progress=False)
    second = train("mpe-5", cfg, tmp_path / "second", seed=1, progress=False, init=tmp_path / "first" / "weights.pt",
                   overrides={"num_obstacles": 7})
    with pytest.raises(ValueError, match="expected a run manifest"):
        bogus = tmp_path / "bogus.json"
        bogus.write_text("{}")
        ship_run(tmp_path / "second", history, earlier=[(bogus, tmp_path / "first" / "progress.csv")])
    earlier = [(tmp_path / "first" / "manifest.json", tmp_path / "first" / "progress.csv")]
    kept = ship_run(tmp_path / "second", history, earlier=earlier, note="a training seed")
    assert (history / "mpe-5-seed1.pt").exists() and not weights_dir.exists()  # not shipped: kept beside the history
    entry = ship_run(tmp_path / "second", history, weights_dir, earlier=earlier, note="two stages")
    assert kept["stages"] == entry["stages"] and entry["note"] == "two stages"
    last = entry["stages"][-1]["training"]
    assert last["seed"] == 1 and last["init"].endswith("weights.pt") and last["overrides"] == {"num_obstacles": 7}
    assert [s["training"]["seed"] for s in entry["stages"]] == [0, 1]
    assert entry["stages"][0]["training"]["wall_clock_s"] == first["wall_clock_s"]
    first_curve = (tmp_path / "first" / "progress.csv").read_text()
    assert (history / "mpe-5-seed1.stage1.progress.csv").read_text() == first_curve
    assert json.loads((history / "mpe-5-seed1.manifest.json").read_text()) == entry
    slim = json.loads((weights_dir / "manifest.json").read_text())["mpe-5"]
    assert slim["stages"] == 2 and slim["env_steps"] == first["env_steps"] + second["env_steps"]
    assert slim["history"] == "results/training/mpe-5-seed1.manifest.json"
    nets, _ = load_weights(weights_dir / "mpe-5.pt", scenario="mpe-5")
    assert nets.arch["width"] == 8 and second["iterations"] == 2
    # a kept history stands for all its stages: a third stage on top of the two kept ones
    train("mpe-5", cfg, tmp_path / "third", seed=1, progress=False, init=tmp_path / "second" / "weights.pt")
    three = ship_run(tmp_path / "third", tmp_path / "later", earlier=[history / "mpe-5-seed1.manifest.json"])
    assert [s["training"] for s in three["stages"][:2]] == [s["training"] for s in entry["stages"]]
    assert (tmp_path / "later" / "mpe-5-seed1.stage1.progress.csv").read_text() == first_curve
    assert len(three["stages"]) == 3 and (tmp_path / "later" / "mpe-5-seed1.stage2.progress.csv").exists()
    with pytest.raises(ValueError, match="expected a training history"):
        ship_run(tmp_path / "third", tmp_path / "later", earlier=[tmp_path / "third" / "manifest.json"])


def test_a_preset_can_ship_another_presets_weights_zero_shot(tmp_path, monkeypatch):
    import masp_lite.weights as weights
    from masp_lite.reproduction.shipping import ship_run, ship_zero_shot
    cfg = MAPPOConfig(**{**TINY, "updates": 1})
    train("mpe-5", cfg, tmp_path / "run", seed=0, progress=False)
    wd = tmp_path / "weights"
    with pytest.raises(ValueError, match="expected shipped weights trained on 'mpe-5'"):
        ship_zero_shot(wd, "mpe-20", "mpe-5", note="no weights yet")
    ship_run(tmp_path / "run", tmp_path / "history", wd)
    entry = ship_zero_shot(wd, "mpe-20", "mpe-5", note="the mpe-5 weights, zero-shot")
    assert entry["file"] == "mpe-5.pt" and entry["trained_on"] == "mpe-5" and entry["scenario"] == "mpe-20"
    monkeypatch.setattr(weights, "HERE", wd)
    monkeypatch.setattr(weights, "MANIFEST", wd / "manifest.json")
    assert weights.trained_preset("mpe-20to10") == "mpe-5" and weights.trained_preset("mpe-50") == "mpe-50"
    nets, rec = weights.load_weights(scenario=get_scenario("mpe-20"))       # the shipped default: accepted
    assert rec["scenario"] == "mpe-5"
    with pytest.raises(ValueError, match="trained for 'mpe-5'"):
        weights.load_weights(wd / "mpe-5.pt", scenario=get_scenario("mpe-50"))
    train("mpe-5", cfg, tmp_path / "run2", seed=0, progress=False, init=tmp_path / "run" / "weights.pt")
    ship_run(tmp_path / "run2", tmp_path / "history", wd)                    # re-shipping mpe-5 updates mpe-20
    manifest = json.loads((wd / "manifest.json").read_text())
    assert manifest["mpe-20"]["sha256"] == manifest["mpe-5"]["sha256"] == weights.sha256(wd / "mpe-5.pt")
    assert manifest["mpe-20"]["note"] == "the mpe-5 weights, zero-shot"
    # a team change may have an entry of its own, ahead of the preset it starts from
    manifest = json.loads((wd / "manifest.json").read_text())
    manifest["mpe-50"] = {**manifest["mpe-5"], "scenario": "mpe-50"}                       # as if trained there
    (wd / "manifest.json").write_text(json.dumps(manifest))
    assert weights.trained_preset("mpe-50to20") == "mpe-50"
    ship_zero_shot(wd, "mpe-50to20", "mpe-5", note="chosen on validation")
    assert weights.trained_preset("mpe-50to20") == "mpe-5" and weights.trained_preset("mpe-50") == "mpe-50"
    assert weights.shipped_entry("mpe-50to20")["note"] == "chosen on validation"
    assert weights.default_checkpoint("mpe-50to20") == wd / "mpe-5.pt"


def test_init_refuses_another_architecture(tmp_path):
    train("mpe-5", MAPPOConfig(**{**TINY, "updates": 1}), tmp_path / "base", seed=0, progress=False)
    with pytest.raises(ValueError, match="differs from the configured"):
        train("mpe-5", MAPPOConfig(**{**TINY, "updates": 1, "width": 16}), tmp_path / "wide", seed=0, progress=False,
              init=tmp_path / "base" / "weights.pt")


def test_weights_remember_their_world_and_refuse_another(tmp_path):
    from masp_lite.weights import read_weights, trained_world
    paper = get_scenario("mpe-5", integration="velocity_first", landmark_spawn="central")
    save_weights(tmp_path / "w.pt", MASPNets(width=8), paper)
    assert trained_world(read_weights(tmp_path / "w.pt")) == paper.world
    load_weights(tmp_path / "w.pt", scenario=paper)                                  # its own world: fine
    with pytest.raises(ValueError, match="trained in the world integration=velocity_first"):
        load_weights(tmp_path / "w.pt", scenario=get_scenario("mpe-5", integration="mpe2", landmark_spawn="whole"))
    load_weights(tmp_path / "w.pt", scenario=get_scenario("mpe-5", integration="mpe2"), any_scenario=True)


def test_chunked_kernels_train_like_plain_autograd():
    """One training iteration with the chunked kernels and with plain autograd: same numbers."""
    from masp_lite.algos.masp_trainer import MASPTrainer
    from masp_lite.nets.kernels import use_kernels
    cfg = TrainConfig.from_flat({"num_envs": 4, "ppo_epochs": 2, "gm_ppo_epochs": 2})
    fast = MASPTrainer("mpe-5", cfg, seed=3)
    row_fast = fast.iteration()
    plain = MASPTrainer("mpe-5", cfg, seed=3)
    assert use_kernels(plain.nets, False) is plain.nets and not plain.nets.cae.fusion.kernel
    assert not plain.nets.gm.cross.kernel and fast.nets.gm.cross.kernel
    row_plain = plain.iteration()
    for k in ("train_sr", "train_steps", "train_cr", "gm_reward", "cae_reward"):
        assert row_fast[k] == pytest.approx(row_plain[k], rel=1e-4, abs=1e-6), k
    for (name, a), b in zip(fast.nets.state_dict().items(), plain.nets.state_dict().values()):
        torch.testing.assert_close(a, b, rtol=1e-3, atol=1e-4, msg=name)


def test_a_trainer_subclass_changes_one_part_and_nothing_else(tmp_path):
    """``train(trainer_type=...)``: the subclass's goal draw is the one trained on; the same draw gives the
    product's weights; anything but a subclass of the world kind's trainer is refused before a file is written."""
    from masp_lite.algos.masp_trainer import MASPTrainer
    from masp_lite.nets.goal_draw import sequential_sample
    calls = []

    class Counted(MASPTrainer):
        @staticmethod
        def draw_goals(logits, alive, generator):
            calls.append(logits.shape)
            return sequential_sample(logits, alive, generator)

    cfg = MAPPOConfig(**{**TINY, "updates": 1, "eval_every": 0})
    train("mpe-5", cfg, tmp_path / "plain", progress=False)
    train("mpe-5", cfg, tmp_path / "counted", progress=False, trainer_type=Counted)
    assert len(calls) == 6  # one draw every global step (3) of an 18-step episode
    a, b = (load_weights(tmp_path / run / "weights.pt")[0].state_dict() for run in ("plain", "counted"))
    assert all(torch.equal(a[k], b[k]) for k in a)
    for bad in (object, MASPNets, "MASPTrainer"):
        with pytest.raises(ValueError, match="trainer_type: expected a subclass of MASPTrainer"):
            train("mpe-5", cfg, tmp_path / "bad", progress=False, trainer_type=bad)
    assert not (tmp_path / "bad").exists()


class _Replay:
    """A policy that sends, step by step, the commands a training rollout sent its world."""

    def __init__(self, commands):
        self.commands = commands

    def reset(self, obs):
        self.t = 0

    def act(self, obs):
        self.t += 1
        return self.commands[self.t - 1]


@pytest.mark.parametrize("scenario", ["mpe-5", "mpe-20to10"])
def test_training_measures_sr_and_steps_as_evaluate_does(scenario):
    """The SR, Steps and CR of a training rollout (the shipped networks, sampling) are those of evaluate's
    metrics on the same episodes, replayed in a fresh world of the same seed: a shrinking team included,
    whose SR counts the landmarks ever reached, not those covered at the end."""
    from masp_lite.algos.masp_trainer import MASPTrainer
    from masp_lite.envs import make
    from masp_lite.evaluation import collision_rate, rollout, steps, success_rate

    nets, _ = load_weights(None, scenario=scenario)
    # seed 7: the shipped mpe-20 weights, sampling, finish some shrinking-team episode within the horizon there
    trainer = MASPTrainer(scenario, TrainConfig.from_flat({**vars(nets.config), "num_envs": 16}), seed=7)
    trainer.nets.load_state_dict(nets.state_dict())
    commands, step = [], trainer.world.step
    trainer.world.step = lambda command: commands.append(command.clone()) or step(command)
    _, _, stats = trainer.collect()
    log, _ = rollout(make(scenario, num_envs=16, seed=7), _Replay(commands), episodes=16)
    assert stats == pytest.approx({"sr": float(success_rate(log).mean()), "steps": float(steps(log).mean()),
                                   "cr": float(collision_rate(log).mean())})
    assert stats["steps"] < log.horizon  # some episode solved (seed 7): Steps is not just the horizon
    if log.varying:  # the fixed-team rule (covered at the end) would have said less
        assert stats["sr"] > float(log.covered[:, -1].double().mean())
