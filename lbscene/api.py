"""
The Python API: what the commands do, as functions that return result objects.

Every name here is exported from :mod:`lbscene` and kept stable; the ``lbscene``
commands are thin wrappers over them.  User mistakes raise
:class:`~lbscene.engine.files.diagnostics.LbsceneUserError`, whose ``diagnostics`` carry
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
    "write_report",
    "export_web",
    "bake",
    "conformance",
    "export_mitsuba",
    "export_blender",
    "LbsceneUserError",
    "Diagnostic",
]

from .engine.files.diagnostics import Diagnostic, LbsceneUserError


def _lazy_forward():
    from .engine.light.forward import ForwardModel as _FM

    return _FM


def load_booth(path: Path | str, *, allowed_dirs: Iterable[Path] = ()):
    """Read and check a booth (folder, ``booth.yaml`` or a shipped booth's name).

    Returns the validated :class:`lbscene.schemas.booth.Booth`; schema and semantic errors
    (the linter's error rules) raise :class:`LbsceneUserError`.
    """
    from .engine.scene.compile import find_booth_file
    from .engine.files.diagnostics import Severity
    from .engine.scene.lint import lint_booth
    from .engine.files.load import load_document
    from .schemas.booth import Booth

    doc = load_document(find_booth_file(Path(path)), Booth, allowed_dirs=allowed_dirs)
    errors = [d for d in lint_booth(doc) if d.severity is Severity.ERROR]
    if errors:
        raise LbsceneUserError(errors)
    return doc.model


def compile_booth(path: Path | str, *, allowed_dirs: Iterable[Path] = ()):
    """Compile a booth into its :class:`lbscene.engine.scene.ir.SceneIR` (typed, hashable)."""
    from .engine.scene.compile import compile_booth as _compile
    from .engine.scene.compile import find_booth_file

    return _compile(find_booth_file(Path(path)), allowed_dirs=tuple(allowed_dirs))


def validate(*paths: Path | str, allowed_dirs: Iterable[Path] = ()):
    """Check files and folders as ``validate-config`` does; returns the
    :class:`lbscene.engine.conformance.validate.ValidationReport` (``.files``, ``.diagnostics``: errors and
    warnings, never raised)."""
    from .engine.conformance.validate import validate_paths

    return validate_paths([Path(p) for p in paths], allowed_dirs=tuple(Path(d) for d in allowed_dirs))


def build(booth: Path | str, out: Path | str, *, lighting: str | None = None, allowed_dirs: Iterable[Path] = ()):
    """Compile and write a build folder (IR, USD stages, bake jobs, render graphs), atomically.

    ``out`` follows the output policy of :mod:`lbscene.engine.files.outputs`: an existing folder is
    replaced only if it is an lbscene build.  Returns a :class:`lbscene.engine.scene.build.BuildResult`.
    """
    from .engine.scene.build import build_booth
    from .engine.scene.compile import find_booth_file

    return build_booth(find_booth_file(Path(booth)), Path(out), lighting, allowed_dirs=tuple(allowed_dirs))


def compare(measurements: Path | str, *, booth: Path | str | None = None, fit: bool = True,
            diagnose: bool = True, history: bool = False, keep_outliers: bool = False,
            allowed_dirs: Iterable[Path] = ()):
    """Compare a booth model with a measurement set: fit, residuals, outliers, diagnosis.

    Returns a :class:`lbscene.engine.loop.compare.CompareResult` (``.verdict``, ``.fit``,
    ``.diagnosis``, ``.to_json()``).  ``history=True`` appends the run to the history next to
    the measurements, as the command does by default.
    """
    from .engine.loop.compare import run_compare

    return run_compare(Path(measurements), booth=booth, fit=fit, do_diagnose=diagnose, history=history,
                       allowed_dirs=tuple(allowed_dirs), keep_outliers=keep_outliers)


def plan(measurements: Path | str, *, booth: Path | str | None = None, points: int = 8,
         allowed_dirs: Iterable[Path] = ()):
    """The readings that would tell the tied explanations apart (``None`` when nothing is tied)."""
    from .engine.loop.compare import plan_for, run_compare

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


def _path_arg(value, name: str) -> Path:
    """``value`` as a Path; ``TypeError`` naming the argument for anything but a str or a path."""
    import os

    if isinstance(value, (str, os.PathLike)) and not isinstance(value, bytes):
        return Path(value)
    raise TypeError(f"{name} must be a path (str or os.PathLike), got {type(value).__name__}")


def write_report(result, out: Path | str) -> Path:
    """Write the compare report of ``result``: one self-contained HTML file.

    Measured, predicted and residual maps, fitted parameters, the diagnosis (suspects, verdict,
    YAML to add), the planned readings, the white-tile spectrum and the history, with every
    plot embedded as a PNG data URI (no scripts, nothing fetched) — what ``lbscene compare
    --report`` writes.

    Parameters
    ----------
    result : lbscene.engine.loop.compare.CompareResult
        What :func:`compare` returned.
    out : path or str
        The HTML file.  The output policy of :mod:`lbscene.engine.files.outputs` applies: an existing
        file is replaced only if lbscene wrote it, never one of the run's inputs.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    TypeError
        ``result`` is not a compare result, or ``out`` not a path.
    LbsceneUserError
        ``LB610``–``LB612`` for an output the policy refuses.

    Examples
    --------
    >>> res = lbscene.compare("examples/walkthrough-spectralight-d65/measurements.yaml")  # doctest: +SKIP
    >>> lbscene.write_report(res, "report.html")                                          # doctest: +SKIP
    PosixPath('report.html')
    """
    from .engine.loop.compare import CompareResult
    from .engine.files.outputs import check_outputs
    from .engine.loop.report import write_report as _write

    if not isinstance(result, CompareResult):
        raise TypeError(f"result must be what lbscene.compare() returned, got {type(result).__name__}")
    out = _path_arg(out, "out")
    check_outputs([(out, "report")], inputs=[result.meas.path])
    return _write(result, out)


def export_web(source: Path | str, out: Path | str, *, lightings: Iterable[str] = (),
               samples: Iterable[Path | str] = (), displays: Iterable[str] = (),
               size: tuple[int, int] | None = None, session: Path | str | None = None,
               max_mb: float = 256.0, allowed_dirs: Iterable[Path] = ()) -> dict:
    """Export a self-contained WebGL2 viewer of a booth or a render configuration.

    The viewer runs the same render graphs and GLSL files as :func:`render_from_config`
    (HTML + JavaScript + data; nothing fetched, opens from ``file://``) — what
    ``lbscene export-web`` writes.

    Parameters
    ----------
    source : path or str
        A render configuration (``kind: render_config``) or a booth folder / ``booth.yaml``.
    out : path or str
        The viewer's folder: new, empty, or an earlier export (replaced whole, atomically).
    lightings : iterable of str
        Lighting configurations to include (default: all of the booth's).
    samples : iterable of path
        Extra sample documents.
    displays : iterable of str
        Extra display documents, or ``"builtin:srgb"`` (the sRGB reference is always in).
    size : (int, int), optional
        Canvas width and height in pixels.
    session : path or str, optional
        A visual-test session (``kind: visual_session``): its cases and the test mode.
    max_mb : float
        Refuse exports whose data exceed this many megabytes (``LB701``).
    allowed_dirs : iterable of path
        Extra folders file references may point into.

    Returns
    -------
    dict
        ``out``, ``files``, ``booth``, ``lightings``, ``views``, ``samples``, ``displays``,
        ``data_MB``, ``data_file_MB``, ``session``, ``elapsed_s``.

    Raises
    ------
    TypeError
        ``lightings``/``displays`` given as one string, ``size`` not a pair of ints.
    LbsceneUserError
        ``LB700`` an ``out`` that is not a web export, ``LB701`` too much data, ``LB202`` an
        unknown lighting, and the located errors of the inputs.
    """
    from .commands.web import run_export_web

    for name, v in (("lightings", lightings), ("samples", samples), ("displays", displays)):
        if isinstance(v, (str, bytes)) or not all(isinstance(x, (str, Path)) for x in v):
            raise TypeError(f"{name} must be an iterable of names or paths, not {v!r}")
    if size is not None and not (isinstance(size, (tuple, list)) and len(size) == 2
                                 and all(isinstance(x, int) and not isinstance(x, bool) for x in size)):
        raise TypeError(f"size must be (width, height) in pixels, got {size!r}")
    if size is not None and not all(16 <= x <= 8192 for x in size):
        raise LbsceneUserError.single("LB500", "size: each side must be 16..8192 pixels", "<arguments>",
                                      value=str(size), expected="WIDTHxHEIGHT with each side 16..8192")
    return run_export_web(_path_arg(source, "source"), _path_arg(out, "out"), lightings=list(lightings),
                          samples=[Path(x) for x in samples], displays=[str(x) for x in displays],
                          size=None if size is None else tuple(size),
                          session=None if session is None else _path_arg(session, "session"),
                          max_mb=float(max_mb), allowed_dirs=tuple(allowed_dirs))


def bake(target: Path | str, *, lighting: str | None = None, quality: str = "preview",
         samples: int | None = None, out: Path | str | None = None, force: bool = False,
         allowed_dirs: Iterable[Path] = (), progress: bool = False):
    """Bake a booth's spectral light products with Blender Cycles (``bpy``), each lighting in its
    own process: environment maps, floor irradiance, irradiance at the measurement points.

    Cached by the job's content hash (an unchanged job is not baked again unless ``force``),
    atomic and resumable — what ``lbscene bake`` does.

    Parameters
    ----------
    target : path or str
        A build folder (``lbscene build``) or a booth folder / ``booth.yaml``.
    lighting : str, optional
        Only this lighting configuration (default: all).
    quality : {"preview", "final"}
        ``final`` samples the grid points until their noise is at most 1 %.
    samples : int, optional
        Fixed samples per pixel/texel for every product (2..65536).
    out : path or str, optional
        Folder of the bakes (default: ``<build dir>/bake``).
    force : bool
        Bake again even when cached.
    allowed_dirs : iterable of path
        Extra folders file references may point into.
    progress : bool
        Show rich progress bars on stderr.

    Returns
    -------
    list of lbscene.bakers.executor.TaskResult
        One per lighting: ``status`` (``cached``, ``baked`` or ``failed``), ``manifest``,
        ``error``, ``task.out_dir``.

    Raises
    ------
    TypeError
        ``samples`` not an int, ``lighting`` not a str.
    LbsceneUserError
        ``LB500`` an unknown quality, lighting or a sample count out of range, the output policy's
        ``LB610``–``LB612``, and the located errors of the booth.
    """
    from .commands.bake import MAX_SAMPLES, _load_targets

    if lighting is not None and not isinstance(lighting, str):
        raise TypeError(f"lighting must be a lighting name, got {lighting!r}")
    if samples is not None and (not isinstance(samples, int) or isinstance(samples, bool)):
        raise TypeError(f"samples must be an int, got {samples!r}")
    if quality not in ("preview", "final"):
        raise LbsceneUserError.single("LB500", f"unknown quality {quality!r}", "<arguments>", value=repr(quality),
                                      expected="'preview' or 'final'")
    if samples is not None and not 2 <= samples <= MAX_SAMPLES:
        raise LbsceneUserError.single("LB500", "samples out of range", "<arguments>", value=str(samples),
                                      expected=f"2..{MAX_SAMPLES}")
    from .bakers.executor import BakeTask, run_tasks
    from .engine.files.outputs import check_outputs

    target = _path_arg(target, "target")
    ir, build_dir, jobs = _load_targets(target, lighting, quality, samples, tuple(allowed_dirs))
    root = _path_arg(out, "out") if out is not None else build_dir / "bake"
    check_outputs([], inputs=[target], dirs=[(root / name, "out" if out is not None else "bake folder")
                                             for name, _ in jobs])
    tasks = [BakeTask(job, root / name, label=f"{ir.booth_name} · {name}") for name, job in jobs]
    return run_tasks(tasks, force=force, progress=progress)


def export_mitsuba(booth: Path | str, out: Path | str, *, lighting: str | None = None,
                   measurements: Path | str | None = None, spp: int = 16384,
                   allowed_dirs: Iterable[Path] = ()):
    """Write the Mitsuba 3 scene lbscene's truth provider renders: a booth, a lighting and its
    readings, as Mitsuba XML (``.xml``, meshes as PLY beside it) or a Python dict module (``.py``).

    See :mod:`lbscene.engine.conformance.mitsuba_export` for what the scene represents and what
    it refuses.

    Parameters
    ----------
    booth : path or str
        Booth folder, ``booth.yaml`` or a shipped booth's name.
    out : path or str
        ``scene.xml`` or ``scene.py``.
    lighting : str, optional
        Lighting configuration (default: the measurement set's, else the booth's first).
    measurements : path or str, optional
        A measurement set: its readings become the scene's sensors (default: the 55-point A3 grid).
    spp : int
        Samples per reading written into the scene.
    allowed_dirs : iterable of path
        Extra folders file references may point into.

    Returns
    -------
    lbscene.engine.conformance.mitsuba_export.MitsubaExport

    Raises
    ------
    LbsceneUserError
        ``LB603`` (located) what Mitsuba cannot represent, ``LB604`` without mitsuba, ``LB500`` a
        bad suffix, ``LB202`` an unknown lighting.
    TypeError
        ``spp`` not an int, a path argument of another type.
    """
    from .engine.conformance.mitsuba_export import export_mitsuba as _export

    if lighting is not None and not isinstance(lighting, str):
        raise TypeError(f"lighting must be a lighting name, got {lighting!r}")
    return _export(_path_arg(booth, "booth"), _path_arg(out, "out"), lighting=lighting,
                   measurements=None if measurements is None else _path_arg(measurements, "measurements"),
                   spp=spp, allowed_dirs=tuple(allowed_dirs))


def export_blender(booth: Path | str, out: Path | str, *, lightings: Iterable[str] | None = None,
                   allowed_dirs: Iterable[Path] = ()):
    """Write a booth as a Blender file (``.blend``): the Cycles scene ``lbscene bake`` renders, in
    RGB, with every lighting as a collection and the observer as the camera.

    See :mod:`lbscene.bakers.blender_export` for what the file represents and its light units
    (Blender's watts, 683 lm/W).

    Parameters
    ----------
    booth : path or str
        Booth folder, ``booth.yaml`` or a shipped booth's name.
    out : path or str
        The ``.blend`` to write.
    lightings : iterable of str, optional
        Lightings to include (default: all; the first is switched on).
    allowed_dirs : iterable of path
        Extra folders file references may point into.

    Returns
    -------
    lbscene.bakers.blender_export.BlenderExport

    Raises
    ------
    LbsceneUserError
        ``LB500`` an ``out`` that is not ``.blend``, ``LB202`` an unknown lighting, ``LB604``
        without bpy, ``LB600`` Blender failed, ``LB610``–``LB612`` an output the policy refuses.
    TypeError
        ``lightings`` a single string, a path argument of another type.
    """
    from .bakers.blender_export import export_blender as _export

    if isinstance(lightings, str):
        raise TypeError(f"lightings must be an iterable of lighting names, got {lightings!r}")
    return _export(_path_arg(booth, "booth"), _path_arg(out, "out"),
                   lightings=None if lightings is None else list(lightings), allowed_dirs=tuple(allowed_dirs))


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
        :mod:`lbscene.engine.files.outputs` applies: an existing file is replaced only if lbscene
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
    from .engine.files.outputs import check_outputs

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
