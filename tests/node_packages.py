"""npm packages for tests, installed on first use into one cache folder outside the repository.

The folder is ``~/.cache/facepuppet-tests/node`` (``$FACEPUPPET_TEST_CACHE`` moves it); each package is pinned
and reinstalled when the version found there is another. Without node/npm, or when the install fails, the test
that asked skips, and fails in CI (``conftest.need``).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path


def prefix() -> Path:
    """The npm prefix (its ``node_modules`` holds the packages)."""
    base = os.environ.get("FACEPUPPET_TEST_CACHE", Path.home() / ".cache" / "facepuppet-tests")
    return Path(base) / "node"


def installed_version(package: str) -> str | None:
    try:
        return json.loads((prefix() / "node_modules" / package / "package.json").read_text())["version"]
    except (OSError, ValueError, KeyError):
        return None


def install(package: str, version: str) -> Path | None:
    """Install ``package@version`` unless it is there; return the prefix, or None if it cannot be had."""
    if installed_version(package) == version:
        return prefix()
    npm, node = shutil.which("npm"), shutil.which("node")
    if not npm or not node:
        return None
    prefix().mkdir(parents=True, exist_ok=True)
    try:
        subprocess.run([npm, "install", "--prefix", str(prefix()), "--no-audit", "--no-fund",
                        f"{package}@{version}"], capture_output=True, text=True, timeout=600)
    except subprocess.TimeoutExpired:
        return None
    return prefix() if installed_version(package) == version else None


def need_package(request, package: str, version: str, what: str) -> Path:
    """The prefix holding ``package@version`` for a fixture; skips (fails in CI) when it cannot be had."""
    # tests/conftest.py is registered under its path; take its need() (skip, or fail in CI)
    root_conftest = request.config.pluginmanager.get_plugin(str(Path(__file__).with_name("conftest.py")))
    where = install(package, version)
    root_conftest.need(where is not None,
                       f"{what} (npm package {package}@{version}) could not be installed (needs node and npm)")
    return where
