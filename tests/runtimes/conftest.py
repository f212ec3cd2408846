"""Fixtures of the realtime runtime's tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def gl_ctx():
    """A headless OpenGL context (Mesa EGL); the test skips with the reason where there is none."""
    from lbscene.runtimes.executor import GLUnavailableError, create_context

    try:
        ctx = create_context()
    except GLUnavailableError as exc:
        pytest.skip(f"no OpenGL context: {exc}")
    yield ctx
    ctx.release()
