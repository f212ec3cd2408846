"""
The Python API: what the commands do, as functions that return result objects.

Every name here is exported from :mod:`lbscene` and kept stable; the ``lbscene``
commands are thin wrappers over them.  User mistakes raise
:class:`~lbscene.engine.diagnostics.LbsceneUserError`, whose ``diagnostics`` carry
the located ``LB…`` codes the command line prints.

Examples
--------
>>> import lbscene
>>> booth = lbscene.load_booth("xrite-spectralight-qc")       # a shipped booth, by name
>>> booth.name
'X-Rite SpectraLight QC'
>>> ir = lbscene.compile_booth("xrite-spectralight-qc")
>>> fm = lbscene.ForwardModel(ir, "D65")
>>> round(float(fm.illuminance_lx([[0.0, 0.0, 0.0]])[0]), -1) > 0
True
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

__all__ = [
    "load_booth",
    "compile_booth",
    "ForwardModel",
    "validate",
    "build",
    "compare",
    "plan",
    "render_from_config",
    "LbsceneUserError",
    "Diagnostic",
]

from .engine.diagnostics import Diagnostic, LbsceneUserError


def _lazy_forward():
    from .engine.forward import ForwardModel as _FM

    return _FM


def load_booth(path: Path | str, *, allowed_dirs: Iterable[Path] = ()):
    """Read and check a booth (folder, ``booth.yaml`` or a shipped booth's name).

    Returns the validated :class:`lbscene.schemas.booth.Booth`; schema and semantic errors
    (the linter's error rules) raise :class:`LbsceneUserError`.
    """
    from .engine.compile import find_booth_file
    from .engine.diagnostics import Severity
    from .engine.lint import lint_booth
    from .engine.load import load_document
    from .schemas.booth import Booth

    doc = load_document(find_booth_file(Path(path)), Booth, allowed_dirs=allowed_dirs)
    errors = [d for d in lint_booth(doc, illuminance=False) if d.severity is Severity.ERROR]
    if errors:
        raise LbsceneUserError(errors)
    return doc.model


def compile_booth(path: Path | str, *, allowed_dirs: Iterable[Path] = ()):
    """Compile a booth into its :class:`lbscene.engine.ir.SceneIR` (typed, hashable)."""
    from .engine.compile import compile_booth as _compile
    from .engine.compile import find_booth_file

    return _compile(find_booth_file(Path(path)), allowed_dirs=tuple(allowed_dirs))


def validate(*paths: Path | str, allowed_dirs: Iterable[Path] = ()):
    """Check files and folders as ``validate-config`` does; returns the
    :class:`lbscene.engine.validate.ValidationReport` (``.files``, ``.diagnostics``: errors and
    warnings, never raised)."""
    from .engine.validate import validate_paths

    return validate_paths([Path(p) for p in paths], allowed_dirs=tuple(Path(d) for d in allowed_dirs))


def build(booth: Path | str, out: Path | str, *, lighting: str | None = None, allowed_dirs: Iterable[Path] = ()):
    """Compile and write a build folder (IR, USD stages, bake jobs, render graphs), atomically.

    ``out`` follows the output policy of :mod:`lbscene.engine.outputs`: an existing folder is
    replaced only if it is an lbscene build.  Returns a :class:`lbscene.engine.build.BuildResult`.
    """
    from .engine.build import build_booth
    from .engine.compile import find_booth_file

    return build_booth(find_booth_file(Path(booth)), Path(out), lighting, allowed_dirs=tuple(allowed_dirs))


def compare(measurements: Path | str, *, booth: Path | str | None = None, fit: bool = True,
            diagnose: bool = True, history: bool = False, keep_outliers: bool = False,
            allowed_dirs: Iterable[Path] = ()):
    """Compare a booth model with a measurement set: fit, residuals, outliers, diagnosis.

    Returns a :class:`lbscene.engine.compare.CompareResult` (``.verdict``, ``.fit``,
    ``.diagnosis``, ``.to_json()``).  ``history=True`` appends the run to the history next to
    the measurements, as the command does by default.
    """
    from .engine.compare import run_compare

    return run_compare(Path(measurements), booth=booth, fit=fit, do_diagnose=diagnose, history=history,
                       allowed_dirs=tuple(allowed_dirs), keep_outliers=keep_outliers)


def plan(measurements: Path | str, *, booth: Path | str | None = None, points: int = 8,
         allowed_dirs: Iterable[Path] = ()):
    """The readings that would tell the tied explanations apart (``None`` when nothing is tied)."""
    from .engine.compare import plan_for, run_compare

    if isinstance(points, bool) or not isinstance(points, int):
        raise TypeError(f"points must be an integer, not {type(points).__name__}")
    if not 1 <= points <= 50:
        raise LbsceneUserError.single("LB500", "points must be 1 … 50", value=str(points),
                                      expected="a number of readings from 1 to 50 (the command's --points)")
    res = run_compare(Path(measurements), booth=booth, do_plan=False, history=False,
                      allowed_dirs=tuple(allowed_dirs))
    return plan_for(res, max_points=points)


def render_from_config(config: Path | str, **options):
    """Render a configuration to its PNG; see :func:`lbscene.runtimes.render.render_from_config`.

    Returns a :class:`lbscene.runtimes.render.RenderResult` (``.png``, ``.frames`` with the
    8-bit and XYZ images, ``.to_json()``).
    """
    from .runtimes.render import render_from_config as _render

    return _render(config, **options)


def __getattr__(name: str):
    if name == "ForwardModel":
        return _lazy_forward()
    raise AttributeError(name)
