"""Shared test fixtures: the real data in ../shared/assets, and optional parts.

Outside CI a test that needs a missing piece skips; with ``CI=true`` it fails instead, so CI proves that
the real-data tests ran.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def need(condition: bool, why: str) -> None:
    """Skip (or, in CI, fail) the calling test unless ``condition`` holds."""
    if not condition:
        if IN_CI:
            pytest.fail(f"CI must run this test, but {why}")
        pytest.skip(why)


def assets_dir() -> Path:
    return Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets")).resolve()


@pytest.fixture(scope="session")
def assets() -> Path:
    """Path of ../shared/assets (or $FACEPUPPET_ASSETS)."""
    path = assets_dir()
    need(path.is_dir(), f"shared assets not found at {path}")
    return path


@pytest.fixture(scope="session")
def ict(assets):
    """The ICT-FaceKit light model as a dict of arrays."""
    path = assets / "ict-facekit" / "ict_face_light.npz"
    need(path.is_file(), f"{path} is missing")
    with np.load(path) as d:
        return {k: d[k] for k in d.files}


@pytest.fixture(scope="session")
def face_landmarker(assets) -> Path:
    """Path of the MediaPipe Face Landmarker model, with the mediapipe package importable."""
    need(importlib.util.find_spec("mediapipe") is not None, "the mediapipe extra is not installed")
    path = Path(os.environ.get("FACEPUPPET_FACE_LANDMARKER", assets / "models" / "face_landmarker.task"))
    need(path.is_file(), f"{path} is missing")
    return path


@pytest.fixture(scope="session")
def demo(tmp_path_factory):
    """The built-in demo run once (5 s, colour tracker): its files hold a video, a profile and a rig."""
    from facepuppet.demo.run import DemoConfig, run_demo

    folder = tmp_path_factory.mktemp("demo")
    return run_demo(folder, DemoConfig(seconds=5.0, progress=False))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
