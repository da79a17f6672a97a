"""The demo's clean-up ends its own kernel workers only: a caller's other children are left alone."""

from __future__ import annotations

import subprocess
import sys
import time

from facepuppet.cli._demo import end_children


def test_end_children_leaves_other_children_alone():
    # a child that ignores SIGTERM, like multiprocessing's resource tracker in a test run
    other = subprocess.Popen([sys.executable, "-c", "import signal, time; signal.signal(signal.SIGTERM, "
                              "signal.SIG_IGN); time.sleep(30)"])
    try:
        time.sleep(0.3)
        t0 = time.monotonic()
        end_children()
        assert time.monotonic() - t0 < 2.0          # no wait on a child it did not start
        assert other.poll() is None                 # still running
    finally:
        other.kill()
        other.wait()


def test_end_children_ends_the_kernel_workers():
    worker = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)", "facepuppet.capture.color."
                               "precompile"])
    time.sleep(0.3)
    end_children()
    assert worker.poll() is not None
