"""The built-in demo: the whole chain on a digital performer, with ground truth, no data, network or camera.

Steps of :func:`run_demo` (each timed in :attr:`DemoResult.timings`):

1. Render the digital performer (:mod:`facepuppet.demo.performer`) acting the calibration script (neutral, each
   key expression held, then the neutral face with the head turning, nodding and tilting) and a performance
   with head motion (:mod:`facepuppet.demo.script`); write both videos and the calibration's marks file, whose
   last line is the head-motion span.
2. Track both videos with the tracker of :data:`TRACKERS` chosen in :class:`DemoConfig`:

   - ``color`` (:data:`DEFAULT_TRACKER`): the paper's colour tracker, after its performer profile is trained
     (§3.1) on every calibration frame, head sweep included, labelled with the performer's true curves (as
     the landmark backend labels a real performer's). It runs without the optional landmark model whatever
     the environment names, so the result is the same on every machine; its kernels are compiled by worker
     processes while the performer is rendered;
   - ``mediapipe``: the landmark backend (its model from :attr:`DemoConfig.model` or
     ``$FACEPUPPET_FACE_LANDMARKER``); a missing package or model is a :class:`~facepuppet.FacepuppetError`
     raised before anything is rendered;
   - ``truth``: :class:`TruthTracker`, the performer's true image curves through the same head-pose solve and
     back-projection onto the generic face as every tracker, a check of the chain without image analysis.
3. Make the key expressions from the calibration marks (as ``facepuppet calibrate --marks``; the head-motion
   span becomes the performer's nuisance, which the mapping discounts), pair them with the stylised Toy
   (:mod:`facepuppet.demo.toy`) and fit the rig (as ``facepuppet rig``).
4. Animate the Toy from the performance (as ``facepuppet animate``): GLB, CSV, side-by-side preview; draw the
   tracked curves and head axes on the performance (overlay).
5. Score against the ground truth: the Toy posed with the script's own weights.

Files (:data:`FILES`): ``calibration.mp4``, ``calibration-marks.csv``, ``performer-profile.npz`` (``color``
only), ``performer.npz``, ``toy.glb``, ``rig.npz``, ``performance.mp4``, ``track.npz``, ``overlay.mp4``,
``animation.glb``, ``animation.csv``, ``preview.mp4`` (unless ``preview=False``).

Error (:attr:`DemoResult.error`, printed by ``facepuppet demo``): over the frames with an expression (largest
scripted weight at least :data:`EXPRESSIVE`), the mean relative vertex error
``||V_pred - V_true|| / ||V_true - T_B||`` (Frobenius norms over all vertices of the Toy, T_B its neutral).
0 is perfect; 1 is as far off as showing the neutral face throughout. The command prints it beside the bar
of 0.5; :attr:`DemoResult.curve_error` is the median distance in pixels between the tracked and the true
curves' control points. Measured values: ``docs/results.md``.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from facepuppet.capture.features import FrameFeatures

__all__ = ["DemoConfig", "DemoResult", "run_demo", "relative_vertex_error", "EXPRESSIVE", "FILES", "TRACKERS",
           "DEFAULT_TRACKER", "TruthTracker"]

log = logging.getLogger(__name__)

#: A frame counts as showing an expression when its largest scripted weight reaches this.
EXPRESSIVE = 0.2

#: What makes the demo's tracks: name -> what it is (printed by ``facepuppet demo``).
TRACKERS: dict[str, str] = {
    "color": "the colour tracker (profile trained on the calibration video)",
    "truth": "the performer's TRUE image curves standing in for a tracker (no image analysis)",
    "mediapipe": "the landmark backend (MediaPipe Face Landmarker; its model from --model or "
                 "$FACEPUPPET_FACE_LANDMARKER)",
}

#: The demo's tracker unless told otherwise: the paper's colour tracker.
DEFAULT_TRACKER = "color"

#: What the demo writes, and what each file is.
FILES: dict[str, str] = {
    "calibration.mp4": "the performer's calibration video (neutral, each key expression held, then the "
                       "neutral face with the head moving)",
    "calibration-marks.csv": "the marks file: frame of each held expression, span of the head motion",
    "performer-profile.npz": "the colour tracker's performer profile trained on the calibration video",
    "performer.npz": "the performer's key expressions (facepuppet calibrate)",
    "toy.glb": "the Toy character (coloured, with normals) with its 13 key-models as morph targets",
    "rig.npz": "the fitted rig (facepuppet rig)",
    "performance.mp4": "the input video: the performer acting, with head motion",
    "track.npz": "the track of the performance",
    "overlay.mp4": "the performance with the tracked curves and head axes drawn on",
    "animation.glb": "the Toy animated by the performance (morph weights + head rotation)",
    "animation.csv": "the animation's weights, Live Link Face layout",
    "preview.mp4": "input with tracked curves (left) beside the animated Toy (right)",
    "monkey.glb": "the Monkey, rigged on the same key expressions (--monkey)",
    "monkey-animation.glb": "the Monkey animated by the same performance (--monkey)",
    "preview-monkey.mp4": "the same performance on the Monkey: each character keeps its own personality",
}
#: Files written only with ``DemoConfig.monkey``.
MONKEY_FILES = ("monkey.glb", "monkey-animation.glb", "preview-monkey.mp4")


@dataclass(frozen=True, kw_only=True)
class DemoConfig:
    """Options of the demo.

    Attributes
    ----------
    seconds : float
        Length of the performance (at least 4.6 s, so that each key expression gets its turn).
    fps : float
    size : int
        Width and height of the rendered videos in pixels.
    seed : int
        Seed of the performance script (order, timing, head motion).
    tracker : str
        A key of :data:`TRACKERS`.
    preview : bool
        Write the side-by-side preview (the slowest output).
    progress : bool or None
        Progress bars; None shows them on a terminal.
    model : str or None
        The Face Landmarker model of the ``mediapipe`` tracker; None takes ``$FACEPUPPET_FACE_LANDMARKER``.
    monkey : bool
        Also rig the built-in Monkey on the same key expressions and animate it from the same track
        (:data:`MONKEY_FILES`; the error figure is the Toy's).
    """

    seconds: float = 8.0
    fps: float = 30.0
    size: int = 320
    seed: int = 0
    tracker: str = DEFAULT_TRACKER
    preview: bool = True
    progress: bool | None = None
    model: str | None = None
    monkey: bool = False

    def __post_init__(self) -> None:
        if self.tracker not in TRACKERS:
            raise ValueError(f"tracker must be one of {', '.join(TRACKERS)}, got {self.tracker!r}")
        if not (np.isfinite(self.seconds) and self.seconds > 0):
            raise ValueError(f"seconds must be a positive number, got {self.seconds}")


@dataclass(frozen=True)
class DemoResult:
    """What the demo did.

    Attributes
    ----------
    error : float
        Mean relative vertex error against ground truth (module docstring).
    error_per_frame : (F,) float
        The relative error of each frame (NaN where the frame shows no expression).
    frames : int
        Frames of the performance.
    seconds : float
        Wall time of the whole demo.
    tracker : str
        The key of :data:`TRACKERS` that made the tracks.
    timings : dict of str -> float
        Seconds per step.
    files : dict of str -> Path
        What was written.
    coverage : float
        Share of performance frames where the tracker found the face.
    curve_error : float
        Median distance in pixels between the tracked and the true curves' control points (0 for "truth").
    """

    error: float
    error_per_frame: np.ndarray
    frames: int
    seconds: float
    tracker: str = DEFAULT_TRACKER
    timings: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    coverage: float = 1.0
    curve_error: float = 0.0


class TruthTracker:
    """A stand-in tracker that returns the performer's true image curves, frame after frame.

    The curves go through what every backend does with its curves (head pose from the stable end points,
    feature points back-projected onto the generic face, :mod:`facepuppet.capture.pose`), so the track is
    what a perfect 2D tracker would give. The frames themselves are not looked at.

    Parameters
    ----------
    curves : (F, C, 4, 2) float
        True curves of each frame of the video, in order.
    """

    name = "performer-truth"

    def __init__(self, curves: np.ndarray) -> None:
        self._curves = np.asarray(curves, dtype=float)
        self._next = 0
        self._pose = None

    def track(self, rgb: np.ndarray, timestamp_ms: int) -> FrameFeatures:
        from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
        from facepuppet.capture.pose import STABLE_FEATURES, estimate_pose, points_in_head, pose_points_from_curves

        k, self._next = self._next, self._next + 1
        if k >= len(self._curves):
            raise ValueError(f"TruthTracker: the video has more frames than the {len(self._curves)} curves given")
        curves = self._curves[k]
        size = rgb.shape[1::-1]
        pose = estimate_pose(pose_points_from_curves(curves, STABLE_FEATURES), size, previous=self._pose)
        self._pose = pose if pose else None
        if not pose:
            return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))
        return FrameFeatures(True, curves, pose.rotation, pose.translation, points_in_head(curves, pose))

    def close(self) -> None:
        """Nothing to release."""


def relative_vertex_error(pred: np.ndarray, true: np.ndarray, neutral: np.ndarray,
                          expressive: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """Mean over expressive frames of ``||pred - true|| / ||true - neutral||``.

    Parameters
    ----------
    pred, true : (F, V, 3) float
    neutral : (V, 3) float
    expressive : (F,) bool, optional
        Frames to score; by default those where ``true`` differs from ``neutral``.

    Returns
    -------
    (mean, per_frame) : float, (F,) float with NaN on frames not scored.
    """
    num = np.linalg.norm((pred - true).reshape(len(pred), -1), axis=1)
    den = np.linalg.norm((true - neutral[None]).reshape(len(true), -1), axis=1)
    use = den > 0 if expressive is None else np.asarray(expressive, bool) & (den > 0)
    per = np.full(len(pred), np.nan)
    per[use] = num[use] / den[use]
    return (float(np.mean(per[use])) if use.any() else float("nan")), per


def _write_video(path: Path, frames: np.ndarray, fps: float) -> None:
    from facepuppet.export.preview import open_preview

    with open_preview(path, fps, frames.shape[2:0:-1]) as out:
        for f in frames:
            out.write(f)


def _write_marks(path: Path, marks: dict[str, int], spans: dict[str, tuple[int, int]]) -> None:
    from facepuppet._util.atomic import atomic_path

    lines = ["# frame,name  (written by facepuppet demo; times may also be given as 1.5s or 00:01.5)"]
    lines += [f"{frame},{name}" for name, frame in sorted(marks.items(), key=lambda kv: kv[1])]
    lines += [f"{a}-{b},{name}" for name, (a, b) in spans.items()]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _monkey(files: dict, performer, track, config: DemoConfig) -> None:
    """The Monkey rigged on the performer's key expressions and animated from the same track."""
    from facepuppet._util.atomic import atomic_path
    from facepuppet.demo.monkey import monkey_character, monkey_colors
    from facepuppet.io.gltf import colored_glb
    from facepuppet.pipeline.animate import AnimateConfig, animate
    from facepuppet.pipeline.rig import fit_rig
    from facepuppet.pipeline.tracking import TrackerOptions

    monkey = monkey_character()
    monkey = replace(monkey, source=colored_glb(monkey, monkey_colors()))
    with atomic_path(files["monkey.glb"]) as tmp:
        tmp.write_bytes(monkey.source)
    rig, _ = fit_rig(performer, monkey)
    animate(files["performance.mp4"], rig, glb=files["monkey-animation.glb"], preview=files.get("preview-monkey.mp4"),
            track=track, colors=monkey_colors(), config=AnimateConfig(tracker=TrackerOptions(progress=config.progress)))


def run_demo(folder: str | os.PathLike = "facepuppet-demo", config: DemoConfig | None = None) -> DemoResult:
    """Run the demo, writing :data:`FILES` into ``folder`` (created if needed).

    The colour tracker's profile is written only when ``config.tracker == "color"``, the preview only when
    ``config.preview``.

    Returns
    -------
    DemoResult
    """
    from facepuppet.capture.tracking import track_media
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import calibration_script, performance_script
    from facepuppet.demo.toy import toy_character, toy_colors
    from facepuppet.export.overlay import write_overlay_video
    from facepuppet.io.gltf import colored_glb
    from facepuppet.io.performer import load_performer, save_performer
    from facepuppet.io.track import save_track
    from facepuppet.pipeline.animate import AnimateConfig, animate
    from facepuppet.pipeline.examples import ExamplesConfig, from_marks
    from facepuppet.pipeline.rig import fit_rig, save_rig
    from facepuppet.pipeline.tracking import TrackerOptions

    config = config or DemoConfig()
    if config.tracker == "mediapipe":   # a missing package or model is told before anything is rendered
        from facepuppet.capture.landmarks import MediaPipeTracker

        MediaPipeTracker(config.model).close()
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    files = {name: out / name for name in FILES}
    if config.tracker != "color":
        files.pop("performer-profile.npz")
    if not config.preview:
        files.pop("preview.mp4")
        files.pop("preview-monkey.mp4")
    if not config.monkey:
        for name in MONKEY_FILES:
            files.pop(name, None)
    timings: dict[str, float] = {}
    progress = config.progress is not False
    t_start = time.perf_counter()

    def step(name: str, t0: float) -> float:
        now = time.perf_counter()
        timings[name] = timings.get(name, 0.0) + now - t0
        return now

    t = time.perf_counter()
    if config.tracker == "color":
        from facepuppet.capture.color.precompile import precompile

        # The tracker's kernels compile in other processes while the performer is rendered (on a fresh
        # machine; later they load from numba's cache). The profile's shape models read the lips, brows and
        # eyes, so only the eyes' rules (which profile training runs) and the rest of a frame's work are needed.
        kernels = precompile(tasks=("eyes", "frame"))
    size = (config.size, config.size)
    cal = calibration_script(fps=config.fps)
    perf = performance_script(config.seconds, config.fps, seed=config.seed)
    cal_frames, cal_curves = render_performer(cal, size=size)
    perf_frames, perf_curves = render_performer(perf, size=size, rng=np.random.default_rng(config.seed + 1))
    t = step("render", t)
    _write_video(files["calibration.mp4"], cal_frames, cal.fps)
    _write_video(files["performance.mp4"], perf_frames, perf.fps)
    _write_marks(files["calibration-marks.csv"], cal.marks, cal.spans)
    del perf_frames
    t = step("write videos", t)

    if config.tracker == "color":
        from facepuppet.capture.color.config import ColorTrackerConfig, LandmarkConfig
        from facepuppet.capture.color.profile import save_profile
        from facepuppet.capture.color.tracker import ColorTracker
        from facepuppet.capture.color.train import train_profile

        # Without the optional landmark model, whatever the environment names (with it the tracker would
        # place its first eye anchors on MediaPipe's eyes): the demo's result is the same on every machine.
        options = ColorTrackerConfig(landmarks=LandmarkConfig(enabled=False, anchor_calibration=0.0))
        profile = train_profile(list(cal_frames), cal_curves, name="demo performer", progress=False,
                                config=options)
        kernels.wait()
        save_profile(files["performer-profile.npz"], profile)
        t = step("train profile", t)

        def tracker(_curves):
            return ColorTracker(profile, config=options)
    elif config.tracker == "mediapipe":
        from facepuppet.capture.landmarks import MediaPipeTracker

        def tracker(_curves):
            return MediaPipeTracker(config.model)
    else:
        tracker = TruthTracker
    del cal_frames

    def track_video(path: Path, curves: np.ndarray):
        t = tracker(curves)
        try:
            return track_media(path, t, progress=progress)
        finally:
            t.close()

    cal_track = track_video(files["calibration.mp4"], cal_curves)
    t = step("track", t)
    toy = toy_character()
    toy = replace(toy, source=colored_glb(toy, toy_colors()))  # materials: the animated GLB is the Toy's scene
    examples = from_marks(files["calibration.mp4"], files["calibration-marks.csv"], names=toy.names,
                          config=ExamplesConfig(), track=cal_track)
    save_performer(files["performer.npz"], examples)
    rig, _pairing = fit_rig(load_performer(files["performer.npz"]), toy)
    save_rig(files["rig.npz"], rig)
    from facepuppet._util.atomic import atomic_path

    with atomic_path(files["toy.glb"]) as tmp:
        tmp.write_bytes(toy.source)
    t = step("calibrate + rig", t)

    track = track_video(files["performance.mp4"], perf_curves)
    save_track(files["track.npz"], track)
    t = step("track", t)
    anim = animate(files["performance.mp4"], rig, glb=files["animation.glb"], csv=files["animation.csv"],
                   preview=files.get("preview.mp4"), track=track, colors=toy_colors(),
                   config=AnimateConfig(tracker=TrackerOptions(progress=config.progress)))
    t = step("animate + preview" if config.preview else "animate", t)
    if config.monkey:
        _monkey(files, load_performer(files["performer.npz"]), track, config)
        t = step("monkey", t)
    write_overlay_video(files["overlay.mp4"], files["performance.mp4"], track)
    t = step("overlay", t)

    neutral = np.asarray(toy.neutral, dtype=float)
    deltas = toy.targets - neutral[None]
    true_w = perf.weights
    pred_w = rig.character_weights(anim.weights)
    true_v = neutral[None] + np.einsum("fk,kvd->fvd", true_w, deltas)
    pred_v = neutral[None] + np.einsum("fk,kvd->fvd", pred_w, deltas)
    error, per_frame = relative_vertex_error(pred_v, true_v, neutral, true_w.max(axis=1) >= EXPRESSIVE)
    curve_error = float(np.nanmedian(np.linalg.norm(track.curves - perf_curves, axis=-1)))
    step("score", t)
    return DemoResult(error, per_frame, perf.n_frames, time.perf_counter() - t_start, config.tracker, timings,
                      files, float(np.mean(track.valid)), curve_error)
