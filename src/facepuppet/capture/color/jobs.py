"""Background compile jobs this process started and has not waited for (:func:`~.precompile.precompile`).

A :class:`~facepuppet.capture.color.tracker.ColorTracker` waits for them (:func:`wait_pending`) before its first
frame: compiling the same kernels in two processes at once only slows both.
"""

from __future__ import annotations

from typing import Protocol

__all__ = ["Job", "add", "discard", "pending", "wait_pending"]


class Job(Protocol):
    """Something to wait for."""

    def wait(self) -> object: ...


_PENDING: list[Job] = []


def add(job: Job) -> None:
    """Register a job started in this process."""
    _PENDING.append(job)


def discard(job: Job) -> None:
    """Forget a job (it has been waited for)."""
    if job in _PENDING:
        _PENDING.remove(job)


def pending() -> tuple[Job, ...]:
    """The jobs not yet waited for, oldest first."""
    return tuple(_PENDING)


def wait_pending() -> None:
    """Wait for every registered job (each job's ``wait`` discards it)."""
    while _PENDING:
        job = _PENDING[-1]
        job.wait()
        discard(job)
