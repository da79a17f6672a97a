"""The viewer page in a real headless Chromium: the morph influences the page applies equal the weights
streamed, frame by frame, and the head rotation too; the neutral button reaches the server; a screenshot."""

from __future__ import annotations

import importlib.util
import math
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from live_helpers import grid_character, live_frame, require

require("websockets", 'the live extra is not installed (pip install "facepuppet[live]")')

from chromium_driver import ensure_chromium, start_driver, stop_driver  # noqa: E402

from facepuppet.io.character import Character  # noqa: E402
from facepuppet.live import ViewerServer  # noqa: E402

SCREENSHOT_COPY = Path("/tmp/live-viewer.png")


def root_conftest(request):
    # tests/conftest.py is registered under its path; take its need() (skip, or fail in CI) and assets_dir()
    return request.config.pluginmanager.get_plugin(str(Path(__file__).resolve().parents[1] / "conftest.py"))


@pytest.fixture(scope="module")
def driver(request):
    need = root_conftest(request).need
    need(importlib.util.find_spec("selenium") is not None, "selenium (the dev extra) is not installed")
    reason = ensure_chromium()
    need(reason is None, reason or "")
    d = start_driver()
    yield d
    stop_driver(d)


def face_character(request) -> Character:
    """The ICT-FaceKit face when the shared assets are there, else a small synthetic mask."""
    path = root_conftest(request).assets_dir() / "ict-facekit" / "ict_face_light.npz"
    if not path.is_file():
        return grid_character()
    with np.load(path) as d:
        neutral = d["neutral"].astype(float)
        return Character(neutral=neutral, targets=neutral[None] + d["expr_deltas"],
                         names=tuple(str(n) for n in d["expr_names"]), faces=d["faces"], name="ICT-FaceKit")


def yaw_pitch(yaw_deg, pitch_deg):
    a, b = math.radians(yaw_deg), math.radians(pitch_deg)
    ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    return ry @ rx


def camera_picture(k):
    """A 320x240 stand-in for the camera: a gradient and a disc that moves with k."""
    y, x = np.mgrid[0:240, 0:320]
    img = np.stack([x * 255 // 320, y * 255 // 240, np.full_like(x, 90)], axis=2).astype(np.uint8)
    img[(x - 100 - 5 * k) ** 2 + (y - 120) ** 2 < 900] = (240, 200, 170)
    return img


CURVES = np.array([[[100, 170], [130, 190], [190, 190], [220, 170]],
                   [[100, 170], [130, 150], [190, 150], [220, 170]]], dtype=float)


def wait_for(driver, script, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for: {script}")


def test_page_applies_the_streamed_weights(driver, request, tmp_path):
    character = face_character(request)
    names = character.names
    server = ViewerServer(character, "127.0.0.1", 0)
    try:
        driver.get(server.url)
        wait_for(driver, "return window.__facepuppet.ready && window.__facepuppet.connected")
        hook = driver.execute_script("return window.__facepuppet")
        assert hook["error"] is None and hook["names"] == list(names)
        rng = np.random.default_rng(7)
        sent = {}
        for i in range(30):
            w = rng.uniform(0, 1, len(names)) * (rng.uniform(size=len(names)) < 0.3)
            head = yaw_pitch(rng.uniform(-25, 25), rng.uniform(-10, 10))
            sent[i] = (w, head)
            server.send(live_frame(names, w, index=i, head=head, image=camera_picture(i), curves=CURVES))
            wait_for(driver, f"return window.__facepuppet.lastApplied === {i}")
        # a clear expression for the screenshot
        final = np.zeros(len(names))
        for n, v in (("jawOpen", 0.35), ("mouthSmile_L", 0.9), ("mouthSmile_R", 0.9), ("eyeBlink_L", 0.2),
                     ("browInnerUp_L", 0.5), ("browInnerUp_R", 0.5)):
            if n in names:
                final[list(names).index(n)] = v
        sent[30] = (final, yaw_pitch(18, -6))
        server.send(live_frame(names, final, index=30, head=sent[30][1], image=camera_picture(30), curves=CURVES))
        wait_for(driver, "return window.__facepuppet.lastApplied === 30")
        wait_for(driver, "return window.__facepuppet.pictures > 0")
        applied = driver.execute_script("return window.__facepuppet.applied")
        by_index = {a["i"]: a for a in applied}
        assert sorted(by_index) == list(range(31))  # every frame applied (each was waited for)
        for i, (w, head) in sent.items():
            np.testing.assert_allclose(by_index[i]["w"], w.astype(np.float32), rtol=1e-7, atol=0,
                                       err_msg=f"frame {i}")
            np.testing.assert_allclose(by_index[i]["h"], head.ravel(), rtol=1e-12, atol=1e-15)
        # the neutral button reaches the server
        driver.find_element("id", "neutral").click()
        deadline = time.monotonic() + 10
        while not server.neutral_requested():
            assert time.monotonic() < deadline, "the neutral press did not arrive"
            time.sleep(0.02)
        time.sleep(0.3)  # let the picture and the bars paint
        shot = tmp_path / "viewer.png"
        assert driver.save_screenshot(str(shot))
        shutil.copyfile(shot, SCREENSHOT_COPY)
        # the character is drawn: the 3D view is not a blank clear colour
        pixels = driver.execute_script("""
            const c = document.getElementById('view'), gl = c.getContext('webgl2');
            const px = new Uint8Array(4 * c.width * c.height);
            gl.readPixels(0, 0, c.width, c.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
            let lit = 0; for (let k = 0; k < px.length; k += 4) if (px[k] > 60) lit++;
            return lit / (c.width * c.height);""")
        assert pixels > 0.05
        assert driver.execute_script("return window.__facepuppet.error") is None
    finally:
        server.close()
