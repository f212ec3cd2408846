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
    "conformance",
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


def conformance(booth: Path | str, *, lightings: Iterable[str] | None = None,
                measurements: Path | str | None = None, report: Path | str | None = None,
                grid: tuple[int, int] = (13, 9), allowed_dirs: Iterable[Path] = ()):
    """Judge each lighting of a booth against the viewing standard it names.

    The forward model with the booth's effects gives the light at the sample and over the
    viewing area; colour-science gives its colorimetry; the checks are those of the
    lighting's ``standard:`` (ISO 3664:2009 P1/P2 in full, the illuminance range of
    ASTM D1729 and ISO 3668).

    Parameters
    ----------
    booth : path or str
        Booth folder, ``booth.yaml`` or a shipped booth's name.
    lightings : iterable of str, optional
        Lighting configurations to judge (default: all).
    measurements : path or str, optional
        A measurement set of the booth; its lighting is judged from the data too.
    report : path or str, optional
        Also write the self-contained HTML report there (the output policy of
        :mod:`lbscene.engine.outputs` applies: an existing file is replaced only if lbscene
        wrote it).
    grid : (int, int)
        Points along x and y of the viewing-area grid.
    allowed_dirs : iterable of path
        Extra folders file references may point into.

    Returns
    -------
    lbscene.engine.conformance.evaluate.ConformanceResult
        ``.lightings`` (each with ``.model``, ``.measured``, ``.checks``, ``.verdict``) and
        ``.to_json()``.

    Raises
    ------
    LbsceneUserError
        A bad booth, measurement set, lighting name (``LB202``) or grid (``LB500``), or an
        output the policy refuses (``LB610``–``LB612``).
    TypeError
        ``lightings`` given as one string, ``grid`` not a pair of ints.

    References
    ----------
    ISO 3664:2009; CIE 13.3-1995; CIE 224:2017; ANSI/IES TM-30-18; CIE 51.2-1999.

    Examples
    --------
    >>> res = lbscene.conformance("iso3664-p1-d50", lightings=["P1"])     # doctest: +SKIP
    >>> [(c.id, c.verdict) for c in res.lightings[0].checks][:2]            # doctest: +SKIP
    [('illuminance', 'pass'), ('uniformity', 'fail')]
    """
    from .engine.conformance import run_conformance
    from .engine.outputs import check_outputs

    if isinstance(lightings, (str, bytes)):
        raise TypeError("lightings must be an iterable of lighting names, not one string")
    if report is not None:
        check_outputs([(Path(report), "report")], inputs=[Path(booth)] + ([Path(measurements)] if measurements else []))
    res = run_conformance(booth, lightings=None if lightings is None else list(lightings),
                          measurements=measurements, grid=grid, allowed_dirs=tuple(allowed_dirs))
    if report is not None:
        from .engine.conformance.report import write_conformance_report

        write_conformance_report(res, report)
    return res


def __getattr__(name: str):
    if name == "ForwardModel":
        return _lazy_forward()
    raise AttributeError(name)
