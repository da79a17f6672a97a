"""The Khronos glTF Validator (npm package ``gltf-validator``) for tests.

Installed on first use into the tests' npm cache folder (:mod:`node_packages`). Without npm, or when the
install fails, a test that needs it skips, and fails in CI (``conftest.need``).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from node_packages import need_package

VALIDATOR_VERSION = "2.0.0-dev.3.10"
SCRIPT = Path(__file__).with_name("gltf_validate.js")


class GltfValidator:
    """Runs the validator on a file; :meth:`check` asserts that it reports no errors."""

    def __init__(self, prefix: Path) -> None:
        self.env = dict(os.environ, NODE_PATH=str(prefix / "node_modules"))

    def report(self, path: str | os.PathLike) -> dict:
        done = subprocess.run([shutil.which("node"), str(SCRIPT), str(path)], capture_output=True, text=True,
                              env=self.env, timeout=120)
        assert done.returncode == 0, f"validator failed on {path}: {done.stderr.strip()}"
        return json.loads(done.stdout)

    def check(self, path: str | os.PathLike) -> dict:
        """Validate ``path``; fail the test listing the messages if the validator reports any error."""
        report = self.report(path)
        issues = report["issues"]
        errors = [m for m in issues["messages"] if m["severity"] == 0]
        assert issues["numErrors"] == 0, f"{path}: glTF validator errors: {json.dumps(errors, indent=1)}"
        return report


@pytest.fixture(scope="session")
def gltf_validator(request) -> GltfValidator:
    """The Khronos glTF Validator, installed on first use (skips without npm; fails in CI).

    Test modules import this fixture: ``from gltf_validator import gltf_validator``.
    """
    return GltfValidator(need_package(request, "gltf-validator", VALIDATOR_VERSION, "the Khronos glTF validator"))
