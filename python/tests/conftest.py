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
def short_loop_tum(tmp_path) -> Path:
    """tmp_path/short.txt: the first 4 s of the built-in loop as a TUM trajectory file (for bench suite tests)."""
    from linnet.sim import builtin_loop

    s = builtin_loop(duration=4.0)
    tum = tmp_path / "short.txt"
    rows = [f"{t * 1e-9:.6f} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f} {q[0]:.9f}"
            for t, p, q in zip(s.t_ns, s.p, s.q)]
    tum.write_text("# t x y z qx qy qz qw\n" + "\n".join(rows) + "\n")
    return tum


@pytest.fixture
def shared_data():
    """Call with a path relative to the shared data folder; see the module docstring."""
    return require_shared_data
