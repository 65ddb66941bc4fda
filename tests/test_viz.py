"""2-D playback: recorded frames, drawing, and the play command writing files."""
import re

import matplotlib
import numpy as np
import pytest
import torch
from PIL import Image

from masp_lite.__main__ import main
from masp_lite.envs import make
from masp_lite.policies import make_policy
from masp_lite.viz.anim2d import animate, draw_frame, record, save


def test_record_frames_follow_the_world():
    w = make("mpe-20to10", num_envs=2, seed=0, horizon=9, change_step=3)
    frames = record(w, make_policy("h-greedy", w), seed=1, env_index=1)
    assert len(frames) == 10 and [f["t"] for f in frames] == list(range(10))
    last = frames[-1]
    np.testing.assert_array_equal(last["agent_pos"], w.agent_pos[1].numpy())
    np.testing.assert_array_equal(last["covered"], w.covered[1].numpy())
    assert last["alive"].sum() == 10 and frames[0]["alive"].all()
    assert last["assignment"].shape == (20,) and last["varying"]
    with pytest.raises(ValueError, match="env_index"):
        record(w, make_policy("h-greedy", w), env_index=2)


def test_draw_frame_draws_every_body_to_scale():
    import matplotlib.pyplot as plt
    w = make("mpe-5", num_envs=1, seed=0, horizon=3)
    frames = record(w, make_policy("h-greedy", w), seed=0)
    fig, ax = plt.subplots()
    scene = draw_frame(ax, frames[-1])
    for coll, key, radius in ((scene.agents, "agent_pos", 0.1), (scene.landmarks, "landmark_pos", 0.05),
                              (scene.obstacles, "obstacle_pos", 0.1)):
        np.testing.assert_allclose(coll.get_offsets(), frames[-1][key])
        np.testing.assert_allclose(coll._widths, radius)  # half-widths in data units: to scale
    covered = frames[-1]["covered"]
    green = matplotlib.colors.to_rgba("#31a354")
    faces = scene.landmarks.get_facecolors()
    assert [tuple(f) == green for f in faces] == covered.tolist()
    assert ax.get_title().startswith("t = 3/3")
    scene.update(frames[0])
    assert ax.get_title().startswith("t = 0/3")
    plt.close(fig)


def test_play_writes_a_small_gif(tmp_path, capsys):
    out = tmp_path / "ep.gif"
    rc = main(["play", "--method", "h-greedy", "--scenario", "mpe-5", "--out", str(out),
               "--set", "horizon=4", "--seed", "3"])
    assert rc == 0 and out.stat().st_size > 0
    with Image.open(out) as im:
        assert im.n_frames == 5
    assert "wrote" in capsys.readouterr().out


def test_save_mp4_and_bad_names(tmp_path, capsys):
    w = make("mpe-5", num_envs=1, seed=0, horizon=2)
    anim = animate(record(w, make_policy("random", w), seed=0))
    assert save(anim, tmp_path / "ep.mp4").stat().st_size > 0
    with pytest.raises(ValueError, match=".gif or .mp4"):
        save(anim, tmp_path / "ep.png")
    assert main(["play", "--method", "random", "--scenario", "mpe-5", "--out", str(tmp_path / "x.txt")]) == 2
    assert "expected a .gif, .mp4 or .html" in capsys.readouterr().err
    assert main(["play", "--method", "random", "--scenario", "drone-5", "--out", str(tmp_path / "x.gif")]) == 2
    assert "drone scenario" in capsys.readouterr().err


def test_html_and_drone_playback_go_to_the_3d_exporter(tmp_path, monkeypatch):
    import sys
    import types

    from masp_lite.evaluation.metrics import EpisodeLog

    calls = []
    solved = torch.tensor([[[False], [True]]])  # one landmark, covered after the first step
    log = EpisodeLog(solved, solved, torch.zeros(1, 1, dtype=torch.long), torch.ones(1, 2, 1, dtype=torch.bool),
                     varying=False, horizon=1)
    fake = types.ModuleType("masp_lite.viz.meshcat3d")
    fake.record_episode = lambda method, scenario, seed=0, **overrides: calls.append(
        (method, scenario, seed, overrides)) or {"log": log}
    fake.episode_html = lambda episode: "<html>3-D</html>"
    monkeypatch.setitem(sys.modules, "masp_lite.viz.meshcat3d", fake)
    out = tmp_path / "ep.html"
    assert main(["play", "--method", "h-greedy", "--scenario", "drone-5", "--out", str(out),
                 "--seed", "2", "--set", "horizon=30"]) == 0
    assert calls == [("h-greedy", "drone-5", 2, {"horizon": 30})] and out.read_text() == "<html>3-D</html>"
    # method options cannot reach the exporter: one clear error instead of a silent drop
    assert main(["play", "--method", "random", "--scenario", "mpe-5", "--out", str(out),
                 "--set", "seed=1"]) == 2


# ------------------------------------------------------- draw_obs, training curves
def test_draw_obs_shows_one_world_of_an_observation():
    import matplotlib.pyplot as plt

    from masp_lite.viz.anim2d import COLOURS, draw_obs, frame_from_obs
    w = make("mpe-20to10", num_envs=3, seed=0, horizon=6, change_step=2)
    obs = w.reset()
    for _ in range(3):
        obs, _ = w.step(make_policy("random", w).act(obs))
    frame = frame_from_obs(obs, w.scenario, env=2)
    np.testing.assert_array_equal(frame["agent_pos"], obs["agent_pos"][2].numpy())
    assert frame["t"] == 3 and frame["horizon"] == 6 and frame["varying"] and frame["assignment"] is None
    fig, ax = plt.subplots()
    scene = draw_obs(obs, w.scenario, env=2, ax=ax, title="after the drop")
    assert scene.ax is ax and ax.get_title() == "after the drop"
    np.testing.assert_allclose(scene.agents.get_offsets(), obs["agent_pos"][2].numpy())
    np.testing.assert_allclose(scene.obstacles.get_offsets(), obs["obstacle_pos"][2].numpy())
    dropped = matplotlib.colors.to_rgb(COLOURS["dropped"])
    edges = [tuple(e[:3]) == dropped for e in scene.agents.get_edgecolors()]
    assert edges == (~obs["alive"][2]).tolist() and sum(edges) == 10
    assert draw_obs(obs, w.scenario, env=0, ax=ax).ax.get_title().startswith("t = 3/6")
    with pytest.raises(ValueError, match="env"):
        frame_from_obs(obs, w.scenario, env=3)
    plt.close(fig)


def _progress_csv(path, rows):
    from masp_lite.training import CSV_FIELDS
    lines = [",".join(CSV_FIELDS)]
    for i, row in enumerate(rows, start=1):
        values = {k: str(0.1 * i) for k in CSV_FIELDS}
        values.update(iteration=str(i), env_steps=str(100 * i), **row)
        lines.append(",".join(values[k] for k in CSV_FIELDS))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_read_progress_columns_nan_where_empty_and_last_evaluation(tmp_path):
    from masp_lite.viz.progress import last_evaluation, read_progress
    empty = {"eval_sr": "", "eval_steps": "", "eval_cr": ""}
    path = _progress_csv(tmp_path / "progress.csv", [empty, {"eval_sr": "0.5", "eval_steps": "20", "eval_cr": "0.25"},
                                                     empty])
    cols = read_progress(path)
    np.testing.assert_array_equal(cols["iteration"], [1, 2, 3])
    np.testing.assert_array_equal(cols["env_steps"], [100, 200, 300])
    assert cols["eval_sr"].dtype == float and np.isnan(cols["eval_sr"][[0, 2]]).all() and cols["eval_sr"][1] == 0.5
    assert last_evaluation(cols) == {"iteration": 2, "env_steps": 200, "sr": 0.5, "steps": 20.0, "cr": 0.25}
    assert last_evaluation(read_progress(_progress_csv(tmp_path / "none.csv", [empty]))) is None
    with pytest.raises(ValueError, match="existing progress.csv"):
        read_progress(tmp_path / "missing.csv")
    (tmp_path / "header.csv").write_text("iteration,env_steps\n")
    with pytest.raises(ValueError, match="no rows"):
        read_progress(tmp_path / "header.csv")
    (tmp_path / "bad.csv").write_text("iteration,env_steps\n1,many\n")
    with pytest.raises(ValueError, match="'env_steps': expected numbers"):
        read_progress(tmp_path / "bad.csv")


def test_plot_progress_draws_training_evaluation_and_baseline(tmp_path):
    import matplotlib.pyplot as plt

    from masp_lite.viz.progress import plot_progress, read_progress
    rows = [{"eval_sr": "", "eval_steps": "", "eval_cr": ""}] * 3 + [{"eval_sr": "0.9", "eval_steps": "12",
                                                                       "eval_cr": "0.3"}]
    cols = read_progress(_progress_csv(tmp_path / "p.csv", rows * 2))
    fig = plot_progress(cols, "a run", baseline={"sr": 0.97, "steps": 11.0, "cr": 0.4}, baseline_label="base")
    sr_ax, steps_ax, _, rewards_ax = fig.axes
    train, evaluation, base = sr_ax.get_lines()
    np.testing.assert_array_equal(train.get_xdata(), cols["env_steps"])
    np.testing.assert_array_equal(evaluation.get_xdata(), [400, 800])      # only the evaluated rows
    np.testing.assert_array_equal(evaluation.get_ydata(), [0.9, 0.9])
    assert base.get_ydata()[0] == 0.97 and base.get_label() == "base" and steps_ax.get_lines()[2].get_ydata()[0] == 11
    assert [line.get_label() for line in rewards_ax.get_lines()] == ["R_GM (eq. 1)", "R_CAE (eq. 5)"]
    assert fig._suptitle.get_text() == "a run"
    plt.close(fig)
    fig = plot_progress(cols)                                                # no baseline: two lines per panel
    assert len(fig.axes[0].get_lines()) == 2
    plt.close(fig)


def test_progress_key_sits_under_the_panels_not_over_the_curves(tmp_path):
    """The key of SR / Steps / CR is one figure legend below every panel: inside the SR panel it
    covered the evaluation points and the baseline of a curve that sits near SR 1."""
    import matplotlib.pyplot as plt

    from masp_lite.viz.progress import plot_progress
    n = 40
    cols = {k: np.full(n, v) for k, v in (("train_sr", 0.98), ("train_steps", 20.0), ("train_cr", 0.1),
                                          ("gm_reward", -1.0), ("cae_reward", -5.0))}
    cols.update(env_steps=1000.0 * np.arange(1, n + 1), eval_sr=np.where(np.arange(n) % 5 == 4, 1.0, np.nan),
                eval_steps=np.where(np.arange(n) % 5 == 4, 18.0, np.nan),
                eval_cr=np.where(np.arange(n) % 5 == 4, 0.1, np.nan))
    fig = plot_progress(cols, "a stage", baseline={"sr": 0.99, "steps": 19.0, "cr": 0.2})
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    assert all(ax.get_legend() is None for ax in fig.axes[:3])
    (key,) = fig.legends
    assert [t.get_text() for t in key.get_texts()] == ["training rollouts (sampled)", "evaluation (deterministic)",
                                                       "h-greedy"]
    box = key.get_window_extent(renderer)
    for ax in fig.axes:
        panel = ax.get_tightbbox(renderer)                  # the panel with its tick labels and axis label
        assert box.y1 <= panel.y0 + 1, f"the key overlaps panel {ax.get_title()!r}"
    plt.close(fig)


def test_plot_history_puts_stages_end_to_end_and_leaves_a_gap_for_a_missing_curve(tmp_path):
    import matplotlib.pyplot as plt

    from masp_lite.viz.progress import plot_history
    rows = [{"eval_sr": "", "eval_steps": "", "eval_cr": ""}, {"eval_sr": "0.9", "eval_steps": "12", "eval_cr": "0.3"}]
    first = _progress_csv(tmp_path / "a.csv", rows * 2)                     # 4 rows: env steps 100 .. 400
    second = _progress_csv(tmp_path / "b.csv", rows)                        # 2 rows: env steps 100, 200
    history = {"stages": [{"progress": first, "training": {}},
                          {"progress": None, "training": {"env_steps": 1000}},   # a stage whose curve is not kept
                          {"progress": second, "training": {}}]}
    fig = plot_history(history, "three stages")
    sr = fig.axes[0]
    train = [line for line in sr.get_lines() if line.get_label() != "_child" and len(line.get_xdata()) > 2]
    np.testing.assert_array_equal(train[0].get_xdata(), [100, 200, 300, 400])
    later = [line.get_xdata() for line in sr.get_lines() if len(line.get_xdata()) and line.get_xdata()[0] > 400
             and line.get_linestyle() != ":"]
    np.testing.assert_array_equal(later[0], [1500, 1600])                 # 400 + 1000 of the missing curve + 100
    starts = sorted({float(line.get_xdata()[0]) for line in sr.get_lines() if line.get_linestyle() == ":"})
    assert starts == [0.0, 400.0, 1400.0]
    assert [t.get_text() for t in sr.texts] == ["1", "2", "3"]
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["training rollouts (sampled)",
                                                                   "evaluation (deterministic)"]
    assert [ax.get_ylabel() for ax in fig.axes] == ["SR", "Steps", "CR"]
    plt.close(fig)


def test_training_history_of_the_shipped_weights(tmp_path):
    from masp_lite.reproduction.histories import training_history
    from masp_lite.viz.progress import last_evaluation, read_progress
    from masp_lite.weights import read_manifest
    with pytest.raises(ValueError, match="no shipped weights"):
        training_history("mpe-7")
    assert training_history("mpe-20", root=tmp_path) is None          # an installed package: no results/
    history = training_history("mpe-20to10")                         # a team change uses its preset's history
    if history is None:
        pytest.skip("results/training/ is not in this checkout")
    entry = read_manifest()["mpe-20"]
    assert history["scenario"] == "mpe-20" and history["sha256"] == entry["sha256"]
    assert len(history["stages"]) == entry["stages"]
    assert sum(s["training"]["env_steps"] for s in history["stages"]) == entry["env_steps"]
    last = history["stages"][-1]
    assert last["progress"].name == "mpe-20-seed0.progress.csv" and last["progress"].is_absolute()
    cols = read_progress(last["progress"])
    assert len(cols["iteration"]) == last["training"]["iterations"]
    assert abs(last_evaluation(cols)["sr"] - last["training"]["final_eval"]["sr"]) < 1e-4


# ------------------------------------------------- playback: readable, keyed, offline
NETWORK = re.compile(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//|url\(\s*["']?\s*(?:https?:)?//|@import""", re.I)


def test_animation_is_readable_at_50_agents_with_key_trails_goals_and_method():
    import matplotlib.pyplot as plt

    from masp_lite.viz.anim2d import MIN_AGENT_PT, legend
    w = make("mpe-50", num_envs=1, seed=0, horizon=12)
    frames = record(w, make_policy("h-greedy", w), seed=0)
    anim = animate(frames, title="h-greedy on mpe-50", goals=True, trail=4)
    anim._func(10)
    fig, scene = anim._fig, anim.scene
    ax = scene.ax
    assert ax.get_title().startswith("h-greedy on mpe-50   t = 10/12")
    fig.canvas.draw()
    drawn_pt = 2 * scene.agents._widths[0] * ax.get_window_extent().width / fig.dpi * 72 / 20.0  # _widths: radii
    assert drawn_pt >= MIN_AGENT_PT and scene.magnify == 2.0       # magnified on the 20 m map ...
    np.testing.assert_allclose(scene.agents._widths, 0.1 * 2.0)
    np.testing.assert_allclose(scene.agents.get_offsets(), frames[10]["agent_pos"])  # ... at exact positions
    assert ax.get_xlabel() == "bodies drawn 2× their size"         # ... and the figure says so
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"agent", "landmark", "covered landmark", "obstacle", "agent in contact", "agent → its goal",
            "recent path"} <= set(labels)
    assert len(scene.trails.get_segments()) == 4 * 50              # 4 earlier frames x 50 agents
    goal_of = frames[10]["assignment"]
    assert len(scene.lines.get_segments()) == int((goal_of >= 0).sum()) > 0
    np.testing.assert_allclose(scene.lines.get_segments()[0][1], frames[10]["landmark_pos"][goal_of[goal_of >= 0][0]])
    plain = animate(frames)                                        # no goal lines unless asked for, no method
    plain._func(10)
    assert len(plain.scene.lines.get_segments()) == 0 and plain.scene.ax.get_title().startswith("t = 10/12")
    w5 = make("mpe-5", num_envs=1, seed=0, horizon=2)
    assert animate(record(w5, make_policy("h-greedy", w5), seed=0)).scene.magnify == 1.0  # small maps: to scale
    fig2, ax2 = plt.subplots()                                          # the key on one axes, without contacts
    assert [t.get_text() for t in legend(ax2, contacts=False).get_texts()] == [
        "agent", "landmark", "covered landmark", "obstacle"]
    plt.close(fig2)
    with pytest.raises(ValueError, match="trail"):
        animate(frames, trail=-1)


def test_current_goals_reads_what_each_policy_exposes():
    from masp_lite.viz.anim2d import current_goals
    w = make("mpe-5", num_envs=2, seed=0, horizon=4)
    obs = w.reset(seed=0)
    for method in ("h-greedy", "h-orca", "masp"):
        policy = make_policy(method, w)
        policy.reset(obs)
        policy.act(obs)
        goals = current_goals(policy)
        assert goals is not None and goals.shape == (2, 5) and not goals.is_floating_point(), method
    random = make_policy("random", w)
    random.reset(obs)
    random.act(obs)
    assert current_goals(random) is None
    frames = record(w, make_policy("masp", w), seed=0)                   # MASP's Goal Matcher picks, per frame
    assert frames[1]["assignment"].shape == (5,) and frames[0]["assignment"] is None


def test_player_embeds_a_video_that_loads_nothing_from_the_network():
    from masp_lite.viz.anim2d import player
    w = make("mpe-5", num_envs=1, seed=0, horizon=3)
    html = player(animate(record(w, make_policy("h-greedy", w), seed=0), title="h-greedy")).data
    assert "<video" in html and 'src="data:video/mp4;base64,' in html
    assert NETWORK.search(html) is None
    assert NETWORK.search('<link href="https://cdn.example/x.css">')  # the pattern does catch a CDN link
    assert NETWORK.search(animate(record(w, make_policy("random", w), seed=0)).to_jshtml())  # matplotlib's JS player


def test_play_goals_flag(tmp_path, capsys):
    out = tmp_path / "goals.gif"
    assert main(["play", "--method", "h-greedy", "--scenario", "mpe-5", "--out", str(out), "--set", "horizon=3",
                 "--goals"]) == 0 and out.stat().st_size > 0
    capsys.readouterr()
    assert main(["play", "--method", "h-greedy", "--scenario", "drone-5", "--out", str(tmp_path / "x.html"),
                 "--goals"]) == 2
    assert "2-D only" in capsys.readouterr().err


def test_progress_step_ticks_do_not_overlap():
    import matplotlib.pyplot as plt

    from masp_lite.viz.progress import plot_progress
    n = 150                                                               # chapter 06's short run at full size
    cols = {k: np.linspace(0, 1, n) for k in ("train_sr", "train_steps", "train_cr", "gm_reward", "cae_reward")}
    cols.update(env_steps=1152.0 * np.arange(1, n + 1), eval_sr=np.full(n, np.nan), eval_steps=np.full(n, np.nan),
                eval_cr=np.full(n, np.nan))
    fig = plot_progress(cols, "short run")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        boxes = [t.get_window_extent(renderer) for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
        assert len(boxes) >= 3
        for a, b in zip(boxes, boxes[1:]):
            assert a.x1 < b.x0, f"x tick labels overlap: {[t.get_text() for t in ax.get_xticklabels()]}"
    assert "50k" in [t.get_text() for t in fig.axes[0].get_xticklabels()]
    plt.close(fig)


def test_video_controls_strip_stays_below_the_legend_and_final_numbers():
    from masp_lite.viz import anim2d

    w = make("mpe-5", num_envs=1, seed=0, horizon=12)
    frames = record(w, make_policy("h-greedy", w), seed=0)
    anim = animate(frames, goals=True)
    fig = anim._fig
    fig.canvas.draw()
    legend = fig.legends[0].get_window_extent()
    # the legend's lowest pixel sits above the strip the browser's <video> control bar covers
    assert legend.y0 >= anim2d.CONTROLS_PX - 1
    numbers = anim2d.episode_numbers(frames)
    assert set(numbers) == {"sr", "steps", "cr"} and 0 <= numbers["sr"] <= 1
    assert 0 <= numbers["steps"] <= frames[-1]["horizon"]
    with pytest.raises(ValueError, match="at least one frame"):
        anim2d.episode_numbers([])


def test_ppo_health_reads_new_runs_and_older_ones_without_it(tmp_path):
    """plot_ppo_health draws both levels' KL, clip fraction and explained variance (a level never trained: none);
    a progress.csv from before those columns reads and plots as before, and says clearly what it lacks."""
    import matplotlib.pyplot as plt

    from masp_lite.training import CSV_FIELDS
    from masp_lite.viz.progress import health_text, plot_ppo_health, plot_progress, read_progress
    frozen = {f"gm_{k}": "" for k in ("approx_kl", "clip_fraction", "explained_variance")}  # a frozen Goal Matcher
    cols = read_progress(_progress_csv(tmp_path / "new.csv", [{}, {}, frozen]))
    fig = plot_ppo_health(cols, "health")
    assert [ax.get_title() for ax in fig.axes] == ["approximate KL", "clip fraction", "explained variance"]
    assert [len(ax.lines) for ax in fig.axes] == [2, 2, 2]
    np.testing.assert_allclose(fig.axes[1].lines[1].get_ydata(), [0.1, 0.2, 0.3])  # the executor's clip fraction
    plt.close(fig)
    old = [k for k in CSV_FIELDS if not k.endswith(("approx_kl", "clip_fraction", "explained_variance"))]
    path = tmp_path / "old.csv"
    path.write_text(",".join(old) + "\n" + ",".join("1" for _ in old) + "\n")
    cols = read_progress(path)
    assert "gm_approx_kl" not in cols and cols["train_sr"][0] == 1.0
    plt.close(plot_progress(cols))
    with pytest.raises(ValueError, match="no columns .*'gm_approx_kl'.*expected the progress.csv of a newer run"):
        plot_ppo_health(cols)
    row = {"gm_approx_kl": 0.004, "cae_approx_kl": 0.0123, "gm_clip_fraction": 0.02, "cae_clip_fraction": 0.09,
           "gm_explained_variance": float("nan"), "cae_explained_variance": 0.781}
    assert health_text(row) == "PPO KL 0.0040/0.0123, clipped 2%/9%, EV -/0.78 (Goal Matcher/executor)"
    assert health_text({"train_sr": 1.0}) == "PPO KL -/-, clipped -/-, EV -/- (Goal Matcher/executor)"
    assert health_text(None) == ""


def test_progress_line_shows_the_last_iterations_ppo_health(capsys):
    from types import SimpleNamespace

    from masp_lite.viz.progress import ProgressLine
    row = {f"{level}_{k}": 0.5 for level in ("gm", "cae") for k in ("approx_kl", "clip_fraction", "explained_variance")}
    ProgressLine(1, "run", every=0)(SimpleNamespace(iterations=1, env_steps=10, last_row=row))
    assert capsys.readouterr().err.rstrip().endswith(
        "done | PPO KL 0.5000/0.5000, clipped 50%/50%, EV 0.50/0.50 (Goal Matcher/executor)")


def test_progress_line_is_one_line_that_updates(capsys):
    from types import SimpleNamespace

    from masp_lite.viz.progress import ProgressLine

    line = ProgressLine(3, "MASP on mpe-5", every=0)
    for k in (1, 2, 3):
        line(SimpleNamespace(iterations=k, env_steps=100 * k))
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.count("\r") == 3       # one line, rewritten in place
    assert err.rstrip().endswith("MASP on mpe-5: iteration 3/3, 300 environment steps, 0 s, done")
    with pytest.raises(ValueError, match="positive number"):
        ProgressLine(0)


def test_progress_keys_name_only_the_lines_drawn():
    """A level that is not trained (R_GM under Hungarian goals, chapter 11) is NaN throughout: it draws
    no line, so no key may name it; the panel says it was not recorded."""
    import matplotlib.pyplot as plt

    from masp_lite.viz.progress import plot_progress
    n = 12
    cols = {k: np.linspace(0, 1, n) for k in ("train_sr", "train_cr", "cae_reward")}
    cols.update(env_steps=100.0 * np.arange(1, n + 1), gm_reward=np.full(n, np.nan), train_steps=np.full(n, np.nan),
                eval_sr=np.full(n, np.nan), eval_steps=np.full(n, np.nan), eval_cr=np.full(n, np.nan))
    fig = plot_progress(cols, "executor only")
    keys = [(ax.get_legend(), ax.get_lines()) for ax in fig.axes if ax.get_legend() is not None]
    keys += [(legend, [line for ax in fig.axes[:3] for line in ax.get_lines()]) for legend in fig.legends]
    assert keys, "expected a key"
    for legend, lines in keys:
        drawn = {line.get_label() for line in lines if np.isfinite(np.asarray(line.get_ydata(), float)).any()}
        named = [t.get_text() for t in legend.get_texts()]
        assert named and set(named) <= drawn, f"the key names {named}, the lines drawn are {sorted(drawn)}"
    rewards = fig.axes[3]
    assert [t.get_text() for t in rewards.get_legend().get_texts()] == ["R_CAE (eq. 5)"]
    assert rewards.get_lines()[0].get_color() == "C1"                    # R_CAE keeps its colour without R_GM
    assert rewards.get_legend().get_title().get_text() == "no R_GM recorded"
    assert fig.axes[1].get_lines() == []                                 # no Steps ever: nothing drawn there
    plt.close(fig)
