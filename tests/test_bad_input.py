"""Every bad input fails with one clear ValueError naming what was expected."""
import json

import numpy as np
import pytest
import torch

from masp_lite.__main__ import main
from masp_lite.bench import load_target
from masp_lite.envs import OVERRIDES, SCENARIOS, make, parallel_env


# ------------------------------------------------------------------ scenarios and overrides
@pytest.mark.parametrize("build", [make, parallel_env])
def test_unknown_scenario_lists_the_valid_ones(build):
    with pytest.raises(ValueError) as e:
        build("mpe-7")
    assert "mpe-7" in str(e.value) and all(name in str(e.value) for name in SCENARIOS)


@pytest.mark.parametrize("build", [make, parallel_env])
def test_unknown_override_lists_the_valid_ones(build):
    with pytest.raises(ValueError) as e:
        build("mpe-5", num_agent=3)
    assert "num_agent" in str(e.value) and all(name in str(e.value) for name in OVERRIDES)


@pytest.mark.parametrize("override", [{"num_agents": 0}, {"num_agents": 2.5}, {"world_size": -1.0},
                                      {"horizon": "long"}, {"team_after": 30}, {"num_agents": True},
                                      {"num_agents": 400, "world_size": 3.0}])
def test_bad_override_values(override):
    with pytest.raises(ValueError, match="expected"):
        make("mpe-20", **override)


def test_bad_render_mode():
    with pytest.raises(ValueError, match="render_mode"):
        parallel_env("mpe-5", render_mode="ansi")


@pytest.mark.skipif(torch.cuda.is_available(), reason="a CUDA device is visible: 'cuda' is a valid device here")
@pytest.mark.parametrize("name", ["mpe-5", "drone-5"])
def test_cuda_without_a_cuda_device_is_one_clear_error(name):
    with pytest.raises(ValueError, match="device 'cuda'.*expected 'cpu'"):
        make(name, device="cuda")


# ------------------------------------------------------------------ batched world actions
@pytest.fixture
def world():
    return make("mpe-5", num_envs=2, seed=0)


@pytest.mark.parametrize("actions, words", [
    (torch.zeros(2, 4, dtype=torch.long), "shape"),
    (torch.zeros(5, dtype=torch.long), "shape"),
    (torch.zeros(2, 5), "integer"),
    (np.zeros((2, 5)), "integer"),
    (torch.zeros(2, 5, dtype=torch.bool), "integer"),
    (torch.full((2, 5), 5), r"\[0, 5\)"),
    (torch.full((2, 5), -1), r"\[0, 5\)"),
    ([[0] * 5] * 2, "tensor"),
])
def test_bad_actions_for_the_batched_world(world, actions, words):
    with pytest.raises(ValueError, match=words):
        world.step(actions)


def test_numpy_int_actions_are_accepted(world):
    for dtype in (np.int64, np.int32, np.uint8):
        world.step(np.full((2, 5), 2, dtype=dtype))
    assert world.t.tolist() == [3, 3]


def test_step_after_the_horizon_asks_for_reset():
    w = make("mpe-5", horizon=2, seed=0)
    for _ in range(2):
        w.step(torch.zeros(1, 5, dtype=torch.long))
    with pytest.raises(ValueError, match="reset"):
        w.step(torch.zeros(1, 5, dtype=torch.long))


# ------------------------------------------------------------------ PettingZoo actions
@pytest.fixture
def env():
    e = parallel_env("mpe-5")
    e.reset(seed=0)
    return e


def all_agents(env, value=0):
    return {a: value for a in env.agents}


@pytest.mark.parametrize("change, words", [
    (lambda acts: acts.update(agent_9=0), "unknown agent"),
    (lambda acts: acts.update(bob=0), "unknown agent"),
    (lambda acts: acts.pop("agent_3"), "missing agent"),
    (lambda acts: acts.update(agent_0=5), r"\[0, 5\)"),
    (lambda acts: acts.update(agent_0=-1), r"\[0, 5\)"),
    (lambda acts: acts.update(agent_0=1.0), "integer"),
    (lambda acts: acts.update(agent_0=np.float32(1)), "integer"),
    (lambda acts: acts.update(agent_0="up"), "integer"),
    (lambda acts: acts.update(agent_0=True), "integer"),
    (lambda acts: acts.update(agent_0=[1, 2]), "integer"),
])
def test_bad_actions_for_the_pettingzoo_face(env, change, words):
    acts = all_agents(env)
    change(acts)
    with pytest.raises(ValueError, match=words) as e:
        env.step(acts)
    assert "agent_0" in str(e.value)  # names what was expected
    assert env.world.t.tolist() == [0]  # nothing happened


def test_actions_must_be_a_dict(env):
    with pytest.raises(ValueError, match="dict"):
        env.step([0, 0, 0, 0, 0])


def test_dropped_agent_may_not_act():
    e = parallel_env("mpe-5", team_after=2, change_step=1)
    e.reset(seed=0)
    gone = set(e.possible_agents)
    e.step(all_agents(e))
    gone -= set(e.agents)
    with pytest.raises(ValueError, match="unknown agent"):
        e.step({**all_agents(e), sorted(gone)[0]: 0})


# ------------------------------------------------------------------ reset options
@pytest.mark.parametrize("options, words", [
    ({"agent_pos": np.zeros((4, 2))}, "agent_pos.*shape"),
    ({"landmark_pos": np.zeros((5, 3))}, "landmark_pos.*shape"),
    ({"obstacle_pos": np.zeros((6, 2))}, "obstacle_pos.*shape"),
    ({"agent_vel": np.zeros(10)}, "agent_vel.*shape"),
    ({"agent_pos": np.full((5, 2), np.nan)}, "finite"),
    ({"agent_pos": np.array([[0, 0], [0, 0], [0.6, 0], [0.9, 0], [-0.6, 0]])}, "same point"),  # overlap is fine
    ({"agent_pos": np.array([[0, 0], [0.3, 0], [0.6, 0], [0.9, 0], [-0.6, 0]]),
      "obstacle_pos": np.array([[0.0, 0.0], [0, 0.6], [0, -0.6], [0.6, 0.6], [-0.6, -0.6]])}, "centre of an obstacle"),
    ({"obstacle_pos": np.zeros((5, 2))}, "obstacles overlap"),
    ({"keep": np.ones(5)}, "keep"),
])
@pytest.mark.parametrize("face", ["batched", "pettingzoo"])
def test_bad_reset_options(face, options, words):
    target = make("mpe-5", seed=0) if face == "batched" else parallel_env("mpe-5")
    with pytest.raises(ValueError, match=words):
        target.reset(options=options)


def test_unknown_reset_option_fails_in_the_batched_world():
    with pytest.raises(ValueError) as e:
        make("mpe-5", seed=0).reset(options={"agent_position": np.zeros((5, 2))})
    assert "agent_position" in str(e.value) and "agent_pos" in str(e.value)


@pytest.mark.parametrize("name", ["mpe-5", "drone-5"])
def test_a_near_miss_of_a_reset_option_fails_in_the_pettingzoo_face(name):
    n, d = (5, 2) if name == "mpe-5" else (5, 3)
    with pytest.raises(ValueError, match="'agent_position'.*did you mean 'agent_pos'"):
        parallel_env(name).reset(options={"agent_position": np.zeros((n, d))})


def test_an_unrelated_reset_option_only_warns_in_the_pettingzoo_face():
    # PettingZoo's parallel_api_test itself passes options={"options": 1}: warn, don't fail
    with pytest.warns(UserWarning, match="'options'.*agent_pos"):
        parallel_env("mpe-5").reset(options={"options": 1})


@pytest.mark.parametrize("name, option, value, words", [
    ("mpe-5", "agent_pos", 1e300, "agent_pos.*expected values in.*got 1e\\+300"),
    ("mpe-5", "landmark_pos", -50.0, "landmark_pos.*expected values in"),
    ("mpe-5", "agent_vel", 1e6, "agent_vel.*expected values in"),
    ("drone-5", "agent_pos", 1e200, "agent_pos.*expected values in"),
    ("drone-5", "agent_pos", -0.5, "agent_pos.*expected values in"),  # below the floor (z column)
    ("drone-5", "landmark_pos", 4.0, "landmark_pos.*expected values in"),  # above the ceiling
])
def test_a_start_outside_the_world_is_refused(name, option, value, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo would write MUJOCO_LOG.TXT here had the body been simulated
    w = make(name, seed=0)
    start = w.reset(seed=0)[option if option != "agent_vel" else "agent_pos"].clone()[0].numpy()
    given = start.astype(np.float64) if option != "agent_vel" else np.zeros(start.shape)
    given[0, -1 if name == "drone-5" else 0] = value
    with pytest.raises(ValueError, match=words):
        w.reset(options={option: given})
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["mpe-5", "drone-5"])
def test_reset_env_ids_as_a_bool_mask_resets_exactly_the_masked_worlds(name):
    w = make(name, num_envs=4, seed=0)
    before = w.reset(seed=0)["landmark_pos"].clone()
    after = w.reset(env_ids=torch.zeros(4, dtype=torch.bool))["landmark_pos"]  # nothing done: nothing reset
    assert torch.equal(after, before)
    after = w.reset(env_ids=[True, False, True, False])["landmark_pos"]
    changed = [not torch.equal(after[i], before[i]) for i in range(4)]
    assert changed == [True, False, True, False]


@pytest.mark.parametrize("env_ids, words", [([2.9], "integer indices or a bool mask"),
                                            (["a"], "integer indices or a bool mask"),
                                            ([True, False], r"bool mask must have shape \(4,\)"),
                                            ([4], r"indices in \[0, 4\)")])
def test_bad_env_ids_are_refused(env_ids, words):
    with pytest.raises(ValueError, match=words):
        make("mpe-5", num_envs=4, seed=0).reset(env_ids=env_ids)


@pytest.mark.parametrize("name", ["mpe-5", "drone-5"])
def test_a_uint8_env_ids_tensor_is_refused_not_read_as_indices(name):
    with pytest.raises(ValueError, match=r"torch.uint8 tensor could be a mask .* or indices"):
        make(name, num_envs=3, seed=0).reset(env_ids=torch.tensor([1, 0, 1], dtype=torch.uint8))


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True, 2**63, np.float64(2.0)])
@pytest.mark.parametrize("name", ["mpe-5", "drone-5"])
def test_a_seed_that_would_be_read_as_another_is_refused(name, seed, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"seed: expected an int from 0 to 2\*\*63 - 1"):
        make(name, seed=seed)
    with pytest.raises(ValueError, match=r"seed: expected an int from 0 to 2\*\*63 - 1"):
        make(name, seed=0).reset(seed=seed)
    with pytest.raises(ValueError, match=r"seed: expected an int from 0 to 2\*\*63 - 1"):
        parallel_env(name).reset(seed=seed)
    make(name, seed=np.int64(3)).reset(seed=2**63 - 1)  # numpy ints and the largest seed are fine


@pytest.mark.parametrize("name", ["mpe-5", "drone-5"])
def test_a_meta_device_or_more_worlds_than_memory_is_one_clear_error(name):
    with pytest.raises(ValueError, match="device 'meta': expected 'cpu' or 'cuda'"):
        make(name, device="meta")
    with pytest.raises(ValueError, match=r"num_envs=1000000000: .* GiB .*expected fewer worlds"):
        make(name, num_envs=10**9)


@pytest.mark.parametrize("options, words", [
    ("abc", "reset options: expected a dict"), ([1, 2], "reset options: expected a dict"),
    ({"agent_pos": "x"}, "reset option 'agent_pos': expected real numbers"),
    ({"agent_pos": object()}, "reset option 'agent_pos': expected real numbers, got dtype object"),
    ({"agent_pos": np.zeros((5, 2), dtype=complex)}, "expected real numbers, got dtype complex128"),
    ({"agent_pos": [[0, 0], [1]]}, "reset option 'agent_pos': expected an array of real numbers"),
])
@pytest.mark.parametrize("face", ["batched", "pettingzoo"])
def test_reset_options_of_the_wrong_type_are_one_clear_error(face, options, words):
    env = make("mpe-5", seed=0) if face == "batched" else parallel_env("mpe-5")
    with pytest.raises(ValueError, match=words):
        env.reset(seed=0, options=options)


@pytest.mark.parametrize("action, words", [
    (np.array([object()] * 4, dtype=object), "got dtype object"),
    (np.zeros(4, dtype=complex), "got dtype complex128"),
    (torch.zeros(4, dtype=torch.complex64), "got dtype complex64"),
    ("abcd", "got dtype <U4"),
])
def test_object_or_complex_actions_on_the_drone_face_are_one_clear_error(action, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env = parallel_env("drone-5")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=rf"step: action of 'drone_0': expected real numbers.*{words}"):
        env.step({a: action for a in env.agents})


# ------------------------------------------------------------------ bench command
def test_missing_or_unknown_bench_target_is_a_clear_error(monkeypatch, capsys):
    with pytest.raises(ValueError, match="expected one of"):
        load_target("gpu")
    import importlib
    real = importlib.import_module

    def fake_import(name, *args):
        if name == "masp_lite.bench.planners":
            err = ModuleNotFoundError(f"No module named {name!r}")
            err.name = name
            raise err
        return real(name, *args)

    monkeypatch.setattr(importlib, "import_module", fake_import)
    with pytest.raises(ValueError, match="not available"):
        load_target("planners")
    assert main(["bench", "planners"]) == 2
    assert "not available" in capsys.readouterr().err


def test_bench_env_rejects_bad_options(capsys):
    assert main(["bench", "env", "--seconds", "0"]) == 2
    assert "--seconds" in capsys.readouterr().err


def test_bench_env_smoke(tmp_path, capsys):
    """Output format only: tiny budgets, no timing assertions."""
    out = tmp_path / "env.json"
    assert main(["bench", "env", "--seconds", "0.1", "--rounds", "2", "--threads", "1", "--worlds", "1", "4",
                 "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "resets included" in text and text.count("agent-steps/s") >= 2
    result = json.loads(out.read_text())
    assert set(result["masp_agent_steps_per_s"]) == {"1", "4"}
    assert all(v > 0 for v in result["masp_agent_steps_per_s"].values())
    if result["mpe2_agent_steps_per_s"] is not None:
        assert "ratio" in text and result["ratio"]["worlds"] == 4


# ------------------------------------------------------------------ checkpoint files
@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A real run folder (state.pt, weights.pt) of a one-iteration training run on mpe-5."""
    from masp_lite.config import TrainConfig
    from masp_lite.training import train
    out = tmp_path_factory.mktemp("run")
    cfg = TrainConfig.from_flat(dict(num_envs=2, updates=1, checkpoint_every=1, eval_every=0, eval_episodes=1,
                                     ppo_epochs=1, num_minibatches=1, width=8))
    train("mpe-5", cfg, out, progress=False)
    return out


def evaluate_error(capsys, checkpoint, scenario="mpe-5"):
    """The error line of ``evaluate --method masp --checkpoint ...`` (exit status 2, no traceback)."""
    assert main(["evaluate", "--method", "masp", "--scenario", scenario, "--episodes", "1", "--seeds", "0",
                 "--checkpoint", str(checkpoint)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: checkpoint ") and "Traceback" not in err
    assert "scenario overrides are" not in err  # the overrides list belongs to misspelt keys, not to files
    return err


def test_a_training_state_is_named_and_the_weights_file_suggested(run_dir, capsys):
    from masp_lite.weights import load_weights
    err = evaluate_error(capsys, run_dir / "state.pt")
    assert "this is a training state" in err and "pass the run's weights.pt" in err
    with pytest.raises(ValueError, match="training state"):
        load_weights(run_dir / "state.pt")
    load_weights(run_dir / "weights.pt", scenario="mpe-5")  # the file it points to loads


def test_a_text_or_empty_file_is_not_a_torch_file(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("hello, not weights\n")
    assert "not a torch file" in evaluate_error(capsys, tmp_path / "notes.txt")
    (tmp_path / "empty.pt").write_bytes(b"")
    assert "the file is empty" in evaluate_error(capsys, tmp_path / "empty.pt")


def test_torch_reason_is_whole_words_of_its_first_sentence(run_dir, tmp_path, capsys):
    import fractions
    (tmp_path / "cut.pt").write_bytes((run_dir / "weights.pt").read_bytes()[:1000])
    torch.save({"x": fractions.Fraction(1, 3)}, tmp_path / "pickled.pt")   # an object weights_only refuses
    for path, kind in ((tmp_path / "cut.pt", "RuntimeError"), (tmp_path / "pickled.pt", "UnpicklingError")):
        err = evaluate_error(capsys, path)
        reason = err.split(f"could not read it ({kind}: ", 1)[1].rstrip().removesuffix(")")
        try:
            torch.load(path, weights_only=True)
        except Exception as e:  # noqa: BLE001  (the message torch gives, to compare with)
            full = " ".join(str(e).split())
        words = reason.removesuffix(" ...").split()
        assert words and " ".join(words) in full
        after = full.split(" ".join(words), 1)[1]
        assert after == "" or after[0] in " .", f"cut mid-word: {reason!r}"
        assert "\x1b" not in reason and len(reason) <= 200
    assert "fractions.Fraction" in err and "do those steps only" not in err  # the object, not the advice


def _weights_variant(run_dir, path, change):
    """A copy of the run's weights record with ``change(record)`` applied, saved at ``path``."""
    rec = torch.load(run_dir / "weights.pt", weights_only=True)
    change(rec)
    torch.save(rec, path)
    return path


@pytest.mark.parametrize("change, words", [
    (lambda r: r.pop("arch"), "field 'arch' is missing; expected a dict of NetConfig settings"),
    (lambda r: r.update(arch=[8, 3]), "field 'arch' is a list; expected a dict"),
    (lambda r: r.update(scenario=5), "field 'scenario' is a int; expected a preset name"),
    (lambda r: r.pop("state_dict"), "field 'state_dict' is missing"),
    (lambda r: r.update(state_dict=[1, 2]), "field 'state_dict' is a list; expected a dict of tensors"),
    (lambda r: r["state_dict"].update(extra=3), "entry 'extra' is a int; expected a tensor"),
    (lambda r: r.update(world="mpe2"), "field 'world' is a str; expected a dict"),
])
def test_a_weights_file_with_a_missing_or_mistyped_field_names_the_field(run_dir, tmp_path, capsys, change, words):
    err = evaluate_error(capsys, _weights_variant(run_dir, tmp_path / "w.pt", change))
    assert words in err


@pytest.mark.parametrize("dtype", [torch.complex64, torch.int64, torch.bool])
def test_weights_that_are_not_real_floating_point_are_refused_not_cast(run_dir, tmp_path, capsys, dtype):
    def change(rec):
        sd = rec["state_dict"]
        for k in sd:
            sd[k] = sd[k].to(dtype)
        if dtype.is_complex:
            next(iter(sd.values())).view(-1)[0] = complex("nan")  # a NaN the real-only finite check missed
    err = evaluate_error(capsys, _weights_variant(run_dir, tmp_path / "w.pt", change))
    assert f"is {dtype}; expected floating-point weights" in err


def test_weights_of_another_float_dtype_are_refused_naming_the_parameter(run_dir, tmp_path, capsys):
    path = _weights_variant(run_dir, tmp_path / "w.pt",
                            lambda r: r["state_dict"].update({k: v.double() for k, v in r["state_dict"].items()}))
    err = evaluate_error(capsys, path)
    assert "is torch.float64, the networks' is torch.float32" in err


def test_sizes_a_weights_file_declares_are_checked_before_anything_is_allocated(run_dir, tmp_path, capsys):
    import zipfile
    name = next(iter(torch.load(run_dir / "weights.pt", weights_only=True)["state_dict"]))
    # one stored number seen as 10**6 of them (stride 0): refused before anything reads it
    path = _weights_variant(run_dir, tmp_path / "stride0.pt",
                            lambda r: r["state_dict"].update({name: torch.zeros(1).expand(10**6)}))
    assert "strides (0,), more elements than its stored bytes" in evaluate_error(capsys, path)
    for key, value in (("width", 2000), ("gcn_layers", 10**6), ("group_size", 10**9)):
        path = _weights_variant(run_dir, tmp_path / f"{key}.pt", lambda r: r["arch"].update({key: value}))
        assert f"arch field {key!r} is {value}; expected at most" in evaluate_error(capsys, path)
    # the same archive, its entries deflated (a deflate bomb unpacks to far more than the file holds)
    bomb = tmp_path / "deflated.pt"
    with zipfile.ZipFile(run_dir / "weights.pt") as src, zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            dst.writestr(info.filename, src.read(info))
    assert "is compressed" in evaluate_error(capsys, bomb) and "expected torch.save's uncompressed archive" in \
        evaluate_error(capsys, bomb)
    legacy = tmp_path / "legacy.pt"
    torch.save(torch.load(run_dir / "weights.pt", weights_only=True), legacy, _use_new_zipfile_serialization=False)
    assert "legacy (pre-1.6) format" in evaluate_error(capsys, legacy)


def test_a_weights_file_that_is_a_pipe_or_a_device_is_refused_at_once(tmp_path, capsys):
    import os
    os.mkfifo(tmp_path / "w.pt")
    assert "expected an existing weights file" in evaluate_error(capsys, tmp_path / "w.pt")  # no hang
    from masp_lite.weights import weights_bytes
    with pytest.raises(ValueError, match="not a regular file"):
        weights_bytes(tmp_path / "w.pt")  # read directly, it would wait for a writer forever


def test_a_replaced_weights_file_is_read_again_even_with_the_same_size_and_time(run_dir, tmp_path):
    import io
    import os

    from masp_lite.weights import read_weights
    path = tmp_path / "w.pt"
    path.write_bytes((run_dir / "weights.pt").read_bytes())
    st = path.stat()
    name = next(iter(read_weights(path)["state_dict"]))
    rec = torch.load(path, weights_only=True)
    rec["state_dict"][name].fill_(0.25)
    buf = io.BytesIO()
    torch.save(rec, buf)  # in memory, as save_weights does: the archive's name stays "archive"
    (tmp_path / "other.pt").write_bytes(buf.getvalue())
    assert (tmp_path / "other.pt").stat().st_size == st.st_size
    os.replace(tmp_path / "other.pt", path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))  # as cp -p leaves it: same size, same mtime
    assert bool((read_weights(path)["state_dict"][name] == 0.25).all())


def test_wrong_scenario_hint_has_the_command_line_and_python_spellings(run_dir, capsys):
    from masp_lite.weights import load_weights
    err = evaluate_error(capsys, run_dir / "weights.pt", scenario="mpe-20")
    assert "was trained for 'mpe-5'" in err and "--set any_scenario=true" in err
    with pytest.raises(ValueError, match="any_scenario=True in Python"):
        load_weights(run_dir / "weights.pt", scenario="mpe-20")
    assert main(["evaluate", "--method", "masp", "--scenario", "mpe-20", "--episodes", "1", "--seeds", "0",
                 "--set", "horizon=2", "--checkpoint", str(run_dir / "weights.pt"), "--set", "any_scenario=true"]) == 0


def test_bench_train_smoke_and_bad_options(tmp_path, capsys):
    """Output format only (tiny budget, no timing assertions); bad options are one clear error."""
    out = tmp_path / "train.json"
    assert main(["bench", "train", "--scenarios", "mpe-5", "--worlds", "2", "--threads", "1", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "masp (plain autograd)" in text and "x plain" in text
    rows = json.loads(out.read_text())["env_steps_per_s"]["mpe-5"]
    from masp_lite.bench.train import METHODS
    assert set(rows) == {*METHODS, "masp (plain autograd)"} and all(v > 0 for v in rows.values())
    assert {"h-mappo", "mappo", "darl1n", "htamp", "mage-x"} <= set(METHODS) and "x masp" in text
    assert main(["bench", "train", "--methods", "nope"]) == 2
    assert "unknown ['nope']" in capsys.readouterr().err
    assert main(["bench", "train", "--scenarios", "nope-5"]) == 2
    assert "unknown scenario" in capsys.readouterr().err.lower()


def test_bench_train_has_a_drone_row(tmp_path):
    out = tmp_path / "train.json"
    args = ["--scenarios", "drone-5", "--worlds", "2", "--threads", "1", "--json", str(out)]
    assert main(["bench", "train", *args]) == 0
    rows = json.loads(out.read_text())["env_steps_per_s"]["drone-5"]
    baselines = {"h-mappo", "htamp", "mage-x", "mappo", "darl1n"}
    assert set(rows) == {"masp", "masp-velocity", "masp (plain autograd)", *baselines}
    assert all(v > 0 for v in rows.values())
    import argparse

    from masp_lite.bench.train import add_arguments
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert {"drone-5", "drone-20"} <= set(parser.parse_args([]).scenarios)  # both drone teams by default
