"""Load a test module's cases and helpers into a benchmark script (imported, never copied)."""

from __future__ import annotations

import importlib.util
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

__all__ = ["load_test_module", "case_rows"]


def load_test_module(relpath: str, name: str):
    """The module at ``REPO/relpath`` under ``name`` (registered before it runs: its dataclasses
    look their module up while it loads)."""
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    spec = importlib.util.spec_from_file_location(name, REPO / relpath)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def case_rows(module, cases: str | None, ready=lambda case: True):
    """``(case, row)`` for the cases of a truth-table test module (``module.CASES``, run by
    ``module.run_case(case, folder)`` in a folder of its own), in order; ``cases``: a
    comma-separated subset of case ids (None: all).  A case ``ready`` refuses gives row None."""
    want = set(cases.split(",")) if cases else None
    for c in module.CASES:
        if want and c.id not in want:
            continue
        if not ready(c):
            yield c, None
            continue
        with tempfile.TemporaryDirectory() as td:
            yield c, module.run_case(c, Path(td))
