"""From a performance video to an animated character: track, map, smooth, scale, write.

:func:`animate` runs the whole chain; :func:`map_track` is its middle (a track and a rig in, weights out) for
callers that track by other means (a live camera, a track file made before).

Per frame: the tracker's feature points (head pose removed) go to the rig's mapper (paper Eq. 13) on frames
with a face; the weights are smoothed by a One-Euro filter, which also holds and then eases lost frames to
neutral (:mod:`facepuppet.pipeline.smoothing`), then scaled and clipped by the expression gain
(:mod:`facepuppet.pipeline.gain`). The outputs are a GLB (the character's key-models as morph targets and one
animation of their weights and of the head rotation), a CSV (Live Link Face layout for ARKit names) and a
side-by-side preview video. Every output is written atomically, and only after the whole performance has been
tracked and mapped, so a failure leaves none of them.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline._tracking import TrackerOptions, get_track
from facepuppet.pipeline.gain import GainConfig, apply_gain
from facepuppet.pipeline.smoothing import SmoothingConfig, smooth

__all__ = ["AnimateConfig", "Animation", "map_track", "animate", "head_rotation_in_character",
           "check_rig_matches"]

log = logging.getLogger(__name__)

#: OpenCV camera axes (x right, y down, z forward) to the character's (glTF: y up, facing +z).
_CAMERA_TO_CHARACTER = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True, kw_only=True)
class AnimateConfig:
    """Options of :func:`animate`.

    Attributes
    ----------
    tracker : TrackerOptions
        Tracker backend, colour-tracker profile, MediaPipe model.
    smoothing : SmoothingConfig
    gain : GainConfig
    head_rotation : bool
        Animate the head's rotation in the GLB (and write it to the CSV).
    """

    tracker: TrackerOptions = field(default_factory=TrackerOptions)
    smoothing: SmoothingConfig = field(default_factory=SmoothingConfig)
    gain: GainConfig = field(default_factory=GainConfig)
    head_rotation: bool = True


@dataclass(frozen=True)
class Animation:
    """The animation of a performance.

    Attributes
    ----------
    weights : (F, M) float
        Final weights (smoothed, gain applied), one column per paired key-model (``names``).
    raw : (F, M) float
        The mapper's weights before smoothing and gain; NaN on frames without a face.
    names : tuple of M str
        Paired key-model names (the rig's).
    fps : float
    track : Track
        What the tracker saw.
    timings : dict of str -> float
        Seconds spent per step (``track``, ``map``, ``write``, ``preview``).
    """

    weights: np.ndarray
    raw: np.ndarray
    names: tuple[str, ...]
    fps: float
    track: Track
    timings: dict = field(default_factory=dict)

    @property
    def valid(self) -> np.ndarray:
        """(F,) bool: frames with a tracked face."""
        return self.track.valid


def head_rotation_in_character(rotation: np.ndarray) -> np.ndarray:
    """Head rotations (F, 3, 3) from the track's camera frame to the character's frame.

    The track's rotation R maps head to OpenCV camera coordinates; the character (y up, facing +z, its own
    left at +x, like the head frame) turns by ``diag(1, -1, -1) @ R``, which is the identity for a frontal,
    upright head. The performer turning to their left turns the character to its own left.
    """
    return np.einsum("ij,fjk->fik", _CAMERA_TO_CHARACTER, np.asarray(rotation, dtype=float))


def check_rig_matches(rig, track: Track, rig_label: str = "rig") -> None:
    """Raise FacepuppetError when the rig was made for other feature points than the track holds."""
    ours = tuple(rig.point_names or ())
    if ours and ours != tuple(track.point_names):
        raise FacepuppetError(
            f"{rig_label}: made for other feature points ({len(ours)}, e.g. {ours[0]!r}) than the "
            f"{track.backend} tracker gives ({len(track.point_names)}, e.g. {track.point_names[0]!r}); "
            f"calibrate and rig again with this tracker")


def map_track(rig, track: Track, config: AnimateConfig | None = None, *, rig_label: str = "rig") -> Animation:
    """Weights of every frame of a track (mapper on valid frames, then smoothing and gain).

    Parameters
    ----------
    rig : facepuppet.io.rig.Rig
    track : Track
    config : AnimateConfig, optional
    rig_label : str
        How to name the rig in error messages (its path).
    """
    config = config or AnimateConfig()
    check_rig_matches(rig, track, rig_label)
    t0 = time.perf_counter()
    f, m = track.n_frames, len(rig.names)
    raw = np.full((f, m), np.nan)
    ok = track.valid & np.isfinite(track.points).all(axis=(1, 2))
    if ok.any():
        pts = track.points[ok]
        try:
            raw[ok] = rig.mapper.weights(pts)
        except ValueError as e:
            raise FacepuppetError(f"{rig_label}: does not fit the track's feature points ({e})") from e
    weights = smooth(raw, track.fps, valid=ok, config=config.smoothing)
    weights = apply_gain(weights, config.gain, rig.names)
    return Animation(weights, raw, tuple(rig.names), float(track.fps), track,
                     {"map": time.perf_counter() - t0})


def _load_rig(rig):
    if isinstance(rig, (str, os.PathLike)):
        from facepuppet.io.rig import load_rig

        return load_rig(rig), str(rig)
    return rig, "rig"


def _check_out(path) -> None:
    if path is None:
        return
    folder = Path(path).parent
    if str(folder) and not folder.is_dir():
        raise FileNotFoundError(f"{path}: folder {folder} does not exist")
    if Path(path).is_dir():
        raise IsADirectoryError(f"{path}: is a folder, not a file name")


def animate(media: str | os.PathLike | None, rig, *, glb: str | os.PathLike | None = None,
            csv: str | os.PathLike | None = None, preview: str | os.PathLike | None = None,
            track: Track | str | os.PathLike | None = None, config: AnimateConfig | None = None,
            colors: np.ndarray | None = None) -> Animation:
    """Animate a character from a performance video.

    Parameters
    ----------
    media : str or PathLike or None
        The performance (video, image folder, ``camera:N``); may be None when ``track`` is given and no
        preview is asked for.
    rig : Rig or str or PathLike
        A rig (``facepuppet rig``) or its file.
    glb, csv, preview : str or PathLike, optional
        Outputs: the animated character, the weights as CSV, the side-by-side preview video.
    track : Track or str or PathLike, optional
        Reuse a track (or track file) of ``media`` instead of tracking again.
    config : AnimateConfig, optional
    colors : (V, 3) float, optional
        Vertex colours of the character in the preview (grey by default).

    Returns
    -------
    Animation
    """
    config = config or AnimateConfig()
    rig, rig_label = _load_rig(rig)
    for out in (glb, csv, preview):
        _check_out(out)
    if preview is not None and media is None:
        raise ValueError("--preview needs the input media (the frames drawn on the left)")
    t0 = time.perf_counter()
    if track is None:
        if media is None:
            raise ValueError("give the media to track, or --track")
        track = get_track(media, config.tracker)
    elif not isinstance(track, Track):
        from facepuppet.io.track import load_track

        track = load_track(track)
    t_track = time.perf_counter() - t0
    if not track.valid.any():
        raise FacepuppetError(f"{media or 'track'}: no face was tracked in any frame")
    anim = map_track(rig, track, config, rig_label=rig_label)
    anim.timings["track"] = t_track

    t0 = time.perf_counter()
    char_weights = rig.character_weights(anim.weights)
    rotation = head_rotation_in_character(track.rotation) if config.head_rotation else None
    if rotation is not None:
        rotation = _fill_lost_rotations(rotation, track.valid)
    if glb is not None:
        from facepuppet.export.gltf_animation import write_animated_glb

        write_animated_glb(glb, rig.character, char_weights, track.fps, head_rotation=rotation)
    if csv is not None:
        _write_csv(csv, rig, anim, rotation)
    anim.timings["write"] = time.perf_counter() - t0
    if preview is not None:
        t0 = time.perf_counter()
        _write_preview(preview, media, rig, anim, config, rotation, colors)
        anim.timings["preview"] = time.perf_counter() - t0
    return anim


def _fill_lost_rotations(rotation: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Lost frames keep the last tracked rotation (the rest pose before the first)."""
    out = rotation.copy()
    last = np.eye(3)
    for k in range(len(out)):
        if valid[k] and np.isfinite(out[k]).all():
            last = out[k]
        else:
            out[k] = last
    return out


def _write_csv(path, rig, anim: Animation, rotation: np.ndarray | None) -> None:
    from facepuppet.export.csv import write_weights_csv

    write_weights_csv(path, anim.weights, anim.names, anim.fps, head_rotation=rotation)


def _write_preview(path, media, rig, anim: Animation, config: AnimateConfig, rotation: np.ndarray | None,
                   colors: np.ndarray | None) -> None:
    from facepuppet.capture.features import FrameFeatures
    from facepuppet.export.overlay import draw_overlay
    from facepuppet.export.preview import write_preview
    from facepuppet.export.render import Camera, render_mesh
    from facepuppet.io.frames import open_media

    track = anim.track
    character = rig.character
    height = int(track.frame_size[1])
    neutral = np.asarray(character.neutral, dtype=float)
    deltas = character.targets[rig.target_indices] - neutral[None]
    pivot = (neutral.min(axis=0) + neutral.max(axis=0)) / 2
    camera = Camera.fit(neutral, (height, height), margin=0.15)

    def left(k: int, frame: np.ndarray) -> np.ndarray:
        if k >= track.n_frames:
            return frame
        feats = FrameFeatures(bool(track.valid[k]), track.curves[k], track.rotation[k], track.translation[k],
                              track.points[k])
        return draw_overlay(frame, feats)

    def right(k: int) -> np.ndarray:
        k = min(k, len(anim.weights) - 1)
        verts = neutral + np.tensordot(anim.weights[k], deltas, axes=1)       # Eq. 14
        if rotation is not None:
            verts = (verts - pivot) @ rotation[k].T + pivot
        return render_mesh(verts, character.faces, camera=camera, colors=colors)

    with open_media(media) as src:
        write_preview(path, src, track.fps, left=left, right=right, n_frames=track.n_frames,
                      progress=config.tracker.progress)
