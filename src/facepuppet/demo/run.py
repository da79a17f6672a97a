"""The built-in demo: the whole chain on a digital performer, with ground truth, no data, network or camera.

1. Render the digital performer (:mod:`facepuppet.demo.performer`) acting the calibration script (neutral, then
   each key expression held, then the neutral face with the head moving) and a performance with head motion
   (:mod:`facepuppet.demo.script`); write both videos.
2. Track both videos (:data:`TRACKERS`): with the colour tracker, whose performer profile is first trained on
   every calibration frame, head sweep included, labelled with the performer's true curves (§3.1; its shape
   models need the sweep: trained on the still frames only they gave 0.75 instead of 0.41, while without
   shape models the sweep frames made the rules' curves worse, 2.5 px from the true ones instead of 1.9);
   with the MediaPipe backend; or with the performer's true image curves standing in for a tracker (the
   same head-pose solve and back-projection onto the generic face as every tracker, from curves that are
   exact).
3. Make the key expressions from the calibration marks (``facepuppet calibrate --marks``; the head-motion span
   becomes the performer's nuisance, which the mapping discounts), pair them with the stylised Toy
   (:mod:`facepuppet.demo.toy`) and fit the rig (``facepuppet rig``).
4. Animate the Toy from the performance (``facepuppet animate``): GLB, CSV, overlay, side-by-side preview.
5. Compare with the ground truth: the Toy posed with the script's own weights.

Error: for each frame with an expression (its largest scripted weight at least :data:`EXPRESSIVE`), the
relative vertex error ``||V_pred - V_true|| / ||V_true - T_B||`` (Frobenius norms over all vertices), averaged.
0 is perfect; 1 is as far off as showing the neutral face.

Which tracker is the default (:data:`DEFAULT_TRACKER`): measured with ``benchmarks/eval_demo_color.py`` on
this performer (320 px frames, 8 s, seeds 0, 1, 2), the colour tracker's error is 0.68, 0.67 and 0.77 (mean
0.71 on 2026-11-30 with the calibration's head-motion span, which the mapping discounts; 0.98 without it),
above the bar of 0.5; MediaPipe's is 0.43 (0.63 without the span), the true curves' 0.14 (0.12). The
head-motion span was measured first on cached tracks: a separate 8 s clip of the neutral face with the head
moving, tracked, its displacements' covariance used as the mapping's nuisance (``nuisance_floor`` 1e-3 there:
colour 0.72; projecting out the first 8 of its principal directions instead: 0.73). Tried beside it and
not adopted: aligning each frame's points on the neutral ones by a 2D similarity first (colour 0.66, but on
the real clips the colour tracker's correlations with MediaPipe's scores fell, performer_a jaw 0.88 to 0.66,
performer_c smile 0.89 to 0.23, and on the ICT yardstick 0.649 to 0.660); a sparsity prior on the weights
(an L1 term growing with the frame's residual noise: MediaPipe 0.43 and colour 0.75 without the span, but
worse on every kind of ICT scene, 1.21 to 1.56 times the source-oracle, and performer_c's colour smile fell
from 0.89 to -0.03). With the span in place, the colour tracker's own curve filter costs most of what is
left: without it (``ColorTrackerConfig(smoothing=False)``) the error is 0.61, with a three times faster
curve filter 0.65 (lag: the tracked curves match the true ones best one frame later); the tracker's
resolution does not (``px`` 72: 0.78; rendering at 640 px with ``px`` 96 before the span: 0.88-1.06).

Where the colour tracker's error came from before the head-motion span (measured on those seeds, swapping
parts of its track for the truth, with the tracker as it was before its brow tilt and lower-lip rules, when
the error was 0.88):

- its curves are about 1.9 px (median) from the true ones, brows 1.6, lids 1.4, lips 2.3, nostrils 2.3; as
  large as the motion the expressions give the feature points (rms about 0.2-0.4 cm, 2-4 px). Any one family
  tracked by colour with the rest true already gives 0.36-0.45 (brows 0.45, outer lips 0.43, lids and inner
  lips 0.36): the mapping turns small errors into weights on every key-model (the true curves plus white
  noise of 0.5, 1 and 2 px give 0.29, 0.43 and 0.65), and the key expressions' examples carry the tracker's
  errors too (in the calibration's blink the lips move 0.5 cm in head coordinates where they stand still);
- the eye corners and nostrils, the head pose's stable points, are not measured but placed with the layout by
  the face frame, a similarity aligned on the eye centres. It cannot show a turn of the head (solved freely,
  the yaw varied by 0.5-1.4 degrees where the true one varies by 6, and against it: the colour tracker now
  holds yaw and pitch at zero), and it jumps when the lids close or the brows lower (the nostrils 4-5 px off
  in the calibration's blink and brow-down): the pose is about 7 degrees off (median). With the true pose
  the error is 0.77; with the true stable points 0.66 (eye corners alone 0.78, nostrils alone 0.75).
  Measuring the nostrils on their dark pixels (1.2 px from the true ones) made it
  worse, 0.94 (0.88 without): the pitch rests on the nose's height under the eyes, and with the nose base
  about 0.9 cm proud of the eye corners a pixel of it is several degrees; smoothing that measurement lagged
  the head (1.09).

Measured again on 2026-11-30 (``benchmarks/eval_demo_color.py`` and scripts on the same seeds):

- the MediaPipe landmark backend (``tracker="mediapipe"``) on the same videos gives 0.58, 0.69 and 0.62: the
  bar asks the colour tracker to beat it. Its points wander less from the true ones than the colour
  tracker's (RMS, head coordinates, constant offset removed; brows 0.8 against 1.1 mm, outer lips 1.1
  against 2.0 mm, where the expressions move them 1.3 and 2.2 mm), except on the lids (0.7 against 0.5 mm);
- the head pose is badly conditioned at this scale (1 cm is about 10 px): the whole yaw range of the
  performance (about 11 degrees each way) moves the nose base under 2 px against the eye corners, and the
  colour tracker's nose points wander 1.9-2.3 px (MediaPipe's 0.8-1.1, its eye corners 0.75 against 1.6).
  With every curve true, 0.5 px of white noise on the seven points the pose is solved from already gives
  0.32, 1 px 0.47 (slowly varying noise: 0.39 and 0.56); with every curve true but the colour tracker's
  nostrils, 0.72; with the true pose and the colour tracker's curves, 0.83. Profiling the six directions in
  which a pose error moves the back-projected points out of the mapping brings the 1 px case to 0.21 and
  MediaPipe to 0.50, but the colour tracker stays at 1.0, as it does when the pose is solved from all 48
  points on the performer's own expression model (MediaPipe 0.53): its lips and brows must improve too;
- without head motion the colour tracker gives 0.71 (seed 0, against 0.85);
- the calibration video mapped back onto itself (weights not smoothed) gives 0.38 with the colour tracker,
  0.00 with the true curves: between the neutral face and a held key, the tracked points do not move along
  the line to the key's example, so onsets read as other keys (brows lowering read as mouthRollLower, the
  inner brows rising as eyeWide at 0.8, with the true pose too);
- tried and worse or no better: mapping each region (brows, eyes, mouth) on its own points (1.4-1.8);
  profiling a rigid motion of all points out of the mapping (colour 0.97; MediaPipe 0.52, but on the real
  clips it lowered the colour tracker's correlations, jaw of clip a 0.86 to 0.62); a ridge regression of the
  curves from the whole face crop learnt on the calibration frames (curves 1.4 to 1.1 px, error 0.92 to 0.91);
  a calibration video with head motion (1.09); low-passing the head rotation (1.25); the true per-coordinate
  noise as the mapper's point scale (0.97); rendering at 480 px (seed 0: 0.87 against 0.85, the curve errors
  grow with the face); ridge regressions of the brows or lips from patches learnt on the calibration
  frames (their curves 1.8 to 1.2 px, the error unchanged while the pose is off).

Since its profile learnt the lips and each brow from the look of the face crop
(:mod:`facepuppet.capture.color.shape_models`), the colour tracker is under the bar (0.405, 0.419, 0.411 on seeds
0-2; 0.408, 0.374, 0.465 on seeds 3-5; its curves 1.0 px from the true ones instead of 1.9) and the demo's
default; the true curves remain a choice (``--tracker truth``), as a check of the chain without image analysis.

That figure held for OpenCV 5.1 only: with the 5.0 wheel a clean install gets it was 0.517, 0.503, 0.490.
The two builds' findTransformECC differ by 1e-6, the profile's colour network (trained to nearly the same
loss) came out different, and with it the contrast C the eyes' rules read; swapping the two networks swapped
the errors, and networks from other seeds or penalties gave 0.43-0.52. Since each eye has a shape model too,
the eyes no longer depend on C: 0.390, 0.379, 0.370 with OpenCV 5.1 and 0.406, 0.374, 0.388 with 5.0 (seeds
0-2; curves 0.74-0.85 px from the true ones).
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field
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

#: The demo's tracker unless told otherwise: the colour tracker, under the bar (module docstring).
DEFAULT_TRACKER = "color"

#: What the demo writes, and what each file is.
FILES: dict[str, str] = {
    "calibration.mp4": "the performer's calibration video (neutral, each key expression held, then the "
                       "neutral face with the head moving)",
    "calibration-marks.csv": "the marks file: frame of each held expression, span of the head motion",
    "performer-profile.npz": "the colour tracker's performer profile trained on the calibration video",
    "performer.npz": "the performer's key expressions (facepuppet calibrate)",
    "toy.glb": "the Toy character with its 13 key-models as morph targets",
    "rig.npz": "the fitted rig (facepuppet rig)",
    "performance.mp4": "the input video: the performer acting, with head motion",
    "track.npz": "the track of the performance",
    "overlay.mp4": "the performance with the tracked curves and head axes drawn on",
    "animation.glb": "the Toy animated by the performance (morph weights + head rotation)",
    "animation.csv": "the animation's weights, Live Link Face layout",
    "preview.mp4": "input with tracked curves (left) beside the animated Toy (right)",
}


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
    """

    seconds: float = 8.0
    fps: float = 30.0
    size: int = 320
    seed: int = 0
    tracker: str = DEFAULT_TRACKER
    preview: bool = True
    progress: bool | None = None
    model: str | None = None

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
    from facepuppet.io.atomic import atomic_path

    lines = ["# frame,name  (written by facepuppet demo; times may also be given as 1.5s or 00:01.5)"]
    lines += [f"{frame},{name}" for name, frame in sorted(marks.items(), key=lambda kv: kv[1])]
    lines += [f"{a}-{b},{name}" for name, (a, b) in spans.items()]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")


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
    from facepuppet.io.gltf import write_glb
    from facepuppet.io.performer import load_performer
    from facepuppet.io.rig import fit_rig, save_rig
    from facepuppet.io.track import save_track
    from facepuppet.pipeline._tracking import TrackerOptions
    from facepuppet.pipeline.animate import AnimateConfig, animate
    from facepuppet.pipeline.calibrate import CalibrateConfig, calibrate_marks, save_examples

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
    examples = calibrate_marks(files["calibration.mp4"], files["calibration-marks.csv"], names=toy.names,
                               config=CalibrateConfig(), track=cal_track)
    save_examples(files["performer.npz"], examples)
    rig, _pairing = fit_rig(load_performer(files["performer.npz"]), toy)
    save_rig(files["rig.npz"], rig)
    write_glb(files["toy.glb"], toy)
    t = step("calibrate + rig", t)

    track = track_video(files["performance.mp4"], perf_curves)
    save_track(files["track.npz"], track)
    t = step("track", t)
    anim = animate(files["performance.mp4"], rig, glb=files["animation.glb"], csv=files["animation.csv"],
                   preview=files.get("preview.mp4"), track=track, colors=toy_colors(),
                   config=AnimateConfig(tracker=TrackerOptions(progress=config.progress)))
    t = step("animate + preview" if config.preview else "animate", t)
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
