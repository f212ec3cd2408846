"""
The booths and displays shipped with lbscene.

In a source checkout they are the top-level ``booths/`` and ``displays/`` folders; in an
installed wheel they travel as the data packages ``lbscene/booths`` and ``lbscene/displays``
(see ``[tool.setuptools.package-dir]`` in ``pyproject.toml``). This module finds them in either
layout, so a shipped booth can be named instead of a path::

    lbscene build xrite-spectralight-qc        # when ./xrite-spectralight-qc does not exist

Examples
--------
>>> from lbscene.engine.files.shipped import shipped_booths
>>> "xrite-spectralight-qc" in shipped_booths()
True
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["data_dir", "shipped_booths", "shipped_booth", "shipped_displays"]


def data_dir(name: str) -> Path | None:
    """The shipped data folder ``name`` (``"booths"`` or ``"displays"``), or None.

    Looks next to the ``lbscene`` package first (installed wheel: ``lbscene/<name>``), then one
    level up (source checkout: ``<repo>/<name>``).
    """
    from importlib.util import find_spec

    # located, not imported: the package's __init__ loads the API, a layer far above this one
    pkg = Path(find_spec("lbscene").origin).resolve().parent
    for cand in (pkg / name, pkg.parent / name):
        if cand.is_dir():
            return cand
    return None


def shipped_booths() -> dict[str, Path]:
    """Shipped booths: folder name → its ``booth.yaml``, sorted by name."""
    root = data_dir("booths")
    if root is None:
        return {}
    return {f.parent.name: f for f in sorted(root.glob("*/booth.yaml"))}


def shipped_booth(name: str) -> Path | None:
    """The ``booth.yaml`` of the shipped booth ``name`` (a folder name), or None."""
    return shipped_booths().get(name)


def shipped_displays() -> dict[str, Path]:
    """Shipped display documents: file stem → path, sorted by name."""
    root = data_dir("displays")
    if root is None:
        return {}
    return {f.stem: f for f in sorted(root.glob("*.yaml"))}
