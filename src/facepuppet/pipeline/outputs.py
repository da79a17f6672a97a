"""File outputs of the stream (:mod:`facepuppet.pipeline.stream`): GLB, CSV and preview video, as frames pass.

Each output holds its file under a temporary name from the moment it is opened (:func:`atomic_path`, entered on
the caller's :class:`contextlib.ExitStack`) and is renamed onto its own name only when the whole stack closes
without error: all outputs of a run appear together, or none. The preview video is written frame by frame; the
GLB and the CSV need the whole take, so their rows (the weights and rotations, a few hundred bytes a frame) are
spooled to a temporary file beside the output instead of memory, and written at :meth:`finish` from the spool
chunk by chunk (:class:`~facepuppet.export.take.TakeRows`): memory stays flat in the take's length.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.stream import StreamFrame

if TYPE_CHECKING:
    from facepuppet.export.take import TakeRows

log = logging.getLogger(__name__)

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

    def chunks(self, rows: int) -> Iterator[np.ndarray]:
        """All rows again, ``rows`` at a time: (n, width) float64 arrays, the last one shorter."""
        self._file.flush()
        self._file.seek(0)
        left = self.rows
        while left > 0:
            n = min(int(rows), left)
            data = self._file.read(n * self.width * 8)
            if len(data) != n * self.width * 8:
                raise OSError(f"the spool of {self.rows} rows ended early")
            left -= n
            yield np.frombuffer(data, dtype=np.float64).reshape(n, self.width)

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

    def take(self, head_rotation: bool, weights=None, width: int | None = None) -> TakeRows:
        """The rows as a take (chunks read from the spool), times from the first frame's; ``weights`` maps a
        chunk's weights (n, M) to the (n, ``width``) the writer takes."""
        from facepuppet.export.take import CHUNK_ROWS, TakeChunk, TakeRows

        m, spool = self.m, self.spool
        first = next(spool.chunks(1))[0, 0]

        def read():
            for data in spool.chunks(CHUNK_ROWS):
                w = data[:, 2:2 + m]
                yield TakeChunk(data[:, 0] - first, w if weights is None else weights(w),
                                data[:, 2 + m:].reshape(-1, 3, 3) if head_rotation else None)

        return TakeRows(spool.rows, m if width is None else int(width), read, bool(head_rotation))


def _channels(rig) -> tuple[str, ...]:
    """The rig's weight channels (``Rig.channel_names``; its key-model names for a rig without them)."""
    return tuple(getattr(rig, "channel_names", rig.names))


def _folder(path) -> Path:
    folder = Path(path).parent
    return folder if str(folder) else Path(".")


class GlbOutput:
    """The character with one animation of the stream's weights: its own scene whole when the rig keeps it
    (``Character.source``), else the bare mesh with its key-models as morph targets. For a regional rig the
    paired key-models are split by region into R·M morph targets: added to the scene's meshes
    (:mod:`facepuppet.export.scene_regional`), or on the bare mesh (``Rig.split_character``) when the rig has
    no scene or its character is only part of one.

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
        character = self.rig.character
        regional = getattr(self.rig, "regional", False)
        if character.source is not None and (not regional or _scene_holds(character)):
            # the character's own scene, whole, with the animation added (a regional rig's split targets too)
            from facepuppet.export.scene_animation import write_scene_animation

            neutral = np.asarray(character.neutral)
            write_scene_animation(self._tmp, character.source, self.rig.names, self._rows.take(self.head_rotation),
                                  self.fps, pivot=(neutral.min(axis=0) + neutral.max(axis=0)) / 2,
                                  regions=(self.rig.region_names, self.rig.mapper.region_masks) if regional
                                  else None)
            return
        if regional:  # the bare mesh, key-models split by region (R·M targets)
            write_animated_glb(self._tmp, self.rig.split_character(), self._rows.take(self.head_rotation), self.fps)
            return
        take = self._rows.take(self.head_rotation, self.rig.character_weights, len(character.names))
        write_animated_glb(self._tmp, character, take, self.fps)


def _scene_holds(character) -> bool:
    """True when the character's vertices are all those of its scene that the reader joins (not one mesh of
    it, picked with ``--mesh``), so a regional rig's masks fit the scene."""
    from facepuppet.export.scene_regional import scene_vertex_count

    fits = scene_vertex_count(character.source) == len(character.neutral)
    if not fits:
        log.warning("the regional animation is written on the bare mesh: the rig's character is part of its "
                    "scene (its region masks do not cover the scene's meshes)")
    return fits


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
        regional = getattr(self.rig, "regional", False)
        write_weights_csv(self._tmp, self._rows.take(self.head_rotation), _channels(self.rig), self.fps,
                          layout="plain" if regional else "auto")


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
