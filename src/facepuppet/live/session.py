"""``facepuppet live``: the stream of :mod:`facepuppet.pipeline.stream` with a camera in and senders out.

A session opens the source (``camera:N``, or a video file or image folder standing in for a camera), paces it
(:mod:`facepuppet.live.source`), and runs every frame through tracker, mapper, smoothing and gain into its
outputs as it comes: the live senders (browser viewer, VMC, Live Link Face), an optional recording (GLB and CSV,
exactly as ``facepuppet animate`` writes them, the frames as captured) and the session's statistics.

It ends at the source's end, at ``max_frames``, on Ctrl+C, SIGTERM or SIGHUP, or on ``q`` in the terminal;
the recording is then finished and committed (all of its files or none). ``n`` in the terminal (or the
viewer's button) takes the current face as the performer's neutral for the session
(:meth:`~facepuppet.pipeline.stream.FrameMapper.rezero`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

from facepuppet.errors import FacepuppetError
from facepuppet.live.frame import LiveFrame
from facepuppet.live.source import LiveSource
from facepuppet.live.stats import LatencyStats
from facepuppet.pipeline.gain import GainConfig
from facepuppet.pipeline.smoothing import SmoothingConfig
from facepuppet.pipeline.stream import FrameMapper, StreamFrame, run_stream

__all__ = ["LiveConfig", "LiveResult", "run_live"]

log = logging.getLogger(__name__)

#: Seconds between two updates of the status line.
STATUS_PERIOD = 0.25
#: Terminal keys: take the current face as neutral, quit.
KEY_NEUTRAL, KEY_QUIT = "n", "q"
#: Frames the status line's rate is measured over.
STATUS_WINDOW = 30


@dataclass(frozen=True, kw_only=True)
class LiveConfig:
    """Options of a live session.

    Attributes
    ----------
    tracker : TrackerOptions
        Backend, colour-tracker profile, MediaPipe model.
    smoothing : SmoothingConfig
    gain : GainConfig
    head_rotation : bool
        Send and record the head's rotation.
    pace : {"realtime", "fast"}
        See :mod:`facepuppet.live.source`.
    max_frames : int or None
        Stop after this many frames of the source.
    status : bool
        Keep a one-line status on stderr (only when it is a terminal).
    keys : bool
        Read ``n`` (neutral) and ``q`` (quit) from the terminal (only when stdin is one).
    """

    tracker: object = None
    smoothing: SmoothingConfig = field(default_factory=SmoothingConfig)
    gain: GainConfig = field(default_factory=GainConfig)
    head_rotation: bool = True
    pace: str = "realtime"
    max_frames: int | None = None
    status: bool = True
    keys: bool = True


@dataclass
class LiveResult:
    """What a session did: frames through the chain, frames with a face, frames dropped, latency, rate."""

    frames: int
    with_face: int
    dropped: int
    seconds: float
    stats: dict


class _SenderOutput:
    """The live senders as one stream output: each frame becomes a :class:`~facepuppet.live.frame.LiveFrame`
    and goes to every sender; a sender that fails is reported once and then left out."""

    def __init__(self, senders: Sequence, names: Sequence[str], head_rotation: bool) -> None:
        self.senders = list(senders)
        self.names = tuple(names)
        self.head_rotation = head_rotation
        self.failed: set[int] = set()

    def write(self, frame: StreamFrame) -> None:
        live = LiveFrame(index=frame.index, time=frame.time, timestamp=frame.captured, weights=frame.weights,
                         names=self.names, head_rotation=frame.rotation if self.head_rotation else None,
                         valid=frame.valid, curves=frame.features.curves, image=frame.rgb)
        for i, sender in enumerate(self.senders):
            if i in self.failed:
                continue
            try:
                sender.send(live)
            except OSError as e:
                self.failed.add(i)
                log.warning("%s: stopped sending (%s)", type(sender).__name__, e)

    def neutral_requested(self) -> bool:
        """True when a sender (the viewer's button) asked for a neutral re-zero since the last call."""
        return any(s.neutral_requested() for s in self.senders if hasattr(s, "neutral_requested"))

    def finish(self) -> None:
        pass


class _Status:
    """The one-line status on stderr, and the session's statistics."""

    def __init__(self, stats: LatencyStats, live: LiveSource, show: bool, after=None) -> None:
        self.stats, self.live, self.after = stats, live, after
        self.show = show and sys.stderr.isatty()
        self._next = 0.0
        self._recent: deque[float] = deque(maxlen=STATUS_WINDOW)

    def __call__(self, frame: StreamFrame) -> None:
        now = time.perf_counter()
        self.stats.add(now - frame.captured, now)
        self._recent.append(now)
        if self.after is not None:
            self.after()
        if self.show and now >= self._next:
            self._next = now + STATUS_PERIOD
            span = self._recent[-1] - self._recent[0]
            fps = (len(self._recent) - 1) / span if span > 0 else 0.0
            p50, p95 = (self.stats.percentile(q) * 1e3 for q in (50, 95))
            line = (f"live: {fps:5.1f} fps  latency p50 {p50:5.1f} ms  p95 {p95:5.1f} ms  "
                    f"face {'yes' if frame.valid else 'no '}  dropped {self.live.dropped}  "
                    f"frames {self.stats.frames}  [n neutral, q quit]")
            sys.stderr.write("\r" + line + "\x1b[K")
            sys.stderr.flush()

    def close(self) -> None:
        if self.show:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()


@contextlib.contextmanager
def _stop_on_signals(live: LiveSource):
    """SIGINT, SIGTERM and SIGHUP end the session cleanly (between frames, never inside a kernel)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    names = ("SIGINT", "SIGTERM", "SIGHUP")
    old = {}
    for name in names:
        sig = getattr(signal, name, None)
        if sig is not None:
            old[sig] = signal.signal(sig, lambda *_: live.stop())
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def _terminal_keys(enabled: bool, on_key):
    """Read single key presses from a terminal stdin in a thread (no echo, no Enter needed)."""
    if not enabled or not sys.stdin.isatty():
        yield
        return
    try:
        import termios
        import tty
    except ImportError:            # not a POSIX terminal
        yield
        return
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    done = threading.Event()

    def read() -> None:
        import select

        while not done.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if ready:
                ch = os.read(fd, 1).decode(errors="ignore")
                if ch:
                    on_key(ch)

    tty.setcbreak(fd)
    thread = threading.Thread(target=read, name="facepuppet-live-keys", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join(timeout=0.5)
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def run_live(source: str | os.PathLike, rig, *, config: LiveConfig | None = None,
             record: str | os.PathLike | None = None, csv: str | os.PathLike | None = None,
             stats: str | os.PathLike | None = None, senders: Sequence = (), on_rezero=None,
             on_start=None) -> LiveResult:
    """Run a live session (see the module notes).

    Parameters
    ----------
    source : str or PathLike or MediaSource
        ``camera:N``, or a video file or image folder standing in for a camera; or a source opened by the
        caller (then not closed here).
    rig : Rig or str or PathLike
        The rig (``facepuppet rig``) or its file.
    config : LiveConfig, optional
    record, csv : str or PathLike, optional
        Record the session as an animated GLB and as CSV (as ``facepuppet animate`` writes them).
    stats : str or PathLike, optional
        Write the session's statistics as JSON: ``frames``, ``dropped``, ``latency_ms`` (``p50``, ``p95``,
        ``p99``, ``max``: from frame read to the last output), ``fps``.
    senders : sequence of facepuppet.live.frame.Sender
        Live outputs, each given every frame as a LiveFrame; a sender with ``neutral_requested()`` (the
        viewer's button) can ask for the session's neutral re-zero. Not closed here.
    on_rezero : callable, optional
        Called after a re-zero was asked for (tests, logging).
    on_start : callable, optional
        Called once, when the first frame has gone through the chain.

    Returns
    -------
    LiveResult
        A session stopped before its first frame returns ``frames == 0`` and writes nothing.
    """
    from facepuppet.pipeline.outputs import check_suffix
    from facepuppet.pipeline.tracking import TrackerOptions

    for out, kind in ((record, "animated character"), (csv, "weights CSV")):
        if out is not None:
            check_suffix(out, kind)  # before the camera opens
    config = config or LiveConfig()
    tracker_options = config.tracker or TrackerOptions()
    rig_label = "rig"
    if isinstance(rig, (str, os.PathLike)):
        from facepuppet.pipeline.rig import load_rig

        rig, rig_label = load_rig(rig), str(rig)
    if senders and getattr(rig, "regional", False):
        raise FacepuppetError(f"{rig_label}: a regional rig's weights are per region and key-model, which the live "
                              f"senders cannot carry; record it (--record, --csv) or rig without --method regional")
    mapper = FrameMapper(rig, smoothing=config.smoothing, gain=config.gain, rig_label=rig_label)

    def rezero() -> None:
        mapper.request_rezero()
        if on_rezero is not None:
            on_rezero()

    try:
        return _session(source, rig, rig_label, mapper, tracker_options, config, record, csv, stats, senders,
                        rezero, on_start)
    except _StoppedBeforeStart as e:
        log.warning("%s: stopped before the first frame; nothing recorded", source)
        return e.result


class _StoppedBeforeStart(Exception):
    """The session was stopped before any frame went through (its outputs are then dropped)."""

    def __init__(self, result: LiveResult) -> None:
        super().__init__("stopped before the first frame")
        self.result = result


def _session(source, rig, rig_label, mapper, tracker_options, config, record, csv, stats, senders, rezero,
             on_start) -> LiveResult:
    from facepuppet.io.frames import open_media
    from facepuppet.pipeline.outputs import CsvOutput, GlbOutput
    from facepuppet.pipeline.tracking import make_tracker_for

    with contextlib.ExitStack() as stack:
        media = stack.enter_context(open_media(source)) if isinstance(source, (str, os.PathLike)) else source
        tracker = make_tracker_for(tracker_options, source)
        stack.callback(tracker.close)

        def warmup(rgb) -> None:
            """A throwaway tracker on the first frame: the compiled kernels load before the clock starts."""
            spare = make_tracker_for(tracker_options, source)
            try:
                spare.track(rgb, 0)
            finally:
                spare.close()

        live = LiveSource(media, pace=config.pace, max_frames=config.max_frames,
                          warmup=warmup if config.pace == "realtime" else None)
        sending = _SenderOutput(senders, rig.names, config.head_rotation)
        outputs: list = [sending] if senders else []
        fps = float(media.fps)
        if record is not None:
            outputs.append(GlbOutput(record, rig, stack, head_rotation=config.head_rotation, fps=fps))
        if csv is not None:
            outputs.append(CsvOutput(csv, rig, stack, head_rotation=config.head_rotation, fps=fps))
        latency = LatencyStats()

        def after_frame() -> None:
            if latency.frames == 1 and on_start is not None:
                on_start()
            if senders and sending.neutral_requested():
                rezero()

        status = _Status(latency, live, config.status, after_frame)
        stack.callback(status.close)

        def on_key(ch: str) -> None:
            if ch.lower() == KEY_NEUTRAL:
                rezero()
            elif ch.lower() == KEY_QUIT:
                live.stop()

        from facepuppet.capture.curves import POINT_NAMES

        with _stop_on_signals(live), _terminal_keys(config.keys, on_key):
            try:
                summary = run_stream(live, tracker, mapper, outputs, on_frame=status, point_names=POINT_NAMES)
            except FacepuppetError:
                if live.stopped and latency.frames == 0 and not live.error:
                    raise _StoppedBeforeStart(LiveResult(0, 0, live.dropped, 0.0, latency.summary())) from None
                raise
            if live.stopped and summary.frames == 0 and not live.error:
                raise _StoppedBeforeStart(LiveResult(0, 0, live.dropped, 0.0, latency.summary()))
        if live.error:
            raise FacepuppetError(live.error)
        if summary.frames == 0:
            raise FacepuppetError(f"{source}: no frames were read")
        latency.drop(live.dropped)
        result = LiveResult(summary.frames, summary.with_face, live.dropped, summary.seconds, latency.summary())
        if stats is not None:
            latency.write(stats)
    return result
