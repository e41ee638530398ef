"""Shared pytest configuration: the ``browser`` marker.

Tests marked ``browser`` open files in headless Chromium; they run only when
selected with ``-m browser`` or with ``SAFENAV_BROWSER_TESTS=1``, so the
default suite needs no browser."""

from __future__ import annotations

import os

import pytest


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
