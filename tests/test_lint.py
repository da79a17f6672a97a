"""The linter's rules (pyproject's ``[tool.ruff]``) hold over the sources, tests and benchmarks."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

from conftest import need

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_finds_nothing():
    need(importlib.util.find_spec("ruff") is not None, "ruff is not installed (pip install -e '.[dev]')")
    done = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "src", "tests", "benchmarks"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
