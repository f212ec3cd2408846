"""Shared test fixtures."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

# A command's output is tested as a pipe gives it to a user: no terminal width imposed.  (pytest-xdist's
# workers set COLUMNS=80 and LINES=24; the tests that need a width set it themselves.)
os.environ.pop("COLUMNS", None)
os.environ.pop("LINES", None)

REPO = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
BOOTHS = REPO / "booths"


@pytest.fixture(autouse=True, scope="session")
def _private_geometry_cache(tmp_path_factory):
    """The forward model's disk cache (engine.files.disk_cache) in a folder of this test session,
    never the user's ~/.cache."""
    import os

    old = os.environ.get("LBSCENE_CACHE_DIR")
    os.environ["LBSCENE_CACHE_DIR"] = str(tmp_path_factory.mktemp("lbscene-cache"))
    yield
    if old is None:
        os.environ.pop("LBSCENE_CACHE_DIR", None)
    else:
        os.environ["LBSCENE_CACHE_DIR"] = old


@pytest.fixture(autouse=True, scope="session")
def _lbscene_usd_schema():
    """The lbscene USD schema registered before any test opens a stage of its own.

    USD makes its schema registry once per process, at the first stage opened; a test that writes a
    USD file with ``pxr`` directly would otherwise decide, by the order tests run in, whether a later
    stage can apply the lbscene API schemas.  (lbscene itself registers the schema before it opens
    any stage: tests/engine/test_geometry_files.py checks that in a fresh process.)
    """
    from lbscene.engine.scene.usd_stage import register_schema

    register_schema()


@pytest.fixture
def minimal_booth(tmp_path) -> Path:
    """A writable copy of tests/data/minimal-booth."""
    dst = tmp_path / "minimal-booth"
    shutil.copytree(DATA / "minimal-booth", dst)
    return dst


@pytest.fixture
def run_cli(monkeypatch):
    """Run the lbscene CLI in-process; returns (exit code, stdout, stderr)."""
    from lbscene.cli import main

    def run(*args, cwd: Path | None = None):
        import contextlib
        import io

        if cwd is not None:
            monkeypatch.chdir(cwd)
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([str(a) for a in args])
        return code, out.getvalue(), err.getvalue()

    return run
