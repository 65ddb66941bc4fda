"""3-D playback: recorded episodes, the standalone meshcat page in headless Chromium, the live server."""
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import replace
from pathlib import Path

import nbformat
import numpy as np
import pytest

from masp_lite.policies.drones import DroneHungarianGreedy
from masp_lite.viz import meshcat3d

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ROOT = Path(__file__).resolve().parents[1]
SERVER_FRAME = re.compile(r"""<iframe[^>]*\ssrc\s*=\s*["']?\s*https?://(?:127\.0\.0\.1|localhost)""", re.I)


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
    assert SERVER_FRAME.search(html.data) is None


def _commands(episode):
    import umsgpack
    window = meshcat3d.RecordingWindow()
    meshcat3d.build_scene(meshcat3d._meshcat().Visualizer(window=window), episode)
    return [umsgpack.unpackb(c) for c in window.commands]


def test_landmarks_are_marked_and_the_page_names_method_and_colours(episode):
    sc = episode["scenario"]
    objects = {c["path"]: c["object"]["geometries"][0] for c in _commands(episode) if c["type"] == "set_object"}
    ball, marker = objects["/meshcat/landmarks/0/ball"], objects["/meshcat/landmarks/0/marker"]
    assert ball["radius"] == sc.landmark_radius == 0.05
    assert marker["radius"] == meshcat3d.marker_radius(sc) > 2.5 * ball["radius"]  # visible from the default camera
    assert objects["/meshcat/landmarks/0/stem"]["height"] == pytest.approx(episode["landmark_pos"][0][2])
    assert meshcat3d.marker_radius(replace(sc, world_size=16.0)) == 0.2              # grows with the map
    page = meshcat3d.episode_html(episode)
    key = page[page.index('<div id="masp-key">'):page.index("</div>", page.index('<div id="masp-key">'))]
    assert "<b>DroneHungarianGreedy</b> on drone-5" in key and "landmarks covered at the end" in key
    for words in ("landmark", "reached", "crash", "rotor spinning −1", "rotor spinning +1"):
        assert words in key
    assert "<title>masp-lite: DroneHungarianGreedy on drone-5</title>" in page
    assert meshcat3d.record_episode("h-greedy", "drone-5", horizon=2)["method"] == "h-greedy"


def test_chapter_08_saved_outputs_embed_the_view_not_a_server_frame(monkeypatch, tmp_path):
    """Run chapter 08's setup and 3-D section as the learner would and save it: the saved outputs
    hold the standalone view (an ``iframe srcdoc``), not a frame on the local server, which is
    blank once the server is gone (every time the saved notebook is opened again)."""
    nbclient = pytest.importorskip("nbclient")
    chapter = nbformat.read(ROOT / "solutions" / "08_quadrotors.ipynb", as_version=4)
    heads = [i for i, c in enumerate(chapter.cells) if c.cell_type == "markdown"]
    at = lambda text: next(i for i in heads if text in chapter.cells[i].source)  # noqa: E731
    setup = [c for c in chapter.cells[at("## Setup"):at("## Section 1")] if c.cell_type == "code"]
    section = [c for c in chapter.cells[at("## Section 5"):at("## Summary")] if c.cell_type == "code"]
    assert any("LiveViewer" in c.source for c in section), "expected the live viewer in the 3-D section"
    part = nbformat.v4.new_notebook(cells=setup + section, metadata=chapter.metadata)
    monkeypatch.setenv("MASP_LITE_FAST", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the kernel's own temp folder (tests/test_notebooks.py)
    nbclient.NotebookClient(part, timeout=300, resources={"metadata": {"path": str(ROOT)}}).execute()
    saved = nbformat.reads(nbformat.writes(part), as_version=4)          # what a saved notebook holds
    html = [value for cell in saved.cells for out in cell.get("outputs", [])
            for key, value in out.get("data", {}).items() if key == "text/html"]
    assert any(h.startswith("<div><iframe srcdoc=") for h in html)         # the embedded standalone view
    assert not [h for h in html if SERVER_FRAME.search(h)], "a saved output frames the local meshcat server"
    assert SERVER_FRAME.search('<iframe src="http://127.0.0.1:7000/static/"></iframe>')  # the pattern does catch one


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


def test_twenty_drones_read_from_the_default_camera_and_animations_stay_in_reach(episode):
    from masp_lite.envs import get_scenario

    assert meshcat3d.drone_scale(get_scenario("drone-5")) == 1.0
    assert meshcat3d.drone_scale(get_scenario("drone-20")) == 2.0
    page = meshcat3d.episode_html(episode)
    assert "drawn" not in page.split('id="masp-key"')[1].split("</div>")[0]   # drone-5: to scale
    # the Scene tree folds and the Animations panel opens once every command is applied; the panel scrolls
    assert "Promise.all(sent)" in page and "f.Scene.close()" in page and "f.Animations.open()" in page
    assert ".dg.main>ul{max-height:calc(100vh - 20px);overflow-y:auto}" in page   # the list scrolls, the button stays
    big = dict(episode, scenario=get_scenario("drone-20"))
    assert "drones drawn 2× their size" in meshcat3d.episode_html(big)


class _Chromium:
    """Headless Chromium driven over its DevTools protocol: real mouse events at page coordinates."""

    def __init__(self, width=900, height=700):
        import json
        import time
        import urllib.request

        websocket = pytest.importorskip("websocket")
        self._json, self._time = json, time
        self.profile = tempfile.TemporaryDirectory()
        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={self.profile.name}", "--remote-debugging-port=0",
             f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = Path(self.profile.name) / "DevToolsActivePort"
        page = None
        for _ in range(600):
            try:
                port = port_file.read_text().split()[0]
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json", timeout=5))
                page = next(t for t in targets if t["type"] == "page")
                break
            except (OSError, IndexError, StopIteration, ValueError):
                time.sleep(0.1)
        assert page is not None, "Chromium's DevTools endpoint did not come up"
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=120, suppress_origin=True)
        self.n = 0

    def send(self, method, **params):
        self.n += 1
        self.ws.send(self._json.dumps({"id": self.n, "method": method, "params": params}))
        while True:
            msg = self._json.loads(self.ws.recv())
            if msg.get("id") == self.n:
                assert "error" not in msg, msg["error"]
                return msg.get("result", {})

    def js(self, expr):
        out = self.send("Runtime.evaluate", expression=expr, returnByValue=True, awaitPromise=True)
        assert "exceptionDetails" not in out, out["exceptionDetails"]
        return out["result"].get("value")

    def wait_for(self, expr, seconds=60.0):
        for _ in range(int(seconds * 10)):                  # false while the page (or its frame) still loads
            value = self.js(f"(() => {{ try {{ return ({expr}); }} catch (e) {{ return false; }} }})()")
            if value:
                return value
            self._time.sleep(0.1)
        raise AssertionError(f"timed out waiting for {expr}")

    def click(self, x, y):
        for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

    def close(self):
        self.ws.close()
        self.proc.terminate()
        self.proc.wait(timeout=30)
        self.profile.cleanup()


# the replay as seen from the page that holds it: the page itself, or the iframe of a notebook's output
_REPLAY = {"page": "window", "output": "document.querySelector('iframe').contentWindow"}


def _replay_again_by_clicking(browser, where):
    """Click meshcat's "Open Controls", open "Animations" if folded, click "play": where each click lands
    is what a person's mouse would hit (``elementFromPoint``), not a script calling the button."""
    win = _REPLAY[where]
    browser.wait_for(f"(() => {{ const v = {win}.viewer; return v && v.animator && v.animator.duration > 0 "
                     f"&& !v.animator.playing; }})()")                         # the replay ran once and stopped
    target = ("(text, selector) => {{ const w = {win}, d = w.document, f = w.frameElement;"
              " const e = [...d.querySelectorAll(selector)].find(e => e.textContent.trim() === text);"
              " if (!e) return null;"
              " const r = e.getBoundingClientRect(), o = f ? f.getBoundingClientRect() : {{x: 0, y: 0}};"
              " const x = o.x + r.x + r.width / 2, y = o.y + r.y + r.height / 2;"
              " let hit = document.elementFromPoint(x, y);"
              " if (f && hit === f) hit = d.elementFromPoint(r.x + r.width / 2, r.y + r.height / 2);"
              " return {{x, y, hit: hit === e || e.contains(hit), visible: r.width > 0 && r.height > 0}};"
              " }}").format(win=win)
    where_is = lambda text, selector: browser.js(f"({target})({text!r}, {selector!r})")  # noqa: E731
    button = where_is("Open Controls", ".dg .close-button")
    assert button and button["visible"] and button["hit"], f"{where}: 'Open Controls' cannot be clicked: {button}"
    browser.click(button["x"], button["y"])
    browser.wait_for(f"!{win}.document.querySelector('.dg.main > ul').classList.contains('closed')", 10)
    folder = where_is("Animations", ".dg li.title")
    assert folder and folder["visible"] and folder["hit"], f"{where}: 'Animations' cannot be clicked: {folder}"
    if browser.js(f"{win}.viewer.gui.__folders.Animations.closed"):
        browser.click(folder["x"], folder["y"])
    play = where_is("play", ".dg .property-name")
    assert play and play["visible"] and play["hit"], f"{where}: the Animations panel's 'play' cannot be clicked: {play}"
    before = browser.js(f"{win}.viewer.animator.time")
    browser.click(play["x"], play["y"])
    assert browser.wait_for(f"{win}.viewer.animator.playing", 10), f"{where}: the replay did not start again"
    browser.wait_for(f"{win}.viewer.animator.time !== {before!r}", 10)      # and it moves


@pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed (Debian: apt-get install chromium)")
def test_replay_controls_are_clicked_open_in_headless_chromium(episode, tmp_path):
    """The key says "replay: Open Controls → Animations → play": do it with the mouse, on a standalone
    page (``play --out``) and on a notebook's saved output (chapters 08 and 11 embed the page in an
    iframe). A page rule once clipped the closed controls to zero height, so a click at the button
    landed on the canvas."""
    page = tmp_path / "drones.html"
    page.write_text(meshcat3d.episode_html(episode))
    output = tmp_path / "output.html"
    output.write_text("<!DOCTYPE html><html><body><p>a notebook cell's output:</p>"
                      + meshcat3d.notebook_html(episode).data + "</body></html>")
    browser = _Chromium()
    try:
        browser.send("Page.enable")
        for where, path in (("page", page), ("output", output)):
            browser.send("Page.navigate", url=path.as_uri())
            _replay_again_by_clicking(browser, where)
    finally:
        browser.close()
