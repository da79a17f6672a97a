"""Blender for tests: the ``bpy`` module from PyPI in its own venv, and ``blender_load.py`` run there.

``bpy`` needs one Python version (3.11 for bpy 5.0) and numpy < 2, so it cannot share the project's venv: it
gets a venv of its own in the tests' cache folder, ``~/.cache/facepuppet-tests/blender`` (``$FACEPUPPET_TEST_CACHE``
moves it, as for :mod:`node_packages`), made on first use with the running Python when it is 3.11, else with a
``python3.11`` on the PATH. bpy is pinned and reinstalled when the version found there is another (about 1 GB,
half a minute). When it cannot be had, the test that asked skips, and fails in CI (``conftest.need``).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pytest

BPY_VERSION = "5.0.1"
#: The Python that bpy BPY_VERSION is built for.
PYTHON = (3, 11)
SCRIPT = Path(__file__).with_name("blender_load.py")


def venv_dir() -> Path:
    base = os.environ.get("FACEPUPPET_TEST_CACHE", Path.home() / ".cache" / "facepuppet-tests")
    return Path(base) / "blender"


def venv_python(venv: Path) -> Path:
    return venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def installed_version(venv: Path) -> str | None:
    """The version of bpy in ``venv``, from its dist-info folder (no import: bpy takes a second to load)."""
    found = [*venv.glob("lib/python3*/site-packages/bpy-*.dist-info"), *venv.glob("Lib/site-packages/bpy-*.dist-info")]
    versions = {re.fullmatch(r"bpy-(.+)\.dist-info", p.name).group(1) for p in found}
    return versions.pop() if len(versions) == 1 else None


def python_version(python: Path) -> tuple[int, int] | None:
    try:
        done = subprocess.run([str(python), "-c", "import sys; print(*sys.version_info[:2])"],
                              capture_output=True, text=True, timeout=60)
        return tuple(int(x) for x in done.stdout.split()) if done.returncode == 0 else None
    except (OSError, ValueError, subprocess.TimeoutExpired):
        return None


def base_python() -> str | None:
    """A Python of version PYTHON to make the venv with: the running one, else ``python3.11`` on the PATH."""
    if sys.version_info[:2] == PYTHON:
        return sys.executable
    return shutil.which("python{}.{}".format(*PYTHON))


@contextlib.contextmanager
def locked(path: Path):
    """Hold an exclusive lock on ``path`` (two test sessions must not install into one venv at once)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    with open(path, "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def install(version: str = BPY_VERSION) -> tuple[Path | None, str]:
    """Make the venv with ``bpy==version`` unless it is there; return its Python (or None) and why not."""
    venv = venv_dir()
    venv.parent.mkdir(parents=True, exist_ok=True)
    with locked(venv.parent / "blender.lock"):
        python = venv_python(venv)
        if python_version(python) != PYTHON:
            base = base_python()
            if base is None:
                return None, "bpy {} needs Python {}.{}, which was not found".format(version, *PYTHON)
            done = subprocess.run([base, "-m", "venv", "--clear", str(venv)], capture_output=True, text=True,
                                  timeout=300)
            if done.returncode != 0:
                return None, f"cannot make a venv at {venv}: {_last_line(done.stderr)}"
        if installed_version(venv) == version:
            return python, ""
        try:
            done = subprocess.run([str(python), "-m", "pip", "install", "--disable-pip-version-check", "--no-input",
                                   f"bpy=={version}"], capture_output=True, text=True, timeout=1200)
        except subprocess.TimeoutExpired:
            return None, f"pip install bpy=={version} took more than 20 minutes"
        if installed_version(venv) != version:
            return None, f"pip install bpy=={version} failed: {_last_line(done.stderr or done.stdout)}"
        return python, ""


def _last_line(text: str) -> str:
    """The last error line of a tool's output (pip warns after its error), else its last line."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("ERROR")]
    return (errors or lines or ["no message"])[-1]


class Blender:
    """Runs ``blender_load.py`` in the bpy venv: imports glTF files as Blender does and reports what it sees."""

    def __init__(self, python: Path) -> None:
        self.python = python

    def load(self, path: str | os.PathLike, fps: int, frames: Sequence[float] = ()) -> dict:
        """Import ``path`` into an empty scene at ``fps`` frames per second; sample it at ``frames``.

        Returns the script's report (its docstring says what it holds).
        """
        (report,) = self.load_all([(path, fps, frames)])
        return report

    def load_all(self, files: Sequence[tuple[str | os.PathLike, int, Sequence[float]]]) -> list[dict]:
        """:meth:`load` on several files in one Blender process (each into its own empty scene)."""
        with tempfile.TemporaryDirectory(prefix="facepuppet-blender-") as tmp:
            request, out = Path(tmp) / "request.json", Path(tmp) / "report.json"
            request.write_text(json.dumps({"out": str(out), "files": [
                {"path": str(Path(p).resolve()), "fps": fps, "frames": [float(f) for f in frames]}
                for p, fps, frames in files]}))
            done = subprocess.run([str(self.python), str(SCRIPT), str(request)], capture_output=True, text=True,
                                  timeout=300)
            assert done.returncode == 0 and out.is_file(), \
                f"Blender could not load {[str(p) for p, _, _ in files]}: {_last_line(done.stderr)}"
            return json.loads(out.read_text())


@pytest.fixture(scope="session")
def blender(request) -> Blender:
    """Blender (bpy BPY_VERSION in its own venv), installed on first use (skips without it; fails in CI).

    Test modules import this fixture: ``from blender_python import blender``.
    """
    # tests/conftest.py is registered under its path; take its need() (skip, or fail in CI)
    root_conftest = request.config.pluginmanager.get_plugin(str(Path(__file__).with_name("conftest.py")))
    python, why = install()
    root_conftest.need(python is not None, f"Blender (bpy=={BPY_VERSION}) could not be had: {why}")
    return Blender(python)
