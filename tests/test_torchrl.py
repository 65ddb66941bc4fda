"""The TorchRL face: TorchRL's own spec check, rollouts and a collector, and agreement with the
native world, the PettingZoo face and the library's metrics, exactly where the numbers allow."""
import weakref

import numpy as np
import pytest
import torch

pytest.importorskip("torchrl")

from tensordict import TensorDict  # noqa: E402
from torchrl.collectors import Collector  # noqa: E402  (0.14 name of SyncDataCollector)
from torchrl.envs.utils import check_env_specs  # noqa: E402

from masp_lite.envs import ParticleWorld, parallel_env  # noqa: E402
from masp_lite.envs.torchrl import METRICS, ParticleTorchRLEnv, finished_episodes  # noqa: E402
from masp_lite.evaluation.metrics import EpisodeLog, collision_rate, reached_target, steps, success_rate  # noqa: E402


def _actions(seed, T, B, N):
    return torch.randint(0, 5, (T, B, N), generator=torch.Generator().manual_seed(seed))


@pytest.mark.parametrize("scenario, overrides", [
    ("mpe-5", {}),
    ("mpe-20", {}),
    # the team shrinks after step 1 and the episode ends at step 2: the 3-step check crosses both
    ("mpe-20to10", {"change_step": 1, "horizon": 2}),
])
def test_check_env_specs(scenario, overrides):
    env = ParticleTorchRLEnv(scenario, num_envs=3, seed=0, **overrides)
    check_env_specs(env, break_when_any_done="both")
    N = env.num_agents
    assert env.full_observation_spec["agents", "observation"].shape == (3, N, 7 * N - 1 + 2 * env.world.num_obstacles)
    assert env.full_action_spec["agents", "action"].shape == (3, N)
    assert env.full_reward_spec["agents", "reward"].shape == (3, N, 1)
    assert set(env.done_keys) == {"done", "terminated", "truncated"}


def test_rollout_auto_resets_and_reports_finished_episodes():
    env = ParticleTorchRLEnv("mpe-5", num_envs=4, seed=1, horizon=6)
    td = env.rollout(13, break_when_any_done=False)
    assert td.batch_size == (4, 13)
    done = td["next", "done"].squeeze(-1)
    assert done[:, [5, 11]].all() and done.sum() == 8  # two finished episodes per world
    assert not td["next", "terminated"].any() and torch.equal(td["next", "truncated"], td["next", "done"])
    assert (td["episode", "collision_rate"][:, 6] == 0).all()  # the step after a reset starts afresh
    metrics = finished_episodes(td)
    assert set(metrics) == set(METRICS) and all(len(v) == 8 for v in metrics.values())
    assert ((metrics["success_rate"] >= 0) & (metrics["success_rate"] <= 1)).all()
    with pytest.raises(ValueError, match="'next', 'done'"):
        finished_episodes(TensorDict({}, batch_size=[2]))


def test_collector_with_a_random_policy():
    env = ParticleTorchRLEnv("mpe-5", num_envs=4, seed=0)
    collector = Collector(env, policy=None, frames_per_batch=4 * 10, total_frames=4 * 30)  # random policy
    batches = list(collector)
    collector.shutdown()
    assert len(batches) == 3
    for batch in batches:
        assert batch["agents", "action"].shape[-1] == 5 and batch.numel() == 40
        assert ((batch["agents", "action"] >= 0) & (batch["agents", "action"] < 5)).all()
        assert batch["next", "agents", "reward"].shape[-2:] == (5, 1)
    assert sum(int(b["next", "done"].sum()) for b in batches) == 4  # horizon 18: one episode per world by 30


def _native_log(world, actions):
    """The native world's trajectory over ``actions`` (T, B, N) and the EpisodeLog of it."""
    cov, rea, alive, col, states = [world.covered], [world.reached], [world.alive], [], [world.get_state()]
    for a in actions:
        _, info = world.step(a)
        cov.append(info["covered"]), rea.append(info["reached"]), alive.append(info["alive"])
        col.append(info["collisions"]), states.append(world.get_state())
    stack = lambda xs: torch.stack(xs, dim=1)  # noqa: E731
    log = EpisodeLog(stack(cov), stack(rea), stack(col).long(), stack(alive), varying=world.scenario.varying,
                     horizon=world.horizon)
    return states, log


@pytest.mark.parametrize("scenario, overrides", [
    ("mpe-5", {}),
    ("mpe-20to10", {}),
    # one agent on a small map: some episodes reach SR 1 (Steps < horizon), some do not
    ("mpe-5", {"num_agents": 1, "num_obstacles": 0, "world_size": 0.6}),
])
def test_same_seed_and_actions_give_the_native_trajectory_and_metrics(scenario, overrides):
    B, seed = 16, 7
    native = ParticleWorld(scenario, num_envs=B, seed=seed, **overrides)
    env = ParticleTorchRLEnv(scenario, num_envs=B, seed=seed, **overrides)
    actions = _actions(0, native.horizon, B, native.num_agents)
    states, log = _native_log(native, actions)
    td = env.reset()
    for t, a in enumerate(actions):
        for k, v in env.world.get_state().items():
            assert torch.equal(v, states[t][k]), (t, k)
        td["agents", "action"] = a
        out = env.step(td)["next"]
        assert torch.equal(out["agents", "mask"], states[t + 1]["alive"])
        td = out
    for k, v in env.world.get_state().items():
        assert torch.equal(v, states[-1][k]), k
    assert bool(out["done"].all())
    ep = out["episode"]
    assert torch.equal(ep["success_rate"], success_rate(log))
    assert torch.equal(ep["steps"], steps(log))
    assert torch.equal(ep["collision_rate"], collision_rate(log))
    assert torch.equal(ep["solved"], reached_target(log))
    if overrides:
        assert 0 < int(ep["solved"].sum()) < B and (ep["steps"][ep["solved"]] < native.horizon).all()
    # set_seed + reset starts the episodes ParticleWorld(seed=...) starts
    env.set_seed(seed)
    env.reset()
    assert torch.equal(env.world.agent_pos, states[0]["agent_pos"])


@pytest.mark.parametrize("scenario", ["mpe-5", "mpe-20to10"])
def test_observation_and_reward_are_the_pettingzoo_faces(scenario):
    """One world against PettingZoo's one episode: same seed, same actions, same observations
    (exactly) and rewards (to float32 rounding); dropped agents: mask off, zero reward after."""
    pz = parallel_env(scenario)
    obs_pz, _ = pz.reset(seed=3)
    env = ParticleTorchRLEnv(scenario, num_envs=1, seed=3)
    td = env.reset()
    names = pz.possible_agents
    assert np.array_equal(td["agents", "observation"][0].numpy(), np.stack([obs_pz[a] for a in names]))
    actions = _actions(1, env.world.horizon, 1, env.num_agents)
    gone = set()
    for a in actions:
        obs_pz, rew_pz, term, trunc, _ = pz.step({n: int(a[0, names.index(n)]) for n in pz.agents})
        td["agents", "action"] = a
        out = env.step(td)["next"]
        td = out
        obs, rew, mask = out["agents", "observation"][0], out["agents", "reward"][0, :, 0], out["agents", "mask"][0]
        for i, n in enumerate(names):
            if n in gone:
                assert rew[i] == 0 and not mask[i]
                continue
            assert np.array_equal(obs[i].numpy(), obs_pz[n]), n
            assert rew[i].item() == pytest.approx(rew_pz[n], rel=1e-5, abs=1e-5)
            assert bool(mask[i]) == (not term[n])
        gone |= {n for n, t in term.items() if t}
    assert bool(out["done"].all()) and all(trunc[n] for n in trunc if n not in gone)
    if scenario == "mpe-20to10":
        assert len(gone) == 10 and int(out["agents", "mask"].sum()) == 10


def test_reset_mask_resets_only_finished_worlds():
    env = ParticleTorchRLEnv("mpe-20", num_envs=4, seed=0)
    td = env.reset()
    for a in _actions(2, 5, 4, 20):
        td["agents", "action"] = a
        td = env.step(td)["next"]
    before = env.world.get_state()
    obs_before = td["agents", "observation"].clone()
    mask = torch.tensor([[True], [False], [True], [False]])
    td["_reset"] = mask
    out = env.reset(td)
    after = env.world.get_state()
    kept, fresh = [1, 3], [0, 2]
    for k, v in after.items():
        assert torch.equal(v[kept], before[k][kept]), k
    assert (after["t"][fresh] == 0).all() and (after["t"][kept] == 5).all()
    assert not torch.equal(after["agent_pos"][fresh], before["agent_pos"][fresh])
    assert torch.equal(out["agents", "observation"][kept], obs_before[kept])
    assert (out["episode", "collision_rate"][fresh] == 0).all()


def _stepper(env, seed):
    actions = iter(_actions(seed, 50, env.world.num_envs, env.num_agents))

    def step(td):
        td["agents", "action"] = next(actions)
        return env.step(td)["next"]
    return step


@pytest.mark.parametrize("hold", ["tensor", "view", "numpy", "tensordict", "storage", "weakref", "shared"])
def test_a_held_observation_keeps_its_numbers(hold):
    """The face writes a new observation into an old one's memory only when nothing can reach
    it: however an observation is held, later steps leave it (and its memory) alone."""
    env = ParticleTorchRLEnv("mpe-5", num_envs=3, seed=0)
    step = _stepper(env, 4)
    td = step(env.reset())
    obs = td["agents", "observation"]
    if hold == "shared":  # another process could hold it: nothing here can tell
        obs.share_memory_()
    copy, ptr = obs.clone(), obs.data_ptr()
    holder = (obs if hold == "tensor" else obs[1:] if hold == "view" else obs.numpy() if hold == "numpy"
              else td if hold == "tensordict" else obs.untyped_storage() if hold == "storage"
              else weakref.ref(obs) if hold == "weakref" else None)
    del obs, td
    td = step(env.reset())
    for _ in range(12):
        td = step(td)
        assert td["agents", "observation"].data_ptr() != ptr
    if hold in ("tensor", "tensordict"):
        assert torch.equal(holder if hold == "tensor" else holder["agents", "observation"], copy)
    elif hold == "weakref":  # what it still reaches is the observation it was made for
        assert holder() is None or torch.equal(holder(), copy)
    elif hold in ("view", "numpy"):
        assert np.array_equal(np.asarray(holder), copy[1:].numpy() if hold == "view" else copy.numpy())


def test_dropped_observations_lend_their_memory():
    """What nobody holds is used again: a few buffers go round instead of fresh memory each step
    (5.2 MB per step at mpe-50 x 64 worlds, a page fault per 4 KiB)."""
    env = ParticleTorchRLEnv("mpe-5", num_envs=3, seed=0)
    step = _stepper(env, 5)
    td, seen = env.reset(), set()
    for _ in range(15):  # within mpe-5's horizon of 18
        td = step(td)
        seen.add(td["agents", "observation"].data_ptr())
    assert len(seen) <= 4


def test_device_is_honoured():
    env = ParticleTorchRLEnv("mpe-5", num_envs=2, device="cpu", seed=0)
    td = env.rollout(2)
    assert env.device == torch.device("cpu") and td.device == torch.device("cpu")
    assert env.world.agent_pos.device == torch.device("cpu")
    if torch.cuda.is_available():
        gpu = ParticleTorchRLEnv("mpe-5", num_envs=2, device="cuda", seed=0)
        check_env_specs(gpu)
        assert gpu.rollout(2)["next", "agents", "observation"].is_cuda


def test_bad_input_is_one_clear_error():
    with pytest.raises(ValueError, match="unknown scenario 'mpe-7'"):
        ParticleTorchRLEnv("mpe-7")
    with pytest.raises(ValueError, match="expected a particle scenario"):
        ParticleTorchRLEnv("drone-5")
    env = ParticleTorchRLEnv("mpe-5", num_envs=2, seed=0)
    env.reset()
    for bad in (torch.zeros(2, 4, dtype=torch.long), torch.zeros(2, 5, 5, dtype=torch.long)):  # too few, one-hot
        with pytest.raises(ValueError, match=r"\('agents', 'action'\) with shape \(num_envs, num_agents\) = \(2, 5\)"):
            env.step(TensorDict({"agents": {"action": bad}}, batch_size=[2]))
    with pytest.raises(ValueError, match="got nothing"):
        env.step(TensorDict({}, batch_size=[2]))
    with pytest.raises(ValueError, match=r"ids in \[0, 5\)"):
        env.step(TensorDict({"agents": {"action": torch.full((2, 5), 5)}}, batch_size=[2]))


def test_without_torchrl_the_import_says_how_to_install(monkeypatch):
    import importlib
    import sys

    for name in [m for m in sys.modules if m == "torchrl" or m.startswith("torchrl.")]:
        monkeypatch.setitem(sys.modules, name, None)  # as if TorchRL were not installed
    monkeypatch.delitem(sys.modules, "masp_lite.envs.torchrl")
    with pytest.raises(ImportError, match=r"pip install masp-lite\[torchrl\]"):
        importlib.import_module("masp_lite.envs.torchrl")
