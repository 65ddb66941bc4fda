"""Nothing lost, nothing silently wrong: training that cannot go on stops before it writes anything."""
import pytest
import torch

from masp_lite.__main__ import main
from masp_lite.config import TrainConfig
from masp_lite.training import train

TINY = dict(num_envs=3, updates=2, checkpoint_every=1, eval_every=0, eval_episodes=2, ppo_epochs=1,
            num_minibatches=2, width=8)


def _cfg(**flat) -> TrainConfig:
    return TrainConfig.from_flat({**TINY, **flat})


@pytest.mark.parametrize("setting", ["lr=inf", "lr=nan", "lr=5", "clip=inf", "clip=3", "gamma=nan",
                                     "max_grad_norm=inf", "huber_delta=nan", "entropy_coef=inf"])
def test_settings_that_cannot_train_are_refused_up_front(tmp_path, capsys, setting):
    out = tmp_path / "run"
    assert main(["train", "--scenario", "mpe-5", "--out", str(out), "--quiet", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert f"{setting.split('=')[0]}: expected a finite number" in err and "Traceback" not in err
    assert not out.exists()


def _state(out):
    return torch.load(out / "state.pt", weights_only=True)


def test_a_non_finite_update_stops_the_run_before_anything_is_written(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    state = _state(out)
    # one corrupted optimizer value: finite, but Adam's square root of it is not
    first = next(iter(state["cae_opt"]["state"].values()))
    first["exp_avg_sq"].view(-1)[0] = -1.0
    torch.save(state, out / "state.pt")
    before = {f: (out / f).read_bytes() for f in ("state.pt", "weights.pt", "progress.csv", "manifest.json")}
    stopped = r"training stopped at iteration 2: the .* is nan; nothing was written, .*iteration 1\) is intact"
    with pytest.raises(ValueError, match=stopped):
        train("mpe-5", _cfg(), out, progress=False, resume=True)
    assert {f: (out / f).read_bytes() for f in before} == before


def test_a_state_with_non_finite_values_is_refused_naming_file_and_value(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    state = _state(out)
    name = next(iter(state["nets"]))
    state["nets"][name].view(-1)[0] = float("nan")
    torch.save(state, out / "state.pt")
    with pytest.raises(ValueError, match=rf"state.pt: expected a training state with finite values; value nets.{name}"):
        train("mpe-5", _cfg(), out, progress=False, resume=True)


def test_a_second_run_into_the_same_folder_is_refused_and_a_stale_lock_taken_over(tmp_path):
    import subprocess
    import sys
    out = tmp_path / "run"
    out.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / ".lock").write_text(f"{holder.pid}\n")
        with pytest.raises(ValueError, match=rf"being trained by process {holder.pid}"):
            train("mpe-5", _cfg(updates=1), out, progress=False)
        assert not (out / "state.pt").exists()
    finally:
        holder.kill()
        holder.wait()
    train("mpe-5", _cfg(updates=1), out, progress=False)  # its holder is gone: a stale lock, taken over
    assert (out / "manifest.json").exists() and not (out / ".lock").exists()  # released at the end
    with pytest.raises(ValueError, match="stopped"):  # released on an error too
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True,
              on_iteration=lambda t: (_ for _ in ()).throw(ValueError("stopped")))
    assert not (out / ".lock").exists()


def test_an_out_folder_that_cannot_be_written_is_one_clear_error(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert main(["train", "--scenario", "mpe-5", "--out", str(tmp_path / "file" / "run"), "--quiet",
                 "--set", "updates=1"]) == 2
    err = capsys.readouterr().err
    assert "expected a folder that can be written" in err and "Traceback" not in err


def test_resume_keeps_the_history_honest(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=2), out, progress=False)
    with pytest.raises(ValueError, match=r"updates=1: expected at least the 2 iterations"):
        train("mpe-5", _cfg(updates=1), out, progress=False, resume=True)
    m = train("mpe-5", _cfg(updates=2), out, progress=False, resume=True)  # ends the run where it is
    assert m["iterations"] == m["config"]["updates"] == 2
    csv = (out / "progress.csv").read_bytes()
    (out / "progress.csv").write_bytes(b"\x00\xff garbage")
    with pytest.raises(ValueError, match="progress.csv: expected the history of the 2 iterations"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    (out / "progress.csv").unlink()
    with pytest.raises(ValueError, match="the file is missing"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    (out / "progress.csv").write_bytes(csv)
    assert train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)["iterations"] == 3


def test_a_run_folders_weights_are_checked_against_the_hash_its_manifest_recorded(tmp_path):
    from masp_lite.weights import load_weights
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    nets, _ = load_weights(out / "weights.pt", any_scenario=True)     # whole: loads
    raw = torch.load(out / "weights.pt", weights_only=True)
    name = next(iter(raw["state_dict"]))
    raw["state_dict"][name].zero_()                                       # a zeroed tensor
    torch.save(raw, out / "weights.pt")
    with pytest.raises(ValueError, match="differ from the SHA-256 its run recorded"):
        load_weights(out / "weights.pt", any_scenario=True)
    raw["state_dict"][name].fill_(float("nan"))
    torch.save(raw, tmp_path / "loose.pt")                                # not in a run folder: no hash to check
    with pytest.raises(ValueError, match=rf"parameter '{name}' holds NaN or inf"):
        load_weights(tmp_path / "loose.pt", any_scenario=True)


def test_resuming_a_finished_run_drops_its_stale_manifest_until_it_finishes_again(tmp_path):
    from masp_lite.weights import load_weights
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    with pytest.raises(ValueError, match="stopped"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True,
              on_iteration=lambda t: (_ for _ in ()).throw(ValueError("stopped")))
    assert not (out / "manifest.json").exists()
    load_weights(out / "weights.pt", any_scenario=True)                   # the newer weights load
    train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    load_weights(out / "weights.pt", any_scenario=True)


def test_init_and_resume_mismatches_name_both_sides(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    with pytest.raises(ValueError, match=r"differs in \['lr'\] \(lr: run 0.0007, now 0.001\)"):
        train("mpe-5", _cfg(updates=2, lr=1e-3), out, progress=False, resume=True)
    with pytest.raises(ValueError, match=r"width: --init 8, configured 16"):
        train("mpe-5", _cfg(updates=1, width=16), tmp_path / "wide", progress=False, init=out / "weights.pt")
    mlp = tmp_path / "mlp"
    train("mpe-5", _cfg(updates=1, goal_matcher="mlp", executor="mlp"), mlp, progress=False)
    with pytest.raises(ValueError, match=r"team_size: --init 5, configured 20.*one team size"):
        train("mpe-20", _cfg(updates=1, goal_matcher="mlp", executor="mlp"), tmp_path / "mlp20", progress=False,
              init=mlp / "weights.pt")
    # weights of another world: refused unless this run names its world (a deliberate move, as the shipped
    # mpe-20 chain's last stage made from mpe2's world into the paper's)
    mpe2 = tmp_path / "mpe2"
    train("mpe-5", _cfg(updates=1), mpe2, progress=False, overrides={"integration": "mpe2", "landmark_spawn": "whole"})
    with pytest.raises(ValueError, match=r"trained in the world integration=mpe2, landmark_spawn=whole, this run's "
                                         r"is integration=velocity_first.*--set integration=velocity_first"):
        train("mpe-20", _cfg(updates=1), tmp_path / "moved", progress=False, init=mpe2 / "weights.pt")
    train("mpe-20", _cfg(updates=1), tmp_path / "moved", progress=False, init=mpe2 / "weights.pt",
          overrides={"integration": "velocity_first", "landmark_spawn": "central"})
