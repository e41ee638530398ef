"""Shared pytest configuration: the ``browser`` marker, and one build per session.

Tests marked ``browser`` open files in headless Chromium; they run only when
selected with ``-m browser`` or with ``SAFENAV_BROWSER_TESTS=1``, so the
default suite needs no browser.

An editable install rebuilds the C++ module whenever ``safenav`` is imported.
The session imports it once, up front; the child processes that tests start
(fuzz workers, command-line runs) are then told to skip that rebuild, so that
none of them waits on the build lock, or is killed mid-build by a test's time
limit, which would leave ninja's logs truncated."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def pytest_sessionstart(session):
    from safenav import _core

    build = next((d for d in Path(_core.__file__).resolve().parents if (d / "CMakeCache.txt").is_file()), None)
    if build is not None:        # scikit-build-core's editable install skips the rebuild for folders listed here
        skip = [p for p in os.environ.get("SKBUILD_EDITABLE_SKIP", "").split(os.pathsep) if p]
        os.environ["SKBUILD_EDITABLE_SKIP"] = os.pathsep.join([*skip, str(build)])


def pytest_configure(config):
    config.addinivalue_line("markers", "browser: renders output in headless Chromium (run with -m browser or "
                                       "SAFENAV_BROWSER_TESTS=1)")


def pytest_collection_modifyitems(config, items):
    selected = "browser" in (config.getoption("markexpr") or "") or os.environ.get("SAFENAV_BROWSER_TESTS") == "1"
    if selected:
        return
    skip = pytest.mark.skip(reason="browser test: run with -m browser or SAFENAV_BROWSER_TESTS=1")
    for item in items:
        if "browser" in item.keywords:
            item.add_marker(skip)
