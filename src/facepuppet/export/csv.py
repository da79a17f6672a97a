"""Blend weights as CSV: the layout of Live Link Face recordings for ARKit-named characters, else plain.

**Live Link Face layout** (``layout="arkit"``), which Unreal's Live Link Face importer and Blender/Maya add-ons
read: a header ``Timecode,BlendShapeCount,`` then the 52 ARKit blendshapes in Live Link Face's capitalised
names and order (:data:`LLF_BLENDSHAPES`), then ``HeadYaw,HeadPitch,HeadRoll,LeftEyeYaw,...,RightEyeRoll``;
``BlendShapeCount`` is 61 on every row. One row per video frame. The timecode is ``HH:MM:SS:FF.mmm`` where
``FF.mmm`` counts 60ths of a second within the second, with three decimals (Live Link Face's 60 Hz timecode;
its importer reads the time as ``seconds + FF.mmm / 60``), so rows at any video frame rate land at their
exact times. Key-model names map to columns whatever their spelling (:mod:`facepuppet.arkit`):
``eyeBlink_L``, ``eyeBlinkLeft``, ``EyeBlinkLeft``, ``eyeBlink.L``; a symmetric ``eyeBlink`` fills both sides;
halves of a shape ARKit has as one (ICT's ``browInnerUp_L`` and ``browInnerUp_R``) are averaged. Head angles
are Live Link Face's: the angle divided by 180° (±1 is a half turn). Eye rotations are zero (gaze is not
tracked).

**Plain layout** (``layout="plain"``): ``time,valid,<key-model names...>`` and, with a head rotation,
``head_yaw,head_pitch,head_roll`` in radians; time in seconds.

Head rotations are in the character's frame (y up, the face looking along +z, x toward the face's own
left), decomposed as R = R_y(yaw) R_x(pitch) R_z(roll): positive yaw turns the face to its own left,
positive pitch tilts it down, positive roll tilts the top of the head to its own right.
A frame that is not valid, or has non-finite weights, is written as the neutral face (zeros).
"""

from __future__ import annotations

import csv
import os
import warnings
from collections.abc import Sequence

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.arkit import LLF_NAMES, arkit_parts, llf_name
from facepuppet.export.take import TakeChunk, TakeRows

__all__ = ["write_weights_csv", "LLF_BLENDSHAPES", "LLF_HEAD_EYES", "llf_timecode", "head_angles",
           "arkit_columns"]

#: The 52 ARKit blendshapes as Live Link Face names and orders its CSV columns.
LLF_BLENDSHAPES: tuple[str, ...] = LLF_NAMES
#: Head and eye rotation columns that follow the blendshapes.
LLF_HEAD_EYES: tuple[str, ...] = ("HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch",
                                  "LeftEyeRoll", "RightEyeYaw", "RightEyePitch", "RightEyeRoll")
_LLF_COLUMN = {n: i for i, n in enumerate(LLF_NAMES)}


def arkit_columns(name: str) -> tuple[int, ...]:
    """Indices into :data:`LLF_BLENDSHAPES` that key-model ``name`` drives (empty if it is not ARKit's).

    Names match as :func:`facepuppet.arkit.arkit_parts` says; a half of a shape ARKit has as one drives
    that shape's column (the halves are averaged).
    """
    parts = arkit_parts(name)
    return tuple(_LLF_COLUMN[llf_name(n)] for n in parts[0]) if parts else ()


def llf_timecode(seconds: float) -> str:
    """``HH:MM:SS:FF.mmm`` of a time in seconds, FF.mmm in 60ths of a second (Live Link Face's timecode)."""
    milli_frames = int(round(seconds * 60000))
    frames, milli = divmod(milli_frames, 1000)
    secs, ff = divmod(frames, 60)
    mins, ss = divmod(secs, 60)
    hh, mm = divmod(mins, 60)
    return f"{hh:02d}:{mm:02d}:{ss:02d}:{ff:02d}.{milli:03d}"


def head_angles(rotation: np.ndarray) -> np.ndarray:
    """(F, 3) yaw, pitch, roll in radians of rotations (F, 3, 3) = R_y(yaw) R_x(pitch) R_z(roll)."""
    r = np.asarray(rotation, dtype=np.float64)
    yaw = np.arctan2(r[:, 0, 2], r[:, 2, 2])
    pitch = np.arcsin(np.clip(-r[:, 1, 2], -1.0, 1.0))
    roll = np.arctan2(r[:, 1, 0], r[:, 1, 1])
    return np.stack([yaw, pitch, roll], axis=1)


def write_weights_csv(path: str | os.PathLike, weights: np.ndarray | TakeRows, names: Sequence[str], fps: float, *,
                      head_rotation: np.ndarray | None = None, valid: np.ndarray | None = None,
                      layout: str = "auto", start_time: float = 0.0, times: np.ndarray | None = None) -> str:
    """Write per-frame blend weights (and head rotation) as CSV, atomically.

    Parameters
    ----------
    path : str or PathLike
        Output .csv file.
    weights : (F, M) float, or TakeRows
        Blend weights per frame, one column per key-model; or the whole take as
        :class:`~facepuppet.export.take.TakeRows` (weights, times, head rotations and valid flags read chunk by
        chunk: memory flat in the take's length; ``head_rotation``, ``valid`` and ``times`` are then not given).
    names : sequence of M str
        Key-model names.
    fps : float
        Frame rate of the video; row f is at ``start_time + f / fps`` seconds.
    head_rotation : (F, 3, 3) float, optional
        Head rotation per frame in the character's frame (module notes).
    valid : (F,) bool, optional
        False where no face was tracked; such rows are written as neutral.
    layout : {"auto", "arkit", "plain"}
        ``auto`` takes the Live Link Face layout when at least half of the names are ARKit blendshapes.
    start_time : float
        Time of the first row in seconds (for example a time of day).
    times : (F,) float, optional
        Each row's time in seconds after ``start_time`` (a live recording with dropped frames); ``f / fps``
        if None.

    Returns
    -------
    str
        The layout written, ``"arkit"`` or ``"plain"``.
    """
    names = [str(n) for n in names]
    if isinstance(weights, TakeRows):
        if head_rotation is not None or valid is not None or times is not None:
            raise ValueError("times, head rotations and valid flags of a TakeRows are its own")
        rows = weights
        if rows.width != len(names):
            raise ValueError(f"weights must have shape (F, {len(names)}) to match names, got "
                             f"({rows.frames}, {rows.width})")
    else:
        weights = np.asarray(weights, dtype=np.float64)
        if weights.ndim != 2 or weights.shape[1] != len(names):
            raise ValueError(f"weights must have shape (F, {len(names)}) to match names, got {weights.shape}")
        rows = None
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    if layout not in ("auto", "arkit", "plain"):
        raise ValueError(f"layout must be 'auto', 'arkit' or 'plain', got {layout!r}")
    if rows is None:
        f = len(weights)
        if valid is not None:
            valid = np.asarray(valid, dtype=bool)
            if valid.shape != (f,):
                raise ValueError(f"valid must have shape ({f},), got {valid.shape}")
        if head_rotation is not None:
            head_rotation = np.asarray(head_rotation, dtype=np.float64)
            if head_rotation.shape != (f, 3, 3):
                raise ValueError(f"head_rotation must have shape ({f}, 3, 3), got {head_rotation.shape}")
        times = np.arange(f) / fps if times is None else np.asarray(times, dtype=np.float64)
        if times.shape != (f,) or not np.isfinite(times).all():
            raise ValueError(f"times must be {f} finite seconds, got shape {times.shape}")
        rows = TakeRows.from_arrays(weights, times, rotation=head_rotation, valid=valid)
    columns = [arkit_columns(n) for n in names]
    if layout == "auto":
        layout = "arkit" if names and sum(bool(c) for c in columns) * 2 >= len(names) else "plain"
    if layout == "arkit":
        unmapped = [n for n, c in zip(names, columns, strict=True) if not c]
        if unmapped:
            warnings.warn(f"{path}: key-models with no ARKit name are left out of the Live Link Face CSV: "
                          f"{', '.join(unmapped)}", stacklevel=2)
        header = ["Timecode", "BlendShapeCount", *LLF_BLENDSHAPES, *LLF_HEAD_EYES]
    else:
        header = ["time", "valid", *names]
        if rows.has_rotation:
            header += ["head_yaw", "head_pitch", "head_roll"]
    with atomic_path(path, suffix=".csv") as tmp:
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(header)
            for chunk in rows.read():
                for first, row in _rows(chunk, columns, layout, float(start_time)):
                    writer.writerow(first + [_number(x) for x in row.tolist()])
    return layout


def _rows(chunk: TakeChunk, columns: list, layout: str, start_time: float):
    """(leading cells, values) of each row of one chunk, in the chosen layout (see the module notes)."""
    weights = chunk.weights
    f = len(weights)
    ok = np.ones(f, dtype=bool) if chunk.valid is None else np.asarray(chunk.valid, dtype=bool).copy()
    if ok.shape != (f,):
        raise ValueError(f"valid must have shape ({f},), got {ok.shape}")
    ok &= np.all(np.isfinite(weights), axis=1)
    angles = None
    if chunk.rotation is not None:
        angles = head_angles(chunk.rotation)
        angles[~(ok & np.all(np.isfinite(angles), axis=1))] = 0.0
    weights = np.where(ok[:, None], weights, 0.0)
    times = start_time + chunk.times
    if layout == "arkit":
        values = np.zeros((f, len(LLF_BLENDSHAPES) + len(LLF_HEAD_EYES)))
        count = np.zeros(len(LLF_BLENDSHAPES))
        for j, cols in enumerate(columns):
            for c in cols:
                values[:, c] += weights[:, j]
                count[c] += 1
        values[:, : len(count)] /= np.maximum(count, 1)
        if angles is not None:
            values[:, len(count): len(count) + 3] = angles / np.pi
        n_columns = str(len(LLF_BLENDSHAPES) + len(LLF_HEAD_EYES))
        lead = ([llf_timecode(t), n_columns] for t in times)
    else:
        values = weights
        if angles is not None:
            values = np.concatenate([weights, angles], axis=1)
        lead = ([f"{t:.6f}", str(int(v))] for t, v in zip(times, ok, strict=True))
    return zip(lead, values, strict=True)


def _number(x: float) -> str:
    text = f"{x:.6g}"
    return "0" if text == "-0" else text
