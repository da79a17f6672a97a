"""Writing a track file frame by frame: memory flat in the take's length.

Each per-frame array (``valid``, ``curves``, ``points``, ``rotation``, ``translation`` and a backend's
per-frame extras) is appended to its own unnamed temporary file beside the output as frames arrive; at
:meth:`TrackWriter.finish` the ``.npz`` (the same file :func:`facepuppet.io.track.save_track` writes) is
assembled under a temporary name by streaming every spool into its archive member in chunks, then renamed onto
the output. Nothing appears at the output unless :meth:`finish` succeeds.
"""

from __future__ import annotations

import contextlib
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError
from facepuppet.io.track import track_scalars

__all__ = ["TrackWriter"]

#: Bytes copied at a time from a spool into the archive.
_CHUNK = 1 << 20


class _Spool:
    """Rows of one dtype and shape, appended to an unnamed temporary file."""

    def __init__(self, shape: tuple[int, ...], dtype, folder: Path, rows_before: int = 0) -> None:
        self.shape, self.dtype = tuple(shape), np.dtype(dtype)
        self.rows = 0
        self.file = tempfile.TemporaryFile(dir=folder)
        if rows_before:
            fill = np.full((rows_before, *self.shape), np.nan if self.dtype.kind == "f" else 0, self.dtype)
            self.append(fill, rows=rows_before)

    def append(self, value, rows: int = 1) -> None:
        value = np.ascontiguousarray(value, dtype=self.dtype)
        if value.size != rows * int(np.prod(self.shape, dtype=np.int64)):
            raise ValueError(f"expected shape {self.shape}, got {np.shape(value)}")
        self.file.write(value.tobytes())
        self.rows += rows

    def copy_into(self, zf: zipfile.ZipFile, name: str) -> None:
        header = {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False,
                  "shape": (self.rows, *self.shape)}
        self.file.flush()
        self.file.seek(0)
        with zf.open(f"{name}.npy", "w", force_zip64=True) as out:
            np.lib.format.write_array_header_2_0(out, header)
            while chunk := self.file.read(_CHUNK):
                out.write(chunk)


class TrackWriter:
    """A track file written as frames pass (see the module notes).

    Parameters
    ----------
    path : str or PathLike
        The ``.npz`` to write.
    fps : float
    frame_size : (int, int)
        Width, height in pixels.
    curve_names, point_names : sequence of str
    backend : str
    static_extras : dict of str -> ndarray, optional
        Arrays stored as they are (``blendshape_names``).
    media, profile_hash
        Provenance (:class:`facepuppet.io.track.Track`).
    stack : ExitStack, optional
        Hold the file under a temporary name on this stack, renamed when it closes without error (with the
        run's other outputs); without it :meth:`finish` renames at once.

    Use as a context manager; call :meth:`add` per frame and :meth:`finish` at the end.
    """

    def __init__(self, path, *, fps: float, frame_size, curve_names, point_names, backend: str,
                 static_extras: dict | None = None, media: dict | None = None,
                 profile_hash: str | None = None, stack: contextlib.ExitStack | None = None) -> None:
        self.path = Path(path)
        folder = self.path.parent if str(self.path.parent) else Path(".")
        if not folder.is_dir():
            raise FacepuppetError(f"{path}: folder {folder} does not exist")
        self._folder = folder
        self.curve_names, self.point_names = tuple(curve_names), tuple(point_names)
        c, p = len(self.curve_names), len(self.point_names)
        self._meta = {"fps": float(fps), "frame_size": frame_size, "backend": backend, "media": media,
                      "profile_hash": profile_hash, "static_extras": dict(static_extras or {})}
        self._spools = {"valid": _Spool((), np.bool_, folder), "curves": _Spool((c, 4, 2), np.float32, folder),
                        "points": _Spool((p, 3), np.float32, folder),
                        "rotation": _Spool((3, 3), np.float32, folder),
                        "translation": _Spool((3,), np.float32, folder)}
        self._extras: dict[str, _Spool] = {}
        self._times = _Spool((), np.float64, folder)
        self._vfr = False
        self.n_frames = 0
        self.n_valid = 0
        # staged on the caller's stack: renamed with the run's other outputs when it closes cleanly
        self._staged = None if stack is None else stack.enter_context(atomic_path(self.path, suffix=".npz"))

    def __enter__(self) -> TrackWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def add(self, features, time: float | None = None) -> None:
        """Append one frame's :class:`~facepuppet.capture.features.FrameFeatures` (NaN where not valid) at
        ``time`` seconds (default ``index / fps``; the file keeps per-frame times only if one differs)."""
        nominal = self.n_frames / self._meta["fps"]
        t = nominal if time is None else float(time)
        self._vfr = self._vfr or abs(t - nominal) > 1e-9
        self._times.append(t)
        valid = bool(features.valid)
        s = self._spools
        s["valid"].append(valid)
        for key in ("curves", "points", "rotation", "translation"):
            value = np.asarray(getattr(features, key), dtype=np.float32)
            s[key].append(value if valid else np.full(s[key].shape, np.nan, np.float32))
        extras = features.extras or {}
        for key, value in extras.items():
            if key not in self._extras:
                if key in s or key in self._meta["static_extras"]:
                    raise ValueError(f"track extra {key!r} clashes with a standard key")
                value = np.asarray(value)
                self._extras[key] = _Spool(value.shape, np.result_type(value.dtype, np.float32), self._folder,
                                           rows_before=self.n_frames)
        for key, spool in self._extras.items():
            value = extras.get(key)
            spool.append(np.full(spool.shape, np.nan, spool.dtype) if value is None else value)
        self.n_frames += 1
        self.n_valid += valid

    def set_media(self, media: dict | None) -> None:
        """Record the media file tracked (known only once it has been read through)."""
        self._meta["media"] = media

    def finish(self) -> None:
        """Assemble the ``.npz`` and rename it onto the output."""
        if self.n_frames == 0:
            raise FacepuppetError(f"{self.path}: no frames to write")
        m = self._meta
        scalars = track_scalars(fps=m["fps"], frame_size=m["frame_size"], curve_names=self.curve_names,
                                point_names=self.point_names, backend=m["backend"], media=m["media"],
                                profile_hash=m["profile_hash"])
        scalars.update({k: np.asarray(v) for k, v in m["static_extras"].items()})
        spools = {**self._spools, **self._extras, **({"times": self._times} if self._vfr else {})}
        with contextlib.ExitStack() as stack:
            tmp = self._staged or stack.enter_context(atomic_path(self.path, suffix=".npz"))
            with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
                for name, value in scalars.items():
                    with zf.open(f"{name}.npy", "w", force_zip64=True) as out:
                        np.lib.format.write_array(out, np.asarray(value), allow_pickle=False)
                for name, spool in spools.items():
                    spool.copy_into(zf, name)

    def close(self) -> None:
        for spool in (*self._spools.values(), *self._extras.values(), self._times):
            spool.file.close()
