"""Run a batch: plan the clips (skip the ones up to date), hand the rest to an engine, keep the report.

:func:`run_batch` is what ``facepuppet batch`` calls. Each clip's outputs are written by
:func:`~facepuppet.pipeline.animate.animate` (all or none, under temporary names until the clip ends), so an
interrupted batch leaves finished clips and nothing half written; ``report.csv`` is rewritten atomically after
every clip, and a rerun skips what it lists as done with unchanged content hashes (:mod:`facepuppet.batch.report`).
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from facepuppet._util.interrupt import handle_signals
from facepuppet.batch.engines import ENGINES, RAY_MISSING
from facepuppet.batch.jobs import Job, check_rigs, check_unique, file_sha256, options_sha256, output_paths
from facepuppet.batch.report import Row, can_skip, read_report, write_report
from facepuppet.batch.worker import ClipResult, ClipTask
from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.animate import AnimateConfig

__all__ = ["BatchConfig", "BatchSummary", "run_batch", "longest_first", "REPORT_NAME"]

log = logging.getLogger(__name__)

#: File name of the report in the output folder.
REPORT_NAME = "report.csv"


@dataclass(frozen=True, kw_only=True)
class BatchConfig:
    """Options of :func:`run_batch`.

    Attributes
    ----------
    animate : AnimateConfig or None
        How every clip is tracked and mapped (as ``facepuppet animate`` takes it); None: the defaults.
    csv, preview : bool
        Also write ``<name>.csv`` / ``<name>.mp4`` beside each ``<name>.glb``.
    engine : str
        ``"local"`` (worker processes here) or ``"ray"``.
    workers : int or None
        Worker processes (local; None: ``os.cpu_count()``) or Ray actors (None: one per CPU of the cluster, or
        ``os.cpu_count()`` CPUs of the local Ray runtime the batch starts).
    address : str or None
        Ray cluster to connect to (``ray`` engine); None starts a local one.
    progress : bool or None
        The progress bar; None shows it when stderr is a terminal.
    """

    animate: AnimateConfig | None = None
    csv: bool = False
    preview: bool = False
    engine: str = "local"
    workers: int | None = None
    address: str | None = None
    progress: bool | None = None


@dataclass(frozen=True)
class BatchSummary:
    """How a batch went: its report rows (job order), the report's path and the wall time in seconds."""

    rows: list[Row]
    report: Path
    seconds: float
    counts: dict = field(default_factory=dict)

    @property
    def failed(self) -> int:
        return sum(r.status == "failed" for r in self.rows)

    @property
    def frames(self) -> int:
        """Frames animated by this run (done clips)."""
        return sum(r.frames for r in self.rows if r.status == "done")


def _frame_count(clip: str) -> int:
    """The clip's frame count for the progress bar and the order of the clips: the video container's (read
    without decoding), else the frame source's (a folder of images), 0 for a clip that cannot be read."""
    from facepuppet.io.frames import container_frame_count, open_media

    count = container_frame_count(clip)
    if count is not None:
        return count
    try:
        with open_media(clip) as source:
            return int(source.frame_count or 0)
    except Exception:           # noqa: BLE001 - an unreadable clip fails in its worker, with its message
        return 0


def longest_first(tasks: list[ClipTask], frames: dict[int, int]) -> list[ClipTask]:
    """The tasks by their clips' frame counts (``frames``: task index -> frames), longest first, ties in job order.

    Workers take the next clip as they finish one, so the last clips handed out decide how long the others
    wait at the end: with the short ones last, the workers finish close together.
    """
    return sorted(tasks, key=lambda t: -frames.get(t.index, 0))


def run_batch(jobs: list[Job], outdir: str | os.PathLike, config: BatchConfig) -> BatchSummary:
    """Animate every job's clip into ``outdir`` and write ``outdir/report.csv``.

    Parameters
    ----------
    jobs : list of Job
        From :func:`~facepuppet.batch.jobs.jobs_from_clips` or :func:`~facepuppet.batch.jobs.read_list`.
    outdir : str or PathLike
        Output folder (made if missing).
    config : BatchConfig

    Returns
    -------
    BatchSummary
        Failed clips are rows with ``status="failed"`` and their error; nothing is raised for them.

    Raises
    ------
    ValueError, FileNotFoundError, FacepuppetError
        Before anything runs: two jobs writing the same outputs, a missing rig, profile or model, an unknown
        engine. :class:`~facepuppet._util.interrupt.Interrupted` (a ``KeyboardInterrupt``) on Ctrl-C, SIGTERM
        or SIGHUP, after the workers ended.
    """
    if config.engine not in ENGINES:
        raise ValueError(f"--engine: {config.engine!r} is not one of {', '.join(ENGINES)}")
    if config.engine == "ray" and importlib.util.find_spec("ray") is None:
        raise FacepuppetError(RAY_MISSING)
    animate_config = config.animate or AnimateConfig()
    check_unique(jobs)
    rig_hashes = check_rigs(jobs)
    options = options_sha256(animate_config, csv=config.csv, preview=config.preview)
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise NotADirectoryError(f"-o {outdir}: is a file, not a folder")
    outdir.mkdir(parents=True, exist_ok=True)
    report = outdir / REPORT_NAME
    previous = read_report(report)
    t0 = time.perf_counter()
    with _engine_session(config, jobs, previous, outdir) as session:
        rows, tasks, expected = _plan(jobs, outdir, config, animate_config, previous,
                                      rig_hashes=rig_hashes, options=options)

        def finished() -> list[Row]:
            return [r for r in rows if r.status]

        write_report(report, finished())
        seen = dict.fromkeys(expected, 0)
        counts = {"done": 0, "failed": 0, "skipped": sum(r.status == "skipped" for r in finished())}

        from tqdm import tqdm

        show = config.progress if config.progress is not None else sys.stderr.isatty()
        with tqdm(total=sum(expected.values()), unit="frame", desc="batch", disable=not show or not tasks,
                  dynamic_ncols=True) as bar:
            bar.set_postfix(counts)

            def on_progress(index: int, frames: int) -> None:
                seen[index] = seen.get(index, 0) + frames
                bar.update(frames)

            def on_result(result: ClipResult) -> None:
                i = result.index
                short = expected[i] - seen.get(i, 0)
                if short:           # the container's count was off, or the clip failed part way
                    bar.total = max(bar.n, bar.total - short)
                    bar.refresh()
                status = "done" if result.ok else "failed"
                counts[status] += 1
                rows[i] = replace(rows[i], status=status, frames=result.frames,
                                  frames_with_face=result.frames_with_face, seconds=result.seconds, error=result.error)
                if not result.ok:
                    log.warning("%s", result.error)
                write_report(report, finished())
                bar.set_postfix(counts)

            runner = ENGINES[config.engine]
            with handle_signals():
                runner(longest_first(tasks, expected), workers=config.workers, address=config.address,
                       on_progress=on_progress, on_result=on_result, **_given(session=session))
        done = finished()
        return BatchSummary(done, report, time.perf_counter() - t0, counts)


def _given(**options) -> dict:
    """The options that are not None."""
    return {k: v for k, v in options.items() if v is not None}


def _plan(jobs: list[Job], outdir: Path, config: BatchConfig, animate_config: AnimateConfig, previous: dict, *,
          rig_hashes: dict, options: str) -> tuple[list[Row], list[ClipTask], dict[int, int]]:
    """Each job's row (``skipped`` when the report lists it done with these hashes and its outputs exist, else a
    row still to fill), the tasks of the jobs to run and their clips' frame counts (task index -> frames)."""
    rows: list[Row] = []
    tasks: list[ClipTask] = []
    expected: dict[int, int] = {}
    for i, job in enumerate(jobs):
        outputs = output_paths(outdir, job.name, csv=config.csv, preview=config.preview)
        clip_sha = file_sha256(job.clip) if os.path.exists(job.clip) else ""
        base = Row(clip=job.clip, output=job.name, rig=job.rig, status="", clip_sha256=clip_sha,
                   rig_sha256=rig_hashes[job.rig], options_sha256=options)
        skipped = can_skip(previous.get(job.name), clip_sha256=clip_sha, rig_sha256=base.rig_sha256,
                           options_sha256=options, outputs=list(outputs.values()))
        if skipped is not None:
            rows.append(replace(base, status="skipped", frames=skipped.frames,
                                frames_with_face=skipped.frames_with_face, seconds=skipped.seconds))
            continue
        rows.append(base)
        tasks.append(ClipTask(index=i, clip=job.clip, rig=job.rig, rig_sha256=base.rig_sha256,
                              outputs={k: str(v) for k, v in outputs.items()}, config=animate_config))
        expected[i] = _frame_count(job.clip)
    return rows, tasks, expected


@contextlib.contextmanager
def _engine_session(config: BatchConfig, jobs: list[Job], previous: dict, outdir: Path):
    """The Ray engine's session (:class:`~facepuppet.batch.ray_engine.RaySession`), opened before the clips are
    hashed so that its actors start meanwhile, and closed at the end; it asks for one actor at most per clip that
    the report does not list as done with its outputs in place. None for the local engine, and when every clip
    looks done: a rerun with nothing to do connects to no cluster (should the hashes say otherwise, the engine
    opens its own session)."""
    todo = [] if config.engine != "ray" else [j for j in jobs if not _looks_done(previous.get(j.name), outdir, j,
                                                                                   config)]
    if not todo:
        yield None
        return
    from facepuppet.batch.ray_engine import RaySession

    session = RaySession(workers=config.workers, address=config.address, most=len(todo),
                         warm=(config.animate or AnimateConfig()).tracker)
    try:
        yield session
    finally:
        session.close()


def _looks_done(row: Row | None, outdir: Path, job: Job, config: BatchConfig) -> bool:
    """Whether the report's row says the job is done and its outputs exist (the hashes are not looked at)."""
    return (row is not None and row.status in ("done", "skipped")
            and all(p.is_file() for p in output_paths(outdir, job.name, csv=config.csv,
                                                     preview=config.preview).values()))
