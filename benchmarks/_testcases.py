"""Load a test module's cases and helpers into a benchmark script (imported, never copied)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

__all__ = ["load_test_module"]


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
