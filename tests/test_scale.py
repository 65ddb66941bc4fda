"""Past the paper's scale: teams of 500 and 1000 at mpe-50's density, a decision that stays cheap there,
and a memory estimate that holds there."""
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from masp_lite.envs import get_scenario, make
from masp_lite.envs.scenarios import same_density
from masp_lite.evaluation.evaluate import memory_estimate
from masp_lite.nets import kernels
from masp_lite.nets.encoders import CrossEncoder
from masp_lite.nets.fusion import GroupInformationFusion, group_division, random_permutation
from masp_lite.nets.masp import MASPNets, gm_inputs, pair_features
from masp_lite.weights import load_weights

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------- the scenarios
@pytest.mark.parametrize("n", [50, 100, 200, 500, 1000])
def test_same_density_keeps_area_and_obstacles_per_agent_and_grows_the_horizon_with_the_side(n):
    base, over = get_scenario("mpe-50"), same_density("mpe-50", n)
    sc = get_scenario("mpe-50", **over)  # a valid scenario: every body still fits
    assert sc.num_agents == n and sc.num_landmarks == n
    assert sc.area / n == pytest.approx(base.area / base.num_agents)
    assert sc.num_obstacles / n == pytest.approx(base.num_obstacles / base.num_agents, abs=0.5 / n)
    ratio = sc.world_size / base.world_size
    assert sc.horizon == math.ceil(base.horizon * ratio) and sc.horizon / base.horizon >= ratio
    assert sc.world == base.world and sc.name == "mpe-50"  # the preset's world, and its weights


def test_same_density_at_the_paper_size_is_the_preset_and_past_it_the_documented_maps():
    base = get_scenario("mpe-50")
    assert same_density("mpe-50", 50) == {"num_agents": 50, "num_obstacles": 30, "world_size": base.world_size,
                                          "horizon": base.horizon}
    five, thousand = same_density("mpe-50", 500), same_density("mpe-50", 1000)
    assert (five["num_obstacles"], round(five["world_size"], 1), five["horizon"]) == (300, 63.2, 285)
    assert (thousand["num_obstacles"], round(thousand["world_size"], 1), thousand["horizon"]) == (600, 89.4, 403)
    assert same_density("mpe-20", 20)["world_size"] == get_scenario("mpe-20").world_size


@pytest.mark.parametrize("name,n", [("mpe-50to20", 500), ("mpe-50", 0), ("mpe-50", 2.5), ("mpe-50", True),
                                    ("mpe-7", 100)])
def test_same_density_refuses_a_team_change_and_bad_sizes(name, n):
    with pytest.raises(ValueError, match="expected"):
        same_density(name, n)


def test_a_world_of_the_scaled_scenario_builds_and_steps():
    w = make("mpe-50", num_envs=1, seed=0, **same_density("mpe-50", 500))
    obs = w.reset(seed=0)
    assert obs["agent_pos"].shape == (1, 500, 2) and obs["obstacle_pos"].shape == (1, 300, 2)
    assert obs["agent_pos"].abs().max() <= w.scenario.world_size / 2
    obs, info = w.step(torch.zeros(1, 500, dtype=torch.long))
    assert info["covered"].shape == (1, 500)


@pytest.mark.parametrize("n", [500, 1000])
def test_the_records_past_the_paper_scale_run_the_documented_scenario(n):
    found = sorted((ROOT / "results" / "zero-shot").glob(f"*_mpe-50_num_agents={n}*.json"))
    methods = {json.loads(p.read_text())["method"] for p in found}
    assert methods == {"masp", "h-greedy", "h-bottleneck"} and len(found) == 6  # batched and one world each
    for path in found:
        rec = json.loads(path.read_text())
        assert rec["overrides"] == same_density("mpe-50", n), path.name
        assert (rec["num_envs"] == 1) == path.stem.endswith("_one-world"), path.name


# ---------------------------------------------------------------- the decision, sliced
def _literal_division(perm, group_size):
    """The paper's rule written with a boolean mask (the first implementation), for comparison."""
    B, N = perm.shape[:2]
    ids = torch.arange(N)
    m = min(group_size - 1, N - 1)
    full = perm.unsqueeze(1).expand(B, N, N) if perm.dim() == 2 else perm
    others = full[full != ids.view(1, N, 1)].view(B, N, N - 1)
    G = math.ceil((N - 1) / m)
    others = torch.cat([others, others[..., :G * m - (N - 1)]], dim=-1).view(B, N, G, m)
    return torch.cat([ids.view(1, N, 1, 1).expand(B, N, G, 1), others], dim=-1)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6, 7, 20, 51])
@pytest.mark.parametrize("group_size", [2, 3, 4, 5])
def test_group_division_gathers_exactly_the_literal_groups(n, group_size):
    g = torch.Generator().manual_seed(n * 10 + group_size)
    perm = random_permutation(3, n, g)
    assert torch.equal(group_division(perm, group_size), _literal_division(perm, group_size))
    per_agent = torch.rand(2, n, n, generator=g).argsort(-1)  # one order per agent
    assert torch.equal(group_division(per_agent, group_size), _literal_division(per_agent, group_size))


@pytest.mark.parametrize("dead", [False, True])
def test_a_world_cut_into_slices_of_agents_fuses_and_scores_bit_for_bit(dead, monkeypatch):
    """A world bigger than a chunk is computed a slice of agents at a time: every number is the same."""
    torch.manual_seed(0)
    gif, cross = GroupInformationFusion(6, 32), CrossEncoder(32, distance_channels=2)
    B, N = 2, 12
    pos, vel = torch.randn(B, N, 2) * 2, torch.randn(B, N, 2)
    pair, groups = pair_features(pos, vel), group_division(random_permutation(B, N), 3)
    alive = torch.ones(B, N, dtype=torch.bool)
    if dead:
        alive[1, [0, 4, 5]] = False
    ya, yt, dist = torch.randn(B, N, 32), torch.randn(B, N, 32), torch.rand(B, N, N, 2)

    def run(rows):
        monkeypatch.setattr(kernels, "FUSION_ROWS", rows)
        monkeypatch.setattr(kernels, "SCORE_ROWS", rows)
        with torch.inference_mode():
            return gif(pair, groups, alive), cross(ya, yt, dist)

    (f_whole, s_whole), (f_sliced, s_sliced) = run(10 ** 9), run(40)  # 40 rows: slices of 2 agents
    assert len(kernels._chunks(B, N, 1, 18, 40)) == 2 * 6
    assert torch.equal(f_whole, f_sliced) and torch.equal(s_whole, s_sliced)


def test_the_shipped_networks_decide_the_same_sliced_or_whole_at_130_agents(monkeypatch):
    """130 agents, the shipped weights: the default chunks slice each world; the executor's fusion and the
    Goal Matcher's scores equal those of whole worlds bit for bit (what keeps the N <= 200 records)."""
    nets, _ = load_weights(None, scenario="mpe-50")
    w = make("mpe-50", num_envs=2, seed=1, num_agents=130)
    obs = w.reset(seed=1)
    perm = random_permutation(2, 130, torch.Generator().manual_seed(0))
    inputs = nets.cae_inputs(obs, torch.zeros(2, 130, dtype=torch.long), perm)

    def run():
        with torch.inference_mode():
            return nets.cae.fusion(*inputs[:3]), nets.gm_logits(obs, w.scenario.world_size / 2)

    assert 130 * inputs[1].shape[2] * 3 > kernels.FUSION_ROWS and 130 * 130 > kernels.SCORE_ROWS  # sliced
    sliced = run()
    monkeypatch.setattr(kernels, "FUSION_ROWS", 10 ** 9)
    monkeypatch.setattr(kernels, "SCORE_ROWS", 10 ** 9)
    whole = run()
    assert all(torch.equal(a, b) for a, b in zip(sliced, whole))


def test_use_kernels_switches_one_network_and_leaves_another_alone(monkeypatch):
    on, off = MASPNets(width=8), kernels.use_kernels(MASPNets(width=8), False)
    assert on.cae.fusion.kernel and on.gm.cross.kernel and not off.cae.fusion.kernel and not off.gm.cross.kernel
    w = make("mpe-5", num_envs=2, seed=0)
    obs = w.reset(seed=0)
    goals, perm = torch.zeros(2, 5, dtype=torch.long), random_permutation(2, 5)

    def refuse(*args):
        raise RuntimeError("kernel called")
    monkeypatch.setattr(kernels.OneLayerFusion, "apply", refuse)
    monkeypatch.setattr(kernels.ScoreHead, "apply", refuse)
    a, g, d = gm_inputs(obs, 1.0)
    with torch.no_grad():
        off.cae_logits(off.cae_inputs(obs, goals, perm))
        off.gm(a, g, d, obs["alive"])
        with pytest.raises(RuntimeError, match="kernel called"):
            on.cae_logits(on.cae_inputs(obs, goals, perm))
        with pytest.raises(RuntimeError, match="kernel called"):
            on.gm(a, g, d, obs["alive"])


# ---------------------------------------------------------------- memory
# The peak of this interpreter's own memory: VmHWM, which starts afresh at exec. (ru_maxrss does not: Linux carries
# the high-water mark of the process image replaced by exec, here a pytest worker of several GiB, into it.)
_PEAK = ("import sys\nfrom masp_lite.cli import main\nmain(sys.argv[1:])\n"
         "print('PEAK', next(line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM:')))")


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="reads VmHWM from Linux's /proc")
@pytest.mark.parametrize("n,worlds", [(500, 4), (1000, 1)])
def test_the_memory_estimate_holds_within_a_quarter_past_the_paper_scale(n, worlds):
    """``evaluate`` of MASP at mpe-50's density, a short horizon (both levels decide): its peak resident memory
    is within 25 % of :func:`memory_estimate`, the figure ``check_memory`` refuses a batch by."""
    over = {**same_density("mpe-50", n), "horizon": 4}
    args = ["evaluate", "--method", "masp", "--scenario", "mpe-50", "--num-envs", str(worlds), "--episodes",
            str(worlds), "--seeds", "0", "--threads", "1"]
    args += [a for k, v in over.items() for a in ("--set", f"{k}={v!r}")]
    out = subprocess.run([sys.executable, "-c", _PEAK, *args], capture_output=True, text=True, cwd=ROOT, check=True)
    peak = next(int(line.split()[1]) for line in out.stdout.splitlines() if line.startswith("PEAK")) * 1024
    assert abs(peak / memory_estimate(n, worlds) - 1) <= 0.25, (peak / 2 ** 20, memory_estimate(n, worlds) / 2 ** 20)
