"""3-D playback: recorded episodes, the standalone meshcat page in headless Chromium, the live server."""
import os
import shutil
import subprocess
import tempfile

import numpy as np
import pytest

from masp_lite.policies.drones import DroneHungarianGreedy
from masp_lite.viz import meshcat3d

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def episode():
    return meshcat3d.record_episode(DroneHungarianGreedy, "drone-5", seed=0, horizon=60)


def test_record_episode_keeps_what_is_drawn(episode):
    T = 60 // 2 + 1
    assert episode["pos"].shape == (T, 5, 3) and episode["quat"].shape == (T, 5, 4)
    assert episode["alive"].shape == (T, 5) and episode["landmark_pos"].shape == (5, 3)
    assert np.isclose(episode["dt"], 0.032)
    assert np.abs(episode["pos"][-1] - episode["pos"][0]).max() > 0.5  # the drones flew
    with pytest.raises(ValueError, match="drone scenario"):
        meshcat3d.record_episode(DroneHungarianGreedy, "mpe-5")


def test_standalone_page_embeds_viewer_and_scene(episode, tmp_path):
    page = meshcat3d.episode_html(episode)
    assert "MeshCat.Viewer" in page and "handle_command_bytearray" in page
    assert "ws://" not in page.split("<script>")[-1]  # the scene needs no server
    assert page.count("base64,") > 5 * 10  # drones, landmarks, trails, crash markers, animation
    html = meshcat3d.notebook_html(page)
    assert html.data.startswith("<div><iframe srcdoc=")


def screenshot(page: str, png: str) -> np.ndarray:
    from PIL import Image
    with tempfile.TemporaryDirectory() as profile:
        html = os.path.join(profile, "page.html")
        with open(html, "w") as f:
            f.write(page)
        subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                        "--no-first-run", "--disable-background-networking", "--disable-component-update",
                        "--disable-sync", f"--user-data-dir={profile}", f"--screenshot={png}",
                        "--window-size=640,480", "--virtual-time-budget=8000", f"file://{html}"],
                       check=True, capture_output=True, timeout=120)
    return np.asarray(Image.open(png).convert("RGB")).astype(int)


@pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed (Debian: apt-get install chromium)")
def test_page_renders_the_scene_in_headless_chromium(episode, tmp_path):
    shot = screenshot(meshcat3d.episode_html(episode), str(tmp_path / "scene.png"))
    empty = screenshot(meshcat3d.RecordingWindow().static_html(), str(tmp_path / "empty.png"))
    assert shot.shape == (480, 640, 3)
    colours = np.unique(shot.reshape(-1, 3), axis=0)
    assert len(colours) > 100, "the page is (nearly) uniform: nothing was drawn"
    changed = (np.abs(shot - empty).sum(-1) > 30).mean()
    assert changed > 0.05, f"only {changed:.1%} of the pixels differ from the empty viewer"


def test_live_viewer_binds_localhost_and_stops(episode):
    with meshcat3d.LiveViewer() as viewer:
        assert "127.0.0.1" in viewer.web_url and viewer.running
        viewer.show(episode)
        proc = viewer._proc
        assert "iframe" in viewer.cell().data
    assert proc.poll() is not None and not viewer.running


def test_play_command_writes_html(tmp_path):
    from masp_lite.__main__ import main
    out = tmp_path / "drones.html"
    assert main(["play", "--method", "h-greedy", "--scenario", "drone-5", "--out", str(out),
                 "--set", "horizon=20"]) == 0
    assert out.stat().st_size > 100_000 and "MeshCat.Viewer" in out.read_text()
