"""The playground, driven from Python: set its widgets, click run, read the frames and metrics it shows."""
import numpy as np
import pytest

pytest.importorskip("ipywidgets")

from masp_lite.envs import make  # noqa: E402
from masp_lite.evaluation import collision_rate, rollout, steps, success_rate  # noqa: E402
from masp_lite.policies import make_policy  # noqa: E402
from masp_lite.viz import playground  # noqa: E402
from masp_lite.viz.playground import Playground, metrics_at, rollout_pair, same_layout, static, team_sizes  # noqa: E402

HORIZON, SEED = 10, 5  # seed 5: both methods collide and solve mpe-5 within 10 steps, at different steps


@pytest.fixture(scope="module")
def pg():
    """A playground set up from its widgets and run by its button (h-greedy vs masp on mpe-5)."""
    pg = Playground(overrides={"horizon": HORIZON}, run=False)
    assert pg.episodes is None
    pg.scenario.value = "mpe-5"
    pg.seed.value = SEED
    pg.method_a.value, pg.method_b.value = "h-greedy", "masp"
    pg.run_button.click()
    return pg


def test_run_button_records_both_methods_on_one_layout(pg):
    a, b = pg.episodes
    assert (a.method, b.method) == ("h-greedy", "masp") and a.seed == b.seed == SEED
    assert len(a.frames) == len(b.frames) == HORIZON + 1 and a.recording is None
    for key in ("agent_pos", "landmark_pos", "obstacle_pos"):
        np.testing.assert_array_equal(a.frames[0][key], b.frames[0][key])
    assert same_layout(a, b)
    assert not np.array_equal(a.frames[-1]["agent_pos"], b.frames[-1]["agent_pos"])  # two methods, two paths
    assert pg.view.value[:8] == b"\x89PNG\r\n\x1a\n" and pg.step.max == HORIZON
    assert "h-greedy vs masp on mpe-5" in pg.status.value


def test_step_slider_moves_the_view_and_the_metrics(pg):
    pg.step.value = 0
    start_png, start_table = pg.view.value, pg.table.value
    assert [m["t"] for m in pg.metrics] == [0, 0] and all(m["success_rate"] < 1 for m in pg.metrics)
    assert "t = 0/10" in start_table and "—" in start_table  # Steps: not reached yet
    pg.step.value = HORIZON
    assert [m["t"] for m in pg.metrics] == [HORIZON, HORIZON]
    assert pg.metrics == tuple(metrics_at(ep, HORIZON) for ep in pg.episodes)
    assert pg.table.value != start_table and pg.view.value != start_png
    assert f"t = {HORIZON}/{HORIZON}" in pg.table.value


def test_last_step_metrics_are_the_episode_metrics(pg):
    """At the last step the ticking numbers are evaluate's: an independent rollout of each method agrees."""
    for ep in pg.episodes:
        world = make("mpe-5", num_envs=1, seed=SEED, horizon=HORIZON)
        options = {"seed": SEED} if ep.method == "masp" else {}
        log, _ = rollout(world, make_policy(ep.method, world, **options), 1, seed=SEED)
        got = metrics_at(ep, HORIZON)
        assert got["success_rate"] == float(success_rate(log)[0])
        assert got["steps"] == float(steps(log)[0]) < HORIZON
        assert got["collision_rate"] == float(collision_rate(log)[0]) > 0
        assert metrics_at(ep, 0)["collision_rate"] == 0.0


def test_scenario_choice_offers_only_valid_team_sizes():
    assert team_sizes("mpe-5") == [5]                 # 20 agents do not fit its 2 m map
    assert team_sizes("mpe-20to10") == [20, 50]       # 5 agents cannot shrink to 10
    pg = Playground(run=False)
    pg.scenario.value = "mpe-50"
    assert list(pg.team_size.options) == [5, 20, 50] and pg.team_size.value == 50


def test_static_fallback_is_a_side_by_side_animation(pg):
    page = static(pg.episodes)
    assert page.data.count("<video") == 2 and "h-greedy vs masp on mpe-5" in page.data
    bundle = pg._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in bundle and "data:image/png;base64," in bundle["text/html"]
    shown = playground.show(overrides={"horizon": 3}, method_b="h-greedy")  # under a test runner: no widgets
    assert shown.data.count("<video") == 2


def test_drones_show_two_meshcat_pages_and_report_a_bad_choice():
    pg = Playground("drone-5", method_a="h-greedy", method_b="random", overrides={"horizon": 12})
    a, b = pg.episodes
    assert same_layout(a, b) and a.frames is None and a.recording["pos"].shape[1] == 5
    assert pg.view3d.value.count("<iframe") == 2 and pg.view.layout.display == "none"
    # each pane's key sits under its view, not over it (nor over meshcat's Open Controls bar)
    assert 'id=&quot;masp-key&quot;' not in pg.view3d.value  # the pages inside the frames carry no key overlay
    assert pg.view3d.value.count('class="masp-key"') == 2
    assert pg.slider_note.value and "moves the metrics" in pg.slider_note.value and pg.step.description == "metrics at"
    pg.step.value = 12
    assert [m["t"] for m in pg.metrics] == [12, 12]
    pg.method_b.value = "h-capt"                      # a particle-only method: the status line says so
    pg.run_button.click()
    assert "expected a particle scenario" in pg.status.value and pg.episodes == (a, b)


@pytest.mark.parametrize("kwargs, match", [
    ({"method_a": "greedy"}, "unknown method 'greedy'"),
    ({"method_b": None}, "method: expected a name"),
    ({"scenario": "mpe-7"}, "unknown scenario 'mpe-7'"),
    ({"team_size": 50}, "too small for 50 agents"),
    ({"seed": -1}, "seed: expected a non-negative int"),
])
def test_bad_choices_fail_with_one_clear_error(kwargs, match):
    with pytest.raises(ValueError, match=match):
        rollout_pair(**kwargs)
    with pytest.raises(ValueError, match=match):
        Playground(**kwargs, run=False)
