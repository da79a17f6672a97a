"""A batch's report, ``OUTDIR/report.csv``: one row per clip, rewritten atomically as clips finish.

Columns (:data:`REPORT_COLUMNS`): ``clip``, ``output`` (the outputs' name), ``rig``, ``status`` (``done``,
``failed`` or ``skipped``), ``frames``, ``frames_with_face``, ``seconds`` (wall time of the clip in its
worker), ``error`` (one line, failed clips only), ``clip_sha256``, ``rig_sha256``, ``options_sha256`` (content
hashes, :mod:`facepuppet.batch.jobs`). A rerun skips a clip whose row says done or skipped, whose outputs all
exist and whose three hashes are unchanged; a skipped row keeps the frames and seconds of the run that did it.
"""

from __future__ import annotations

import csv
import os
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

from facepuppet._util.atomic import atomic_path

__all__ = ["Row", "REPORT_COLUMNS", "STATUSES", "read_report", "write_report", "can_skip"]

#: Status of a clip in the report: outputs written by this run, failed (see ``error``), already up to date.
STATUSES = ("done", "failed", "skipped")


@dataclass(frozen=True, kw_only=True)
class Row:
    """One clip's line of the report (see the module notes for the columns)."""

    clip: str
    output: str
    rig: str
    status: str
    frames: int = 0
    frames_with_face: int = 0
    seconds: float = 0.0
    error: str = ""
    clip_sha256: str = ""
    rig_sha256: str = ""
    options_sha256: str = ""


#: The report's columns, in order.
REPORT_COLUMNS = tuple(f.name for f in fields(Row))


def write_report(path: str | os.PathLike, rows: list[Row]) -> None:
    """Write the report atomically (a reader sees the old one or the new one, never half of one)."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=REPORT_COLUMNS, lineterminator="\n")
            w.writeheader()
            for row in rows:
                d = asdict(row)
                d["seconds"] = f"{row.seconds:.3f}"
                w.writerow(d)


def read_report(path: str | os.PathLike) -> dict[str, Row]:
    """The rows of an earlier report by output name; empty when there is none or it cannot be read."""
    path = Path(path)
    if not path.is_file():
        return {}
    rows: dict[str, Row] = {}
    try:
        with open(path, newline="", encoding="utf-8") as f:
            for d in csv.DictReader(f):
                if not d.get("output"):
                    continue
                rows[d["output"]] = Row(
                    clip=d.get("clip", ""), output=d["output"], rig=d.get("rig", ""), status=d.get("status", ""),
                    frames=int(d.get("frames") or 0), frames_with_face=int(d.get("frames_with_face") or 0),
                    seconds=float(d.get("seconds") or 0.0), error=d.get("error", "") or "",
                    clip_sha256=d.get("clip_sha256", "") or "", rig_sha256=d.get("rig_sha256", "") or "",
                    options_sha256=d.get("options_sha256", "") or "")
    except (OSError, ValueError, csv.Error, UnicodeDecodeError):
        return {}           # an unreadable report resumes nothing: every clip is done again
    return rows


def can_skip(previous: Row | None, *, clip_sha256: str, rig_sha256: str, options_sha256: str,
             outputs: list[Path]) -> Row | None:
    """The skipped row for a clip already done with these inputs and options, or None when it must be done."""
    if previous is None or previous.status not in ("done", "skipped"):
        return None
    if (previous.clip_sha256, previous.rig_sha256, previous.options_sha256) != (
            clip_sha256, rig_sha256, options_sha256):
        return None
    if not all(p.is_file() for p in outputs):
        return None
    return replace(previous, status="skipped", error="")
