"""three.js (npm package ``three``) for tests: load a GLB as a page would and play its animation.

Installed on first use into the tests' npm cache folder (:mod:`node_packages`); without npm, or when the
install fails, a test that needs it skips, and fails in CI (``conftest.need``). The work is done by
``three_load.mjs`` (its header says what it prints).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest

from node_packages import need_package

THREE_VERSION = "0.187.0"
SCRIPT = Path(__file__).with_name("three_load.mjs")


class ThreeLoader:
    """Runs ``three_load.mjs`` on a file."""

    def __init__(self, prefix: Path) -> None:
        self.prefix = prefix

    def play(self, path: str | os.PathLike, times: Sequence[float] = (), clip: str | None = None) -> dict:
        """Load ``path`` with GLTFLoader, play its first animation (or the one named ``clip``) to each of
        ``times`` (ascending, seconds).

        Returns the script's report: ``meshes``, ``clips`` and one entry of ``samples`` per time.
        """
        args = [shutil.which("node"), str(SCRIPT), str(self.prefix), str(path), *(repr(float(t)) for t in times)]
        env = dict(os.environ, **({"FP_CLIP": clip} if clip else {}))
        done = subprocess.run(args, capture_output=True, text=True, timeout=120, env=env)
        assert done.returncode == 0, f"three.js could not load {path}: {done.stderr.strip()}"
        return json.loads(done.stdout)


@pytest.fixture(scope="session")
def three_loader(request) -> ThreeLoader:
    """three.js, installed on first use (skips without npm; fails in CI).

    Test modules import this fixture: ``from three_loader import three_loader``.
    """
    return ThreeLoader(need_package(request, "three", THREE_VERSION, "three.js"))
