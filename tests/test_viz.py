"""2-D playback: recorded frames, drawing, and the play command writing files."""
import matplotlib
import numpy as np
import pytest
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

    calls = []
    fake = types.ModuleType("masp_lite.viz.meshcat3d")
    fake.play_to_html = lambda method, scenario, out, seed=0, **overrides: calls.append(
        (method, scenario, out, seed, overrides))
    monkeypatch.setitem(sys.modules, "masp_lite.viz.meshcat3d", fake)
    out = tmp_path / "ep.html"
    assert main(["play", "--method", "h-greedy", "--scenario", "drone-5", "--out", str(out),
                 "--seed", "2", "--set", "horizon=30"]) == 0
    assert calls == [("h-greedy", "drone-5", str(out), 2, {"horizon": 30})]
    # method options cannot reach the exporter: one clear error instead of a silent drop
    assert main(["play", "--method", "random", "--scenario", "mpe-5", "--out", str(out),
                 "--set", "seed=1"]) == 2
