"""``reproduce --train``: the plan built from the recipes, run in turn, resumed, and on Ray."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from masp_lite.config import TrainConfig
from masp_lite.files import sha256
from masp_lite.recipes import RECIPES
from masp_lite.reproduction import plan
from masp_lite.reproduction.plan import Run, Stage, describe, load_plan, read_plan, run_plan, save_plan

ROOT = Path(__file__).resolve().parents[1]


def test_the_plan_is_the_recipes_and_every_kept_history_is_one_of_its_runs():
    runs, skipped = read_plan(ROOT)
    names = {r.name for r in runs}
    kept = {str(p.relative_to(ROOT / "results/training"))[: -len(".manifest.json")]
            for p in (ROOT / "results/training").rglob("*.manifest.json")}
    assert {n for n, _ in skipped} == kept - names
    assert all("no recipe makes it" in why for _, why in skipped)
    expected = {f"{s.keep}-seed{k}" for r in RECIPES.values() for s in r.stages if s.keep for k in (0, 1, 2)}
    assert names == expected
    by_name = {r.name: r for r in runs}
    faithful = by_name["faithful/mpe-20-seed0"]
    assert len(faithful.stages) == 1 and faithful.stages[0].config["updates"] == 150
    assert faithful.wall_clock_s is not None  # its kept history is the recipe's: timed
    assert "results/faithful/masp-seed0_mpe-50.json" in faithful.records  # zero-shot records follow the weights
    drone = by_name["drone-20-seed0"]
    assert drone.shipped and [s.init for s in drone.stages] == [None, 0, 1]
    assert {"results/omnidrones/masp_drone-20.json", "results/omnidrones-varying/masp_drone-20to10.json",
            "results/omnidrones-split/masp-decode-hungarian_drone-20.json",  # the default weights, with an option
            "results/omnidrones-split/h-orca-goals-masp_drone-20.json"} <= set(drone.records)  # as a goal source
    assert not any("velocity" in r or "-seed" in r for r in drone.records)
    velocity = by_name["masp-velocity/drone-20-seed0"]  # a method's packaged seed 0 follows its run too
    assert velocity.packaged == "masp_lite/weights/methods/masp-velocity/drone-20.pt" and not velocity.shipped
    assert {"results/omnidrones/masp-velocity-train-seed0_drone-20.json",
            "results/omnidrones-split/h-orca-goals-masp-velocity_drone-20.json"} <= set(velocity.records)
    assert "results/omnidrones-split/h-orca-goals-masp-velocity_drone-20.json" not in \
        by_name["masp-velocity/drone-5-seed0"].records
    assert by_name["masp-velocity/drone-20-seed1"].packaged is None
    # drone-20 starts from drone-5's first stage: one task, the shared stage trained once
    tasks = plan._tasks([by_name["drone-5-seed0"], drone, faithful])
    assert sorted(len(t) for t in tasks) == [1, 2]
    # the faithful recipe and MASP's budget run on mpe-20 are the same stage: trained once
    assert plan._key(faithful, 0) == plan._key(by_name["masp-budget/mpe-20-seed0"], 0)
    text = describe(runs, skipped, workers=2)
    assert "drone-20-seed0" in text and "h of training in turn" in text


def _tiny_run(seed: int, records=(), packaged=None) -> Run:
    config = {**TrainConfig().flat(), "goal_matcher": "hungarian", "executor": "nearest", "num_envs": 2,
              "updates": 6, "eval_every": 0, "eval_episodes": 2, "checkpoint_every": 2, "ppo_epochs": 1,
              "gm_ppo_epochs": 1}
    return Run(f"h-mappo/mpe-5-seed{seed}", (Stage("mpe-5", "h-mappo", seed, config, {}, None, 1, 540, 1.0),),
               False, "a tiny test run", tuple(records), packaged)


def _record(root: Path, seed: int) -> str:
    rel = f"results/rl/h-mappo-seed{seed}_mpe-5.json"
    (root / rel).parent.mkdir(parents=True, exist_ok=True)
    weights = f"results/training/h-mappo/mpe-5-seed{seed}.pt"
    (root / rel).write_text(json.dumps({"method": "h-mappo", "scenario": "mpe-5", "seeds": [0], "episodes_per_seed": 2,
                                        "num_envs": 2, "sr": {"mean": 0.0, "std": 0.0},
                                        "method_options": {"checkpoint": weights}}))
    return rel


def _weights(root: Path, name: str) -> dict:
    return torch.load(root / "results/training" / f"{name}.pt", weights_only=True)["state_dict"]


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.fixture(scope="module")
def in_turn(tmp_path_factory):
    """A two-run plan run in turn in a fresh root."""
    root = tmp_path_factory.mktemp("in-turn")
    package = root / "masp_lite/weights/methods"  # seed 0 is packaged: an old file the run replaces
    (package / "h-mappo").mkdir(parents=True)
    (package / "h-mappo/mpe-5.pt").write_bytes(b"old weights")
    (package / "manifest.json").write_text(json.dumps({"h-mappo": {"mpe-5": {
        "copy_of": "results/training/h-mappo/mpe-5-seed0.pt", "file": "h-mappo/mpe-5.pt", "sha256": "0" * 64}}}))
    default = "results/rl/h-mappo_mpe-5.json"  # a record of the packaged default: no checkpoint option
    (root / "results/rl").mkdir(parents=True)
    (root / default).write_text(json.dumps({"method": "h-mappo", "scenario": "mpe-5", "seeds": [0],
                                            "episodes_per_seed": 2, "num_envs": 2, "sr": {"mean": 0.0, "std": 0.0}}))
    runs = [_tiny_run(0, [_record(root, 0), default], "masp_lite/weights/methods/h-mappo/mpe-5.pt"), _tiny_run(1)]
    said = []
    assert run_plan(runs, root, use_ray=False, say=said.append) == ["h-mappo/mpe-5-seed0", "h-mappo/mpe-5-seed1"]
    return root, runs, said


def test_a_plan_in_turn_ships_weights_histories_and_remakes_the_records(in_turn, monkeypatch):
    root, runs, said = in_turn
    history = json.loads((root / "results/training/h-mappo/mpe-5-seed0.manifest.json").read_text())
    assert history["note"] == "a tiny test run" and history["stages"][0]["training"]["iterations"] == 6
    rec = json.loads((root / "results/rl/h-mappo-seed0_mpe-5.json").read_text())
    assert rec["method_options"] == {"checkpoint": "results/training/h-mappo/mpe-5-seed0.pt"}  # as named before
    assert rec["checkpoint_sha256"] == sha256(root / "results/training/h-mappo/mpe-5-seed0.pt")
    assert rec["episodes_per_seed"] == 2 and "steps" in rec and "cr" in rec
    assert not _same(_weights(root, "h-mappo/mpe-5-seed0"), _weights(root, "h-mappo/mpe-5-seed1"))
    packaged = root / "masp_lite/weights/methods/h-mappo/mpe-5.pt"  # the package's copy follows seed 0
    assert packaged.read_bytes() == (root / "results/training/h-mappo/mpe-5-seed0.pt").read_bytes()
    manifest = json.loads((root / plan.METHODS_MANIFEST).read_text())
    assert manifest["h-mappo"]["mpe-5"]["sha256"] == sha256(packaged)
    default = json.loads((root / "results/rl/h-mappo_mpe-5.json").read_text())
    assert "steps" in default and "method_options" not in default  # re-made, still naming the default weights
    assert any("started" in s for s in said)
    # run again: everything is done, nothing trains
    monkeypatch.setattr(plan, "train", lambda *a, **k: pytest.fail("a finished run trained again"))
    assert run_plan(runs, root, use_ray=False, say=lambda m: None) == [r.name for r in runs]


def test_a_killed_plan_resumes_to_the_same_weights(in_turn, tmp_path):
    root, runs, _ = in_turn
    plan_file = tmp_path / "plan.json"
    slow = Run(runs[0].name, (Stage(**{**runs[0].stages[0].__dict__,
                                       "config": {**runs[0].stages[0].config, "updates": 6}}),), False,
               runs[0].note, ())
    save_plan([slow], plan_file)
    assert load_plan(plan_file) == [slow]
    other = tmp_path / "root"
    cmd = [sys.executable, "-m", "masp_lite", "reproduce", "--train", "--plan", str(plan_file), "--root", str(other),
           "--in-turn"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, cwd=ROOT)
    state = None
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        states = list((other / plan.STAGES_DIR).glob("*/state.pt"))
        if states:
            state = states[0]
            break
        time.sleep(0.05)
    assert state is not None, proc.communicate()[0].decode()[-2000:]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (other / "results/training/h-mappo/mpe-5-seed0.pt").exists()   # stopped before the end
    done_before = torch.load(state, weights_only=False)["iterations"]
    assert 0 < done_before < 6
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "resumed" in out.stdout
    assert _same(_weights(other, runs[0].name), _weights(root, runs[0].name))


def test_a_plan_on_a_local_ray_gives_the_weights_of_running_it_in_turn(in_turn, tmp_path):
    pytest.importorskip("ray")
    root, runs, _ = in_turn
    other = tmp_path / "ray-root"
    runs = [Run(r.name, r.stages, r.shipped, r.note, ()) for r in runs]  # the weights only
    assert sorted(run_plan(runs, other, use_ray=True, say=lambda m: None)) == sorted(r.name for r in runs)
    for r in runs:
        assert _same(_weights(other, r.name), _weights(root, r.name))


def test_bad_plans_and_options_are_one_clear_error(tmp_path, capsys):
    from masp_lite.cli import main
    bad = tmp_path / "plan.json"
    bad.write_text('[{"name": "x"}]')
    with pytest.raises(ValueError, match="expected a JSON list of runs"):
        load_plan(bad)
    assert main(["reproduce", "--dry-run"]) != 0
    assert "go with --train" in capsys.readouterr().err
    assert main(["reproduce", "--train", "--in-turn", "--address", "ray://head:10001"]) != 0
    assert "expected one of them" in capsys.readouterr().err
    assert main(["reproduce", "--train", "--dry-run", "--only", "no-such-run"]) != 0
    assert "no run of the plan matches" in capsys.readouterr().err
    assert main(["reproduce", "--train", "--dry-run", "--only", "mappo/mpe-5"]) == 0
    out = capsys.readouterr().out
    assert "mappo/mpe-5-seed0" in out and "h-mappo/mpe-5-seed0" in out and "faithful" not in out.split("\n")[1]


@pytest.mark.parametrize("change, words", [
    (lambda r: r.update(name="../../escaped"), "run name '../../escaped': expected a relative path inside the root"),
    (lambda r: r.update(name="/tmp/escaped"), "run name '/tmp/escaped': expected a relative path"),
    (lambda r: r.update(records=["/tmp/x.json"]), "record '/tmp/x.json': expected a relative path"),
    (lambda r: r.update(records=["results/../masp_lite/weights/manifest.json"]), "without '..'"),
    (lambda r: r.update(records=["masp_lite/weights/manifest.json"]), "expected a results/....json path"),
    (lambda r: r["stages"][0].update(init=0), "init 0; expected an earlier stage's index"),
])
def test_a_plan_writes_only_inside_its_root(tmp_path, change, words):
    path = tmp_path / "plan.json"
    save_plan([_tiny_run(0)], path)
    data = json.loads(path.read_text())
    change(data[0])
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="expected a JSON list of runs") as e:
        load_plan(path)
    assert words in str(e.value)
    stages = tuple(Stage(**s) for s in data[0]["stages"])
    run = Run(**{**data[0], "stages": stages, "records": tuple(data[0]["records"])})
    with pytest.raises(ValueError, match="expected"):  # a plan built in Python is checked the same way
        run_plan([run], tmp_path / "root", use_ray=False)
    assert not (tmp_path / "root").exists() and sorted(p.name for p in tmp_path.iterdir()) == ["plan.json"]


def test_a_plan_that_is_a_pipe_or_nested_too_deep_is_one_clear_error(tmp_path):
    os.mkfifo(tmp_path / "plan.json")
    with pytest.raises(ValueError, match="not a regular file"):
        load_plan(tmp_path / "plan.json")  # at once, no writer awaited
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match="expected a JSON list of runs"):
        load_plan(tmp_path / "deep.json")


def test_malformed_kept_histories_are_named_and_their_runs_planned_untimed(tmp_path):
    base = tmp_path / "results" / "training" / "mappo"
    base.mkdir(parents=True)
    for name, text in {"mpe-5-seed0": '{"file": "a-seed0.pt"}', "mpe-20-seed0": '{"stages": 5}',
                       "mpe-50-seed0": '{"stages": [{"scenario": "mpe-50"}]}', "x-seed0": "{}"}.items():
        (base / f"{name}.manifest.json").write_text(text)
    runs, skipped = read_plan(tmp_path)
    why = dict(skipped)
    assert "malformed" in why["mappo/mpe-5-seed0"] and "malformed" in why["mappo/mpe-20-seed0"]
    assert why["mappo/x-seed0"].startswith("no recipe makes it")
    by_name = {r.name: r for r in runs}
    assert all(by_name[f"mappo/{p}-seed0"].wall_clock_s is None for p in ("mpe-5", "mpe-20", "mpe-50"))
    d = base.parent / "darl1n"
    d.mkdir()
    (d / "mpe-5-seed0.manifest.json").write_text("{not json")
    with pytest.raises(ValueError, match=r"mpe-5-seed0.manifest.json: expected a JSON"):  # names the file
        read_plan(tmp_path)
