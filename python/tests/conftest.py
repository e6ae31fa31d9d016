"""Shared pytest fixtures.

``shared_data``: the development data folder (``$LINNET_SHARED_DATA``, default ``<repo>/../shared/data``). A test
that needs it calls ``shared_data("sub/path")``: the path is returned if it exists; otherwise the test FAILS when
``CI=true`` (the data must be there in CI) and is skipped elsewhere (users who clone the project do not have it).
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def shared_data_root() -> Path:
    return Path(os.environ.get("LINNET_SHARED_DATA", REPO.parent / "shared" / "data"))


def require_shared_data(relative: str = "") -> Path:
    path = shared_data_root() / relative
    if not path.exists():
        message = f"shared data missing: {path} (set LINNET_SHARED_DATA)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(message)
        pytest.skip(message)
    return path


@pytest.fixture
def shared_data():
    """Call with a path relative to the shared data folder; see the module docstring."""
    return require_shared_data
