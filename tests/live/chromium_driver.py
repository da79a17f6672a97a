"""Debian's Chromium and ChromeDriver for the viewer's browser test, installed once when allowed.

With ``CI=true`` or ``FACEPUPPET_INSTALL_CHROMIUM=1`` a missing browser is installed with
``apt-get update && apt-get install -y chromium chromium-driver`` (needs root); otherwise the test that asked
skips with the reason (and fails in CI, ``conftest.need``). Selenium drives it through
``/usr/bin/chromedriver`` (never Selenium Manager, which would download a driver).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
#: Headless, offline, no GPU (WebGL2 through SwiftShader), nothing fetched in the background.
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-dev-shm-usage",
         "--window-size=1400,760", "--hide-scrollbars")


def install_allowed() -> bool:
    return (os.environ.get("CI", "").lower() in ("1", "true", "yes")
            or os.environ.get("FACEPUPPET_INSTALL_CHROMIUM", "") == "1")


def ensure_chromium() -> str | None:
    """None when Chromium and ChromeDriver are there (installing them if allowed), else why not."""
    if CHROMIUM.exists() and CHROMEDRIVER.exists():
        return None
    if not install_allowed():
        return (f"{CHROMIUM} or {CHROMEDRIVER} is missing; set FACEPUPPET_INSTALL_CHROMIUM=1 (or CI=true) to "
                f"install Debian's chromium and chromium-driver")
    apt = shutil.which("apt-get")
    if apt is None or os.geteuid() != 0:
        return "installing chromium needs apt-get and root"
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for cmd in ([apt, "update"], [apt, "install", "-y", "chromium", "chromium-driver"]):
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, env=env)
        except subprocess.TimeoutExpired:
            return f"{' '.join(cmd)} timed out"
        if done.returncode:
            last = (done.stderr.strip() or done.stdout.strip()).splitlines()[-1:] or [""]
            return f"{' '.join(cmd)} failed: {last[0]}"
    return None if CHROMIUM.exists() and CHROMEDRIVER.exists() else "chromium was installed but not found"


def start_driver():
    """A Selenium Chrome driver on Debian's Chromium with :data:`FLAGS` and a new empty profile folder."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in FLAGS:
        options.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="facepuppet-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    driver.facepuppet_profile = profile
    return driver


def stop_driver(driver) -> None:
    try:
        driver.quit()
    finally:
        shutil.rmtree(driver.facepuppet_profile, ignore_errors=True)
