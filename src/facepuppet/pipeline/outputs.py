"""File outputs of the stream (:mod:`facepuppet.pipeline.stream`): GLB, CSV and preview video, as frames pass.

Each output holds its file under a temporary name from the moment it is opened (:func:`atomic_path`, entered on
the caller's :class:`contextlib.ExitStack`) and is renamed onto its own name only when the whole stack closes
without error: all outputs of a run appear together, or none. The preview video is written frame by frame; the
GLB and the CSV need the whole take, so their rows (the weights and rotations, a few hundred bytes a frame) are
spooled to a temporary file beside the output instead of memory, and written at :meth:`finish`.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.stream import StreamFrame

__all__ = ["RowSpool", "GlbOutput", "CsvOutput", "PreviewOutput", "OUTPUT_SUFFIXES", "check_suffix"]

#: File name suffixes each output writes (lower case): the GLB container (.vrm is one), .gltf JSON with an
#: embedded buffer, CSV text, MPEG-4 video.
OUTPUT_SUFFIXES: dict[str, tuple[str, ...]] = {"animated character": (".glb", ".gltf", ".vrm"),
                                               "weights CSV": (".csv",), "preview video": (".mp4", ".m4v")}


def check_suffix(path: str | os.PathLike, kind: str) -> None:
    """Raise ValueError naming ``path`` when its suffix is not one the output ``kind`` writes."""
    allowed = OUTPUT_SUFFIXES[kind]
    if Path(path).suffix.lower() not in allowed:
        raise ValueError(f"{path}: the {kind} is written as {', '.join(allowed)}, not "
                         f"{Path(path).suffix or 'a name without suffix'}")


class RowSpool:
    """Rows of float64 values appended to an unnamed temporary file; read back at the end.

    Parameters
    ----------
    width : int
        Values per row.
    folder : str or PathLike, optional
        Where the temporary file lives (beside the output, so a full disk shows there).
    """

    def __init__(self, width: int, folder: str | os.PathLike | None = None) -> None:
        self.width = int(width)
        self.rows = 0
        self._file = tempfile.TemporaryFile(dir=folder)

    def append(self, row: np.ndarray) -> None:
        """Append one row of ``width`` values."""
        row = np.asarray(row, dtype=np.float64).reshape(-1)
        if row.size != self.width:
            raise ValueError(f"row must have {self.width} values, got {row.size}")
        self._file.write(row.tobytes())
        self.rows += 1

    def read(self) -> np.ndarray:
        """All rows, (rows, width) float64 (a new array)."""
        self._file.flush()
        self._file.seek(0)
        data = np.frombuffer(self._file.read(), dtype=np.float64)
        return data.reshape(self.rows, self.width).copy()

    def close(self) -> None:
        self._file.close()


def _stage(stack: contextlib.ExitStack, path: str | os.PathLike, suffix: str | None = None) -> Path:
    """A temporary path beside ``path``, renamed onto it when ``stack`` closes cleanly."""
    return stack.enter_context(atomic_path(path, suffix=suffix))


class _Rows:
    """The spooled rows shared by the GLB and CSV outputs: time, valid, weights (C channels), rotation (9)."""

    def __init__(self, n_weights: int, folder: Path, stack: contextlib.ExitStack) -> None:
        self.m = n_weights
        self.spool = RowSpool(2 + n_weights + 9, folder)
        stack.callback(self.spool.close)

    def add(self, frame: StreamFrame) -> None:
        self.spool.append(np.concatenate([[frame.time, float(frame.valid)], frame.weights,
                                          frame.rotation.reshape(-1)]))

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """times (F,), valid (F,) bool, weights (F, M), rotation (F, 3, 3)."""
        data = self.spool.read()
        m = self.m
        return data[:, 0], data[:, 1] > 0.5, data[:, 2:2 + m], data[:, 2 + m:].reshape(-1, 3, 3)


def _channels(rig) -> tuple[str, ...]:
    """The rig's weight channels (``Rig.channel_names``; its key-model names for a rig without them)."""
    return tuple(getattr(rig, "channel_names", rig.names))


def _folder(path) -> Path:
    folder = Path(path).parent
    return folder if str(folder) else Path(".")


class GlbOutput:
    """The character with one animation of the stream's weights: its own scene whole when the rig keeps it
    (``Character.source``), else the bare mesh with its key-models as morph targets; for a regional rig the bare
    mesh with the paired key-models split by region (``Rig.split_character``, R·M morph targets).

    Parameters
    ----------
    path : str or PathLike
        The .glb to write.
    rig : facepuppet.pipeline.rig.Rig
        Its character is written; the rig's weights are spread over the character's key-models.
    stack : ExitStack
        Holds the temporary file until the run commits.
    head_rotation : bool
        Animate the head's rotation too.
    fps : float
        The take's frame rate (the GLB's keys are at the frames' own times).
    """

    def __init__(self, path, rig, stack: contextlib.ExitStack, *, head_rotation: bool = True,
                 fps: float = 30.0) -> None:
        check_suffix(path, "animated character")
        self.path, self.rig, self.head_rotation, self.fps = path, rig, head_rotation, float(fps)
        self._tmp = _stage(stack, path, suffix=Path(path).suffix.lower())
        self._rows = _Rows(len(_channels(rig)), _folder(path), stack)

    def write(self, frame: StreamFrame) -> None:
        self._rows.add(frame)

    def finish(self) -> None:
        from facepuppet.export.gltf_animation import write_animated_glb

        if self._rows.spool.rows == 0:
            raise FacepuppetError(f"{self.path}: no frames to write")
        times, _, weights, rotation = self._rows.read()
        times = times - times[0] if len(times) else times
        rotation = rotation if self.head_rotation else None
        character = self.rig.character
        if getattr(self.rig, "regional", False):  # the bare mesh, key-models split by region (R·M targets)
            write_animated_glb(self._tmp, self.rig.split_character(), weights, self.fps, times=times,
                               head_rotation=rotation)
            return
        if character.source is not None:  # the character's own scene, whole, with the animation added
            from facepuppet.export.scene_animation import write_scene_animation

            neutral = np.asarray(character.neutral)
            write_scene_animation(self._tmp, character.source, self.rig.names, weights, self.fps, times=times,
                                  head_rotation=rotation, pivot=(neutral.min(axis=0) + neutral.max(axis=0)) / 2)
            return
        write_animated_glb(self._tmp, character, self.rig.character_weights(weights), self.fps,
                           times=times, head_rotation=rotation)


class CsvOutput:
    """The stream's weights as CSV (Live Link Face layout for ARKit names; see :mod:`facepuppet.export.csv`); a
    regional rig's R·M channels ``<region>/<key-model>`` in the plain layout (the regional GLB's morph weights).

    Parameters are those of :class:`GlbOutput`.
    """

    def __init__(self, path, rig, stack: contextlib.ExitStack, *, head_rotation: bool = True,
                 fps: float = 30.0) -> None:
        check_suffix(path, "weights CSV")
        self.path, self.rig, self.head_rotation, self.fps = path, rig, head_rotation, float(fps)
        self._tmp = _stage(stack, path, suffix=".csv")
        self._rows = _Rows(len(_channels(rig)), _folder(path), stack)

    def write(self, frame: StreamFrame) -> None:
        self._rows.add(frame)

    def finish(self) -> None:
        from facepuppet.export.csv import write_weights_csv

        if self._rows.spool.rows == 0:
            raise FacepuppetError(f"{self.path}: no frames to write")
        times, _, weights, rotation = self._rows.read()
        regional = getattr(self.rig, "regional", False)
        write_weights_csv(self._tmp, weights, _channels(self.rig), self.fps, layout="plain" if regional else "auto",
                          times=times - times[0] if len(times) else times,
                          head_rotation=rotation if self.head_rotation else None)


class PreviewOutput:
    """Side-by-side preview video written as frames pass: the frame with its tracked curves, the character.

    Parameters
    ----------
    path : str or PathLike
        The .mp4 to write.
    rig : facepuppet.pipeline.rig.Rig
    stack : ExitStack
    fps : float
    frame_height : int
        Height of the input frames (the character is rendered square at that height).
    colors : (V, 3) float, optional
        Vertex colours of the character (grey by default).
    head_rotation : bool
        Turn the rendered head with the performer's.
    """

    def __init__(self, path, rig, stack: contextlib.ExitStack, *, fps: float, frame_height: int,
                 colors: np.ndarray | None = None, head_rotation: bool = True) -> None:
        from facepuppet.export.render import Camera

        check_suffix(path, "preview video")
        self.path, self.fps, self.colors, self.head_rotation = path, float(fps), colors, head_rotation
        self._stack = stack
        character = rig.character
        self._faces = character.faces
        self._neutral = np.asarray(character.neutral, dtype=float)
        self._deltas = character.targets[rig.target_indices] - self._neutral[None]
        if getattr(rig, "regional", False):  # R·M split targets M_k ⊙ (T_i − T_B), as the GLB plays them
            split = rig.split_character()
            self._deltas = split.targets - self._neutral[None]
        self._pivot = (self._neutral.min(axis=0) + self._neutral.max(axis=0)) / 2
        self._camera = Camera.fit(self._neutral, (int(frame_height), int(frame_height)), margin=0.15)
        self._writer = None

    def write(self, frame: StreamFrame) -> None:
        from facepuppet.export.overlay import draw_overlay
        from facepuppet.export.preview import open_preview, side_by_side
        from facepuppet.export.render import render_mesh

        if frame.rgb is None:
            raise ValueError("the preview needs the input frames")
        verts = self._neutral + np.tensordot(frame.weights, self._deltas, axes=1)       # Eq. 14
        if self.head_rotation:
            verts = (verts - self._pivot) @ frame.rotation.T + self._pivot
        right = render_mesh(verts, self._faces, camera=self._camera, colors=self.colors)
        img = side_by_side(draw_overlay(frame.rgb, frame.features), right)
        if self._writer is None:
            self._writer = self._stack.enter_context(open_preview(self.path, self.fps, img.shape[1::-1]))
        self._writer.write(img)

    def finish(self) -> None:
        if self._writer is None:
            from facepuppet.errors import FacepuppetError

            raise FacepuppetError(f"{self.path}: no frames to write")
