"""Headless Chromium through chromedriver, for the browser tests (tests/reports/test_browser.py, tests/web/).

Needs Debian's ``chromium`` and ``chromium-driver`` (``make setup`` installs them) and selenium;
:func:`start_chromium` skips the calling test, saying which is missing, without them.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

#: Flags every test browser gets: headless, software rendering (SwiftShader gives WebGL2 with
#: no GPU; without --enable-unsafe-swiftshader Chromium falls back to it with a warning), and
#: nothing that reaches the network or keeps state between runs.
CHROMIUM_FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--disable-dev-shm-usage",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)


def start_chromium(profile: Path, extra_args: tuple[str, ...] = ()):
    """A selenium driver for headless Chromium with :data:`CHROMIUM_FLAGS`, ``extra_args`` and a
    fresh profile folder ``profile``; the browser's console is kept (``driver.get_log("browser")``)."""
    webdriver = pytest.importorskip("selenium.webdriver")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_path = shutil.which("chromedriver")
    if chromium is None or driver_path is None:
        pytest.skip("chromium and chromium-driver are not installed (make setup installs them)")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in (*CHROMIUM_FLAGS, f"--user-data-dir={profile}", *extra_args):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(driver_path), options=options)
