"""Stopping cleanly on SIGINT, SIGTERM and SIGHUP: a flag set by the signal, acted on where it is safe.

A Python signal handler that raises can land anywhere, also inside numba's dispatcher (the C code around a
compiled kernel), which then fails with ``SystemError: CPUDispatcher(...) returned a result with an exception
set``. Under :func:`handle_signals` the handler only records the signal, then:

- inside :func:`between_frames` (the frame loops) nothing more: the loop calls :func:`check` between frames,
  which raises :class:`Interrupted`;
- elsewhere it raises :class:`Interrupted` at once, unless numba's code is on the stack: then it is raised at
  the next Python call made outside numba (a one-shot trace function).

A second signal while the first is still waiting (numba compiling a kernel for a minute) raises at once.

:class:`Interrupted` is a :class:`KeyboardInterrupt`, so ``except Exception`` does not swallow it and every
``finally`` (temporary files, worker processes) runs. Its exit code is 128 + the signal number.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator

__all__ = ["Interrupted", "handle_signals", "between_frames", "check", "SIGNALS"]

#: The signals that stop a command (those a terminal, ``kill`` and a closed session send).
SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")

_state = {"pending": None, "depth": 0}


class Interrupted(KeyboardInterrupt):
    """A stop asked by a signal; ``signum`` is the signal, ``exit_code`` 128 + it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = int(signum)
        self.exit_code = 128 + self.signum
        try:
            self.name = signal.Signals(self.signum).name
        except ValueError:
            self.name = f"signal {self.signum}"


def check() -> None:
    """Raise :class:`Interrupted` if a signal arrived (call between frames)."""
    signum = _state["pending"]
    if signum is not None:
        _state["pending"] = None
        raise Interrupted(signum)


def _in_numba(frame) -> bool:
    while frame is not None:
        if str(frame.f_globals.get("__name__", "")).startswith("numba"):
            return True
        frame = frame.f_back
    return False


def _raise_later(frame, event, arg):
    if event == "call" and _state["pending"] is not None and not _in_numba(frame):
        sys.settrace(None)
        check()
    return None


def _handler(signum, frame) -> None:
    again = _state["pending"] is not None
    _state["pending"] = signum
    if again:        # a second signal while the first waits (a kernel compiling): stop now
        check()
    if _state["depth"] > 0:
        return
    if _in_numba(frame):
        sys.settrace(_raise_later)
        return
    check()


@contextlib.contextmanager
def handle_signals() -> Iterator[None]:
    """Handle :data:`SIGNALS` as described in the module notes while the block runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for name in SIGNALS:
        sig = getattr(signal, name, None)
        if sig is not None:
            old[sig] = signal.signal(sig, _handler)
    _state["pending"] = None
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        _state["pending"] = None


@contextlib.contextmanager
def between_frames() -> Iterator[None]:
    """A frame loop: signals only set the flag, and the loop calls :func:`check` between frames."""
    _state["depth"] += 1
    try:
        check()
        yield
    finally:
        _state["depth"] -= 1
    check()   # a signal during the last frame
