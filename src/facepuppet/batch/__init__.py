"""Many performances at once: ``facepuppet batch`` on worker processes here or on a Ray cluster.

:func:`run_batch` animates a list of :class:`Job` (clips, each with a rig and an output name) into one folder,
each clip exactly as :func:`facepuppet.pipeline.animate.animate` writes it, keeps ``report.csv`` up to date and
skips on a rerun the clips already done with the same inputs (content hashes). See ``docs/batch.md``.
"""

from facepuppet.batch.jobs import LIST_COLUMNS, Job, jobs_from_clips, read_list
from facepuppet.batch.report import REPORT_COLUMNS, Row, read_report
from facepuppet.batch.run import REPORT_NAME, BatchConfig, BatchSummary, run_batch
from facepuppet.batch.worker import ClipResult, ClipTask, run_clip

__all__ = ["Job", "LIST_COLUMNS", "jobs_from_clips", "read_list", "Row", "REPORT_COLUMNS", "read_report",
           "BatchConfig", "BatchSummary", "run_batch", "REPORT_NAME", "ClipTask", "ClipResult", "run_clip"]
