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
