"""What a batch does: its clips, each with a rig and an output name, and the content hashes that let it resume.

A batch is a list of :class:`Job` (one per clip). Its inputs come from the command line (clips and one rig) or
from a list file (:func:`read_list`): CSV, one clip per row, columns

==========  ==========================================================================================
``clip``    the performance (video or image folder); relative paths are taken from the list's folder
``rig``     its rig file (same rule); empty or absent: the batch's ``--rig``
``output``  the outputs' name without extension (``OUTDIR/<output>.glb`` ...); empty or absent: the
            clip's stem
==========  ==========================================================================================

A header row is optional: with one (``clip,rig,output`` in any order, ``rig`` and ``output`` may be left out)
the columns go by name, without one by position. Blank rows and rows starting with ``#`` are skipped.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from facepuppet import __version__
from facepuppet.errors import FacepuppetError

__all__ = ["Job", "LIST_COLUMNS", "read_list", "jobs_from_clips", "output_paths", "file_sha256",
           "options_sha256", "check_unique", "check_rigs"]

#: Columns of a batch list file, in their positional order.
LIST_COLUMNS = ("clip", "rig", "output")

#: Bytes read at a time when hashing a file.
_HASH_CHUNK = 1 << 20


@dataclass(frozen=True, kw_only=True)
class Job:
    """One clip of a batch.

    Attributes
    ----------
    clip : str
        The performance (video file or image folder).
    rig : str
        Its rig file.
    name : str
        The outputs' name: ``OUTDIR/<name>.glb``, ``.csv``, ``.mp4``.
    source : str
        Where the job was given (``"LIST.csv:4"`` or ``"argument 2"``), for error messages.
    """

    clip: str
    rig: str
    name: str
    source: str


def output_paths(outdir: str | os.PathLike, name: str, *, csv: bool, preview: bool) -> dict[str, Path]:
    """The files a job writes: ``{"glb": ..., "csv": ..., "preview": ...}`` (the asked ones)."""
    out = Path(outdir)
    paths = {"glb": out / f"{name}.glb"}
    if csv:
        paths["csv"] = out / f"{name}.csv"
    if preview:
        paths["preview"] = out / f"{name}.mp4"
    return paths


def _stem(clip: str) -> str:
    return Path(clip.rstrip("/\\")).stem


def _check_clip(clip: str, where: str) -> str:
    if clip.startswith("camera:"):
        raise ValueError(f"{where}: {clip} is a camera; a batch animates recorded clips")
    return clip


def _check_name(name: str, where: str) -> str:
    if name.lower().endswith(".glb"):
        name = name[:-4]
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        raise ValueError(f"{where}: output name {name!r} must be a plain file name (no folder)")
    return name


def jobs_from_clips(clips: list[str], rig: str | None) -> list[Job]:
    """Jobs of clips given on the command line, all with the one rig."""
    if rig is None:
        raise ValueError("--rig: required with clips on the command line")
    return [Job(clip=_check_clip(str(c), f"argument {k + 1}"), rig=str(rig),
                name=_check_name(_stem(str(c)), f"argument {k + 1} ({c})"), source=f"argument {k + 1}")
            for k, c in enumerate(clips)]


def read_list(path: str | os.PathLike, rig: str | None = None) -> list[Job]:
    """Jobs of a batch list file (see the module notes); ``rig`` for the rows that name none.

    Raises
    ------
    FileNotFoundError
        When the list is missing.
    ValueError
        Naming the line, for a row without a clip, with too many cells, without a rig and no ``rig``, or an
        output name with a folder in it; for a list without a single clip.
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"--list {path}: is a folder, not a list file")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such list file")
    base = path.parent
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(enumerate(csv.reader(f), start=1))
    except (UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{path}: not a CSV text file ({e})") from None
    rows = [(n, [c.strip() for c in r]) for n, r in rows if r and any(c.strip() for c in r)
            and not r[0].lstrip().startswith("#")]
    columns = LIST_COLUMNS
    if rows and "clip" in (c.lower() for c in rows[0][1]):
        n, header = rows.pop(0)
        unknown = [c for c in header if c.lower() not in LIST_COLUMNS]
        if unknown:
            raise ValueError(f"{path}:{n}: unknown column {unknown[0]!r}; the columns are "
                             f"{', '.join(LIST_COLUMNS)}")
        columns = tuple(c.lower() for c in header)
    jobs = []
    for n, row in rows:
        where = f"{path}:{n}"
        if len(row) > len(columns):
            raise ValueError(f"{where}: {len(row)} cells, the list has {len(columns)} columns "
                             f"({', '.join(columns)})")
        cell = dict(zip(columns, row, strict=False))
        clip = cell.get("clip", "")
        if not clip:
            raise ValueError(f"{where}: no clip")
        row_rig = cell.get("rig", "")
        if row_rig:
            row_rig = str(base / row_rig)
        elif rig is not None:
            row_rig = str(rig)
        else:
            raise ValueError(f"{where}: no rig in the row and no --rig")
        clip = str(base / _check_clip(clip, where))
        name = _check_name(cell.get("output", "") or _stem(clip), where)
        jobs.append(Job(clip=clip, rig=row_rig, name=name, source=where))
    if not jobs:
        raise ValueError(f"{path}: no clips in the list")
    return jobs


def check_unique(jobs: list[Job]) -> None:
    """Raise ValueError when two jobs would write the same outputs (same output name, e.g. same clip stem)."""
    seen: dict[str, Job] = {}
    for job in jobs:
        key = os.path.normcase(job.name)
        if key in seen:
            first = seen[key]
            raise ValueError(f"{job.source} ({job.clip}) and {first.source} ({first.clip}) both write "
                             f"{job.name}.glb: give one an output name (list column 'output')")
        seen[key] = job


def file_sha256(path: str | os.PathLike) -> str:
    """sha256 (hex) of a file's bytes, or of an image folder's file names and bytes in name order."""
    h = hashlib.sha256()
    path = Path(path)
    files = sorted(p for p in path.iterdir() if p.is_file()) if path.is_dir() else [path]
    for p in files:
        if path.is_dir():
            h.update(p.name.encode() + b"\0")
        with open(p, "rb") as f:
            while chunk := f.read(_HASH_CHUNK):
                h.update(chunk)
    return h.hexdigest()


def options_sha256(config, *, csv: bool, preview: bool) -> str:
    """sha256 (hex) of what decides a clip's outputs besides clip and rig.

    The :class:`~facepuppet.pipeline.animate.AnimateConfig` (without its progress-bar switch), the contents of
    its profile and model files, the outputs asked for and the facepuppet version.
    """
    d = dataclasses.asdict(config)
    d["tracker"].pop("progress", None)
    for key in ("profile", "model"):
        p = d["tracker"].get(key)
        if p is not None:
            if not Path(p).is_file():
                raise FileNotFoundError(f"--{key}: {p}: no such file")
            d["tracker"][key] = file_sha256(p)
    d["outputs"] = {"csv": bool(csv), "preview": bool(preview)}
    d["version"] = __version__
    text = json.dumps(d, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def check_rigs(jobs: list[Job]) -> dict[str, str]:
    """sha256 of each distinct rig file of the jobs; raise FacepuppetError naming the first job of a missing one
    or of one that is not a rig file of a version this facepuppet reads (its format members alone are read)."""
    from facepuppet._util.npz import check_format, read_npz
    from facepuppet.pipeline.rig import RIG_FORMAT, RIG_VERSION

    hashes: dict[str, str] = {}
    for job in jobs:
        if job.rig in hashes:
            continue
        if not Path(job.rig).is_file():
            raise FacepuppetError(f"{job.source}: rig {job.rig}: no such file")
        try:
            check_format(read_npz(job.rig, "rig file", known=("format", "version")), job.rig, "rig file",
                         RIG_FORMAT, RIG_VERSION)
        except FacepuppetError as e:
            raise FacepuppetError(f"{job.source}: {e}") from e
        hashes[job.rig] = file_sha256(job.rig)
    return hashes
