"""The install is deterministic: one OpenCV distribution, the one pyproject.toml declares (the one mediapipe
requires too), and it is the cv2 that is imported."""

from __future__ import annotations

import importlib.metadata as metadata
import json
import re
import subprocess
import sys
from pathlib import Path

import tomllib

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~;\[ ]", requirement, maxsplit=1)[0].strip().lower()


def declared_opencv() -> list[str]:
    project = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["project"]
    return [_name(r) for r in project["dependencies"] if _name(r).startswith("opencv")]


def test_one_opencv_distribution_is_declared_and_mediapipe_wants_the_same():
    assert declared_opencv() == ["opencv-contrib-python"]
    project = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["project"]
    extras = [_name(r) for rs in project["optional-dependencies"].values() for r in rs]
    assert not [e for e in extras if e.startswith("opencv")]  # no extra brings another one
    try:
        wanted = [_name(r) for r in metadata.requires("mediapipe") or [] if _name(r).startswith("opencv")]
    except metadata.PackageNotFoundError:
        return
    assert set(wanted) <= set(declared_opencv())


def test_the_imported_cv2_is_the_declared_distribution():
    """Asked in a fresh interpreter of this environment (other tests may hide or stub packages in this one)."""
    (name,) = declared_opencv()
    probe = ("import json, cv2, importlib.metadata as m; "
             f"print(json.dumps([cv2.__version__, m.version({name!r}), m.packages_distributions().get('cv2', [])]))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr.strip().splitlines()[-1:]
    imported, version, owners = json.loads(done.stdout)
    assert version.startswith(imported + "."), (
        f"cv2 {imported} is imported, but {name} is {version}: another OpenCV distribution overwrote it ({owners})")
