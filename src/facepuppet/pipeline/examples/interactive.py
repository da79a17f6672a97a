"""Key expressions captured live from a camera: the performer copies each key-model shown and presses a key."""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.performer import Performer
from facepuppet.pipeline.examples.checks import make_performer
from facepuppet.pipeline.examples.config import NEUTRAL, ExamplesConfig
from facepuppet.pipeline.examples.window import steadiest_window
from facepuppet.pipeline.tracking import tracker_kwargs

__all__ = ["from_camera", "window_key_source", "KeySource", "CAPTURE_KEYS", "CANCEL_KEYS", "PICTURE_SIZE"]

#: Keys that capture the current expression (space, enter) and that cancel (q, Esc).
CAPTURE_KEYS = (ord(" "), 13, 10)
CANCEL_KEYS = (ord("q"), 27)
#: Side in pixels of the rendered picture of a key-model.
PICTURE_SIZE = 360

KeySource = Callable[[int, np.ndarray], int]
"""Called once per camera frame with (frame index, the picture shown); returns a key code or -1."""


def window_key_source(title: str = "facepuppet calibrate") -> KeySource:
    """Show the picture in an OpenCV window and read the keyboard; a clear error when there is no display."""
    import sys

    import cv2

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise FacepuppetError("camera:N needs a display to show the key expressions, and none is available "
                              "(DISPLAY is not set); capture them from a recorded video with --marks or --auto")

    def show(k: int, picture: np.ndarray) -> int:
        try:
            cv2.imshow(title, cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))
            return int(cv2.waitKey(1))
        except cv2.error as e:
            raise FacepuppetError("camera:N cannot open a window (OpenCV was built without a GUI, as "
                                  "opencv-python-headless is); capture the key expressions from a recorded "
                                  "video with --marks or --auto") from e

    return show


def _prompt_picture(frame: np.ndarray, picture: np.ndarray | None, title: str, hint: str) -> np.ndarray:
    """The camera frame (H, W, 3) beside the key-model's picture, with a title above and a hint below."""
    import cv2

    from facepuppet.export.preview import side_by_side

    h = frame.shape[0]
    if picture is None:
        picture = np.full((h, h // 2, 3), 40, np.uint8)
    out = side_by_side(frame, picture).copy()
    for y, text, scale in ((30, title, 0.8), (h - 15, hint, 0.5)):
        cv2.putText(out, text, (10, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(out, text, (10, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def _key_model_renderer(character) -> Callable[[str], np.ndarray]:
    """A function from a key-model's name (``neutral`` included) to its rendered picture (S, S, 3) uint8."""
    from facepuppet.export.render import Camera, render_mesh

    size = (PICTURE_SIZE, PICTURE_SIZE)
    camera = Camera.fit(character.neutral, size, margin=0.12)
    index = {n: i for i, n in enumerate(character.names)}

    def render(name: str) -> np.ndarray:
        verts = character.neutral if name == NEUTRAL else character.targets[index[name]]
        if character.faces is None:
            return np.full((*size, 3), 40, np.uint8)
        return render_mesh(verts, character.faces, camera=camera)

    return render


def from_camera(camera: str, character, *, config: ExamplesConfig | None = None,
                keys: KeySource | None = None, render: Callable[[str], np.ndarray] | None = None) -> Performer:
    """Capture the key expressions live: the performer copies each key-model shown and presses a key.

    The neutral face comes first, then each key-model of ``character`` in turn. For each, the camera frame
    (with its name) is shown beside a rendered picture of the key-model; space or enter captures it (the
    points of the steadiest ``config.window`` frames among the next ``2 * window`` valid ones are averaged),
    q or Esc cancels.

    Parameters
    ----------
    camera : str
        ``camera:N`` (device N), or ``camera:VIDEO`` with a video standing in for the device.
    character : Character
        The character whose key-models are shown.
    config : ExamplesConfig, optional
    keys : KeySource, optional
        Where key presses come from; by default an OpenCV window (which needs a display).
    render : callable name -> (H, W, 3) uint8, optional
        Picture of a key-model (``neutral`` included); by default rendered with
        :func:`facepuppet.export.render.render_mesh`.
    """
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.io.frames import open_media

    config = config or ExamplesConfig()
    keys = keys or window_key_source()
    render = render or _key_model_renderer(character)
    todo = [NEUTRAL, *character.names]
    pictures: dict[str, np.ndarray] = {}
    captured: dict[str, np.ndarray] = {}
    frames: dict[str, tuple[int, int]] = {}
    tracker = make_tracker(config.tracker.backend, **tracker_kwargs(config.tracker))
    point_names = None
    try:
        with open_media(camera) as src:
            step_ms = 1000.0 / src.fps
            buffer: list[np.ndarray] = []
            start = None
            for k, rgb in enumerate(src):
                if not todo:
                    break
                name = todo[0]
                feats = tracker.track(rgb, int(round(k * step_ms)))
                if point_names is None:
                    point_names = getattr(tracker, "point_names", None)
                if start is not None:                       # collecting after a key press
                    if feats.valid:
                        buffer.append(np.asarray(feats.points, dtype=float))
                    if len(buffer) >= 2 * config.window or k - start > 4 * config.window + 10:
                        if not buffer:
                            raise FacepuppetError(f"{camera}: no face was tracked while capturing {name}")
                        pts = np.stack(buffer)
                        span = steadiest_window(pts, np.ones(len(pts), bool), len(pts) // 2, len(pts),
                                                config.window) or (0, len(pts))
                        captured[name] = pts[span[0]:span[1]].mean(axis=0)
                        frames[name] = (start + span[0], start + span[1])
                        todo.pop(0)
                        buffer, start = [], None
                    continue
                if name not in pictures:
                    pictures[name] = render(name)
                status = "face found" if feats.valid else "no face"
                shown = _prompt_picture(rgb, pictures[name], f"{name} ({len(captured) + 1}/"
                                        f"{len(character.names) + 1})",
                                        f"copy the face, press space ({status}); q quits")
                key = keys(k, shown)
                if key in CANCEL_KEYS:
                    raise FacepuppetError("capturing the key expressions cancelled; nothing was written")
                if key in CAPTURE_KEYS:
                    start = k
    finally:
        tracker.close()
    if todo:
        raise FacepuppetError(f"{camera}: the camera stopped before every key expression was captured "
                              f"(missing {', '.join(todo)})")
    names = tuple(character.names)
    from facepuppet.capture.curves import POINT_NAMES

    return make_performer(captured[NEUTRAL], np.stack([captured[n] for n in names]), names,
                          point_names or POINT_NAMES, frames, config)
