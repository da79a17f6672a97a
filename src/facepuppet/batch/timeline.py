"""Where an engine's time goes: its start-up, each worker's clips and the gaps between them, its ending.

An engine fills one :class:`Timeline` as it runs (the worker side's moments come back as wall-clock times,
``time.time()``, which every node of a cluster keeps close to the others) and logs its summary at INFO level
(``facepuppet -v batch ...``), one line per item, each starting with :data:`TIMELINE_PREFIX`: seconds from the
engine's start. ``benchmarks/bench_batch.py`` prints these lines beside its timings.
"""

from __future__ import annotations

import logging
import os
import time

__all__ = ["Timeline", "TIMELINE_PREFIX", "process_start_time"]

log = logging.getLogger(__name__)

#: How every line of a timeline starts.
TIMELINE_PREFIX = "timeline:"


def process_start_time() -> float | None:
    """Wall-clock time (``time.time()``) at which this process started, from Linux's /proc (10 ms steps); None
    where it cannot be read."""
    try:
        with open("/proc/self/stat") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    return time.time() - uptime + ticks / os.sysconf("SC_CLK_TCK")


class Timeline:
    """Moments of one engine run, in seconds from its start (``time.time()`` when made; the process's own start
    is the first mark, before 0).

    ``mark(what)`` notes a moment of the driver; ``worker(name, times)`` a worker's start-up (wall-clock times
    of its named steps, in order); ``clip(worker, started, seconds)`` a finished clip (wall-clock start, length).
    :meth:`lines` gives the summary: the marks, each worker's start-up steps, each worker's clips (count,
    first start, last end, busy seconds and the idle gaps between its clips) and the end.
    """

    def __init__(self, engine: str) -> None:
        self.engine = engine
        self.t0 = time.time()
        self.marks: list[tuple[float, str]] = []
        self.workers: dict[str, list[tuple[str, float]]] = {}
        self.clips: dict[str, list[tuple[float, float]]] = {}
        began = process_start_time()
        if began is not None:
            self.marks.append((self.at(began), "this process started"))

    @staticmethod
    def wanted() -> bool:
        """Whether the timeline is logged (INFO enabled): what only it needs can be left undone otherwise."""
        return log.isEnabledFor(logging.INFO)

    def at(self, wall: float) -> float:
        """Seconds from the start of a wall-clock time."""
        return wall - self.t0

    def mark(self, what: str) -> None:
        self.marks.append((self.at(time.time()), what))

    def worker(self, name: str, times: list[tuple[str, float | None]]) -> None:
        self.workers[name] = [(step, t) for step, t in times if t is not None]

    def clip(self, worker: str, started: float, seconds: float) -> None:
        if started > 0:
            self.clips.setdefault(worker, []).append((started, started + seconds))

    def lines(self) -> list[str]:
        out = [f"{TIMELINE_PREFIX} {self.engine} {t:7.2f} s  {what}" for t, what in self.marks]
        for name, steps in self.workers.items():
            text = ", ".join(f"{step} {self.at(t):.2f}" for step, t in steps)
            out.append(f"{TIMELINE_PREFIX} {self.engine} worker {name} start-up (s): {text}")
        for name, spans in sorted(self.clips.items()):
            spans.sort()
            busy = sum(b - a for a, b in spans)
            gaps = sum(max(0.0, spans[k + 1][0] - spans[k][1]) for k in range(len(spans) - 1))
            out.append(f"{TIMELINE_PREFIX} {self.engine} worker {name}: {len(spans)} clips from "
                       f"{self.at(spans[0][0]):.2f} to {self.at(spans[-1][1]):.2f} s, busy {busy:.2f} s, "
                       f"idle between clips {gaps:.2f} s")
        return out

    def log(self) -> None:
        for line in self.lines():
            log.info("%s", line)
