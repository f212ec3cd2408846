r"""
Does this booth meet its standard?  Each lighting judged from the forward model (and from
measurements, side by side).

For each lighting configuration:

* the **spectral irradiance at the sample** (upward surface at ``sample_position_mm``) from
  the forward model with the booth's effects (inter-reflection, diffuser, occlusion, …:
  :class:`~lbscene.engine.light.forward.ForwardModel` with ``ir.effects``), and its colorimetry
  (:mod:`lbscene.engine.conformance.colorimetry`);
* the **illuminance at the sample** and over the **viewing area**: a grid of ``nx × ny``
  points spanning the area edge to edge (``linspace`` over each extent, corners included).
  The viewing area is the booth's platform (``platform.centre_mm``, ``size_mm``, at rotation
  0), else an A3 sheet (420 × 297 mm) centred on the sample position.  The uniformity is

  .. math:: U = E_\min / \bar E

  over the grid (``uniformity``; ``uniformity_min_to_max`` is :math:`E_\min/E_\max`);
* the **checks** of the lighting's ``standard:`` (:mod:`lbscene.engine.conformance.standards`).

With a measurement set (``kind: measurement_set``), its lighting is judged from the data too:
the illuminance at the sample is the upward reading at the sample position (within 10 mm),
else the readings' linear interpolation there; the uniformity is over the upward readings on
the viewing area's plane inside it (at least 3); the colorimetry is that of the white tile's
spectral radiance divided by its reflectance (:math:`E ∝ πL/ρ`), over the wavelengths measured.

Illuminance is physical (what a surface receives): a meter's cosine error
(``detector_cosine_error``) is not applied to the model's figures.

References
----------
ISO 3664:2009; CIE 13.3-1995; CIE 224:2017; ANSI/IES TM-30-18; CIE 51.2-1999 (see
:mod:`lbscene.engine.conformance.standards`).

Examples
--------
>>> res = run_conformance("iso3664-p1-d50", lightings=["P1"])      # doctest: +SKIP
>>> res.lightings[0].verdict, round(res.lightings[0].model.illuminance_at_sample_lx, -1)  # doctest: +SKIP
('fail', 1960.0)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError, SourceLocation
from .colorimetry import LightColorimetry, colorimetry_1nm
from .standards import (STANDARD_TITLES, Check, SourceFigures, overall_verdict, standard_checks,
                        surround_check)

__all__ = ["ViewingArea", "SourceResult", "LightingConformance", "ConformanceResult", "run_conformance",
           "viewing_area", "DEFAULT_GRID_POINTS", "SAMPLE_READING_TOLERANCE_MM"]

#: grid over the viewing area (points along x, along y)
DEFAULT_GRID_POINTS = (13, 9)
#: a reading this close to the sample position is the measured illuminance at the sample
SAMPLE_READING_TOLERANCE_MM = 10.0
#: readings this close to the viewing area's plane (and inside it, with this margin) count for uniformity
PLANE_TOLERANCE_MM = 1.0
#: the viewing area of a booth without a platform: an A3 sheet at the sample
A3_MM = (420.0, 297.0)


@dataclass(frozen=True)
class ViewingArea:
    """A horizontal rectangle (mm) over which uniformity is judged."""

    centre_mm: tuple[float, float, float]
    size_mm: tuple[float, float]
    source: str

    def grid_mm(self, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(x (nx,), y (ny,), points (ny·nx, 3))``: the grid edge to edge, rows along x."""
        cx, cy, cz = self.centre_mm
        x = cx + np.linspace(-self.size_mm[0] / 2, self.size_mm[0] / 2, nx)
        y = cy + np.linspace(-self.size_mm[1] / 2, self.size_mm[1] / 2, ny)
        X, Y = np.meshgrid(x, y, indexing="xy")
        return x, y, np.c_[X.ravel(), Y.ravel(), np.full(X.size, cz)]

    def contains(self, P, margin_mm: float = PLANE_TOLERANCE_MM) -> np.ndarray:
        P = np.atleast_2d(P)
        cx, cy, cz = self.centre_mm
        return ((np.abs(P[:, 0] - cx) <= self.size_mm[0] / 2 + margin_mm)
                & (np.abs(P[:, 1] - cy) <= self.size_mm[1] / 2 + margin_mm)
                & (np.abs(P[:, 2] - cz) <= PLANE_TOLERANCE_MM))

    def to_json(self) -> dict:
        return {"centre_mm": [float(v) for v in self.centre_mm], "size_mm": [float(v) for v in self.size_mm],
                "source": self.source}


def viewing_area(ir) -> ViewingArea:
    """The booth's platform at rotation 0, else an A3 sheet centred on the sample position."""
    if ir.platform is not None:
        return ViewingArea(tuple(float(v) for v in ir.platform.centre_mm),
                           tuple(float(v) for v in ir.platform.size_mm), "platform")
    return ViewingArea(tuple(float(v) for v in ir.sample_position_mm), A3_MM, "A3 sheet at the sample")


@dataclass
class SourceResult:
    """The figures of one lighting from one source (``model`` or ``measured``)."""

    source: str
    illuminance_at_sample_lx: float | None
    grid_points_mm: np.ndarray                 # (K, 3)
    grid_lx: np.ndarray                        # (K,)
    grid_shape: tuple[int, int] | None         # (ny, nx) for the model's regular grid
    spectrum_1nm: np.ndarray | None            # relative spectral irradiance at the sample
    wavelengths_nm: np.ndarray | None
    colorimetry: LightColorimetry | None
    uv_reached: bool = True
    notes: list[str] = field(default_factory=list)

    @property
    def uniformity(self) -> float | None:
        """:math:`E_\\min/\\bar E` over the viewing area (None with fewer than 3 points)."""
        if self.grid_lx.size < 3 or self.grid_lx.mean() <= 0:
            return None
        return float(self.grid_lx.min() / self.grid_lx.mean())

    @property
    def uniformity_min_to_max(self) -> float | None:
        if self.grid_lx.size < 3 or self.grid_lx.max() <= 0:
            return None
        return float(self.grid_lx.min() / self.grid_lx.max())

    def figures(self) -> SourceFigures:
        return SourceFigures(self.source, self.illuminance_at_sample_lx, self.uniformity, self.colorimetry,
                             self.uv_reached)

    def to_json(self) -> dict:
        n = self.grid_lx.size
        r = lambda v, nd=3: None if v is None else round(float(v), nd)  # noqa: E731
        return {
            "illuminance_at_sample_lx": r(self.illuminance_at_sample_lx),
            "uniformity": r(self.uniformity, 4),
            "uniformity_min_to_max": r(self.uniformity_min_to_max, 4),
            "illuminance_min_lx": r(self.grid_lx.min()) if n else None,
            "illuminance_mean_lx": r(self.grid_lx.mean()) if n else None,
            "illuminance_max_lx": r(self.grid_lx.max()) if n else None,
            "viewing_area_points": int(n),
            "colorimetry": None if self.colorimetry is None else self.colorimetry.to_json(),
            "uv_reached": self.uv_reached,
            "notes": list(self.notes),
        }


@dataclass
class LightingConformance:
    """One lighting: its figures from the model (and the measurements), its checks, its verdict."""

    name: str
    standard: str
    description: str
    model: SourceResult
    measured: SourceResult | None
    checks: list[Check]

    @property
    def verdict(self) -> str:
        return overall_verdict(self.checks)

    def to_json(self) -> dict:
        return {"name": self.name, "standard": self.standard,
                "standard_title": STANDARD_TITLES.get(self.standard, self.standard),
                "description": self.description, "verdict": self.verdict,
                "model": self.model.to_json(),
                "measured": None if self.measured is None else self.measured.to_json(),
                "checks": [c.to_json() for c in self.checks]}


@dataclass
class ConformanceResult:
    """What :func:`run_conformance` found (``to_json()`` is the command's JSON output)."""

    booth_name: str
    booth_file: str
    ir_hash: str
    effects: list[str]
    area: ViewingArea
    grid_points: tuple[int, int]
    lightings: list[LightingConformance]
    measurements: str | None = None
    measured_lighting: str | None = None
    notes: list[str] = field(default_factory=list)

    def lighting(self, name: str) -> LightingConformance:
        for lc in self.lightings:
            if lc.name == name:
                return lc
        raise LbsceneUserError.single("LB202", f"no lighting {name!r} in this result", "<result>",
                                      expected=f"one of {', '.join(lc.name for lc in self.lightings)}")

    def to_json(self) -> dict:
        from lbscene._version import __version__

        return {"booth": self.booth_name, "booth_file": self.booth_file, "ir_hash": self.ir_hash,
                "lbscene_version": __version__, "effects": self.effects,
                "viewing_area": {**self.area.to_json(), "grid_points": list(self.grid_points)},
                "measurements": self.measurements, "measured_lighting": self.measured_lighting,
                "lightings": [lc.to_json() for lc in self.lightings], "notes": list(self.notes),
                "verdict_counts": {v: sum(1 for lc in self.lightings for c in lc.checks if c.verdict == v)
                                   for v in ("pass", "fail", "not_applicable")}}


# --------------------------------------------------------------------------- pieces

def _lamp_uv_reached(doc, booth, lamp_ids) -> bool:
    """Whether every lamp's declared spectrum covers 360–400 nm (analytic or dataset spectra do)."""
    from lbscene.engine.scene.lint import spectrum_coverage

    by_id = {lp.id: lp for lp in booth.lamps}
    for lid in lamp_ids:
        lp = by_id.get(lid)
        if lp is None:
            continue
        cov = spectrum_coverage(lp.spd, doc.resolve)
        if cov is not None and (cov[0] > 360.0 or cov[1] < 400.0):
            return False
    return True


def _model_source(ir, name: str, area: ViewingArea, grid: tuple[int, int], cache: dict,
                  uv_reached: bool) -> SourceResult:
    from lbscene.engine.light.forward import ForwardModel

    nx, ny = grid
    _, _, G = area.grid_mm(nx, ny)
    P = np.vstack([np.asarray(ir.sample_position_mm, float)[None, :], G])
    fm = ForwardModel(ir, name, cache=cache)
    pred = fm.predict(P, None, False)
    lux = pred.lux()
    spec = pred.spectral_1nm(rows=[0])[0]
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    return SourceResult("model", float(lux[0]), G, lux[1:], (ny, nx), spec, WL.copy(),
                        colorimetry_1nm(spec, uv_reached=uv_reached), uv_reached)


def _measured_source(meas, area: ViewingArea, sample_mm) -> SourceResult:
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    notes: list[str] = []
    E_s = None
    pts = np.zeros((0, 3))
    lux = np.zeros(0)
    ill = meas.illuminance
    if ill is not None and len(ill):
        up = ill.horizontal_up
        d = np.linalg.norm(ill.points_mm - np.asarray(sample_mm, float), axis=1)
        near = np.nonzero(up & (d <= SAMPLE_READING_TOLERANCE_MM))[0]
        if near.size:
            E_s = float(ill.lux[near[np.argmin(d[near])]])
        else:
            plane = up & (np.abs(ill.points_mm[:, 2] - sample_mm[2]) <= PLANE_TOLERANCE_MM)
            if plane.sum() >= 3:
                from scipy.interpolate import griddata

                v = griddata(ill.points_mm[plane, :2], ill.lux[plane], [np.asarray(sample_mm[:2], float)],
                             method="linear")
                if np.isfinite(v[0]):
                    E_s = float(v[0])
                    notes.append("illuminance at the sample interpolated linearly between the readings")
            if E_s is None:
                notes.append("no reading at or around the sample position")
        on = up & area.contains(ill.points_mm)
        pts, lux = ill.points_mm[on], ill.lux[on]
        if on.sum() < 3:
            notes.append(f"{int(on.sum())} upward reading(s) on the viewing area: no uniformity")
    else:
        notes.append("no illuminance readings")
    spec = wl = col = None
    uv_reached = False
    if meas.tile is not None:
        t = meas.tile
        cov = np.asarray(t.covered, bool)
        wl = WL[cov]
        rho = np.clip(np.asarray(t.reflectance_1nm, float)[cov], 1e-6, None)
        spec = np.pi * np.asarray(t.radiance_1nm, float)[cov] / rho
        uv_reached = bool(cov[(WL >= 360) & (WL <= 400)].all())
        col = colorimetry_1nm(spec, wl, uv_reached=uv_reached)
        notes.append(f"spectrum: white tile {t.display}, {wl[0]:g}-{wl[-1]:g} nm")
    else:
        notes.append("no white-tile spectrum: no colorimetry from the measurements")
    return SourceResult("measured", E_s, pts, lux, None, spec, wl, col, uv_reached, notes)


def _surfaces(ir) -> list[tuple[str, str, np.ndarray, str]]:
    out, seen = [], set()
    for s in ir.surfaces:
        role = s.role
        if not (role in ("floor", "platform") or role.endswith("_wall")) or role in seen:
            continue
        seen.add(role)
        m = ir.materials[s.material]
        out.append((role, m.id, m.reflectance.array_1nm, m.type))
    return out


def _user_error(code, message, where, **kw) -> LbsceneUserError:
    return LbsceneUserError(Diagnostic(code, message, SourceLocation(str(where)), **kw))


# --------------------------------------------------------------------------- the run

def run_conformance(booth: Path | str, *, lightings: Sequence[str] | None = None,
                    measurements: Path | str | None = None, grid: tuple[int, int] = DEFAULT_GRID_POINTS,
                    allowed_dirs: Iterable[Path] = (),
                    progress: Callable[[str], None] | None = None) -> ConformanceResult:
    """Judge each lighting of a booth against the standard it names.

    Parameters
    ----------
    booth : path or str
        Booth folder, ``booth.yaml`` or a shipped booth's name.
    lightings : sequence of str, optional
        Lighting configurations to judge (default: all of the booth's).
    measurements : path, optional
        A measurement set of this booth: its lighting is judged from the data too (side by side).
    grid : (int, int)
        Points along x and y of the viewing-area grid (each at least 2).
    allowed_dirs : iterable of path
        Extra folders file references may point into.
    progress : callable, optional
        Called with a short description before each lighting.

    Returns
    -------
    ConformanceResult

    Raises
    ------
    LbsceneUserError
        ``LB202`` for an unknown lighting, ``LB500`` for a bad grid, and the located errors of
        the booth or the measurement set.
    """
    from lbscene.schemas.booth import Booth

    from lbscene.engine.scene.compile import compile_loaded, find_booth_file
    from lbscene.engine.files.diagnostics import Severity
    from lbscene.engine.scene.lint import lint_booth
    from lbscene.engine.files.load import display_path, load_document

    if (not isinstance(grid, (tuple, list)) or len(grid) != 2
            or not all(isinstance(g, (int, np.integer)) and not isinstance(g, bool) for g in grid)):
        raise TypeError(f"grid must be a pair of ints (points along x, along y), got {grid!r}")
    if not all(2 <= int(g) <= 201 for g in grid):
        raise _user_error("LB500", "the viewing-area grid needs 2 to 201 points per side", "<arguments>",
                          value=f"{grid[0]}x{grid[1]}", expected="e.g. 13x9")
    if lightings is not None and (isinstance(lightings, (str, bytes)) or
                                  not all(isinstance(x, str) for x in lightings)):
        raise TypeError(f"lightings must be a sequence of lighting names, got {lightings!r}")
    say = progress or (lambda _m: None)
    booth_file = find_booth_file(Path(booth))
    doc = load_document(booth_file, Booth, allowed_dirs=allowed_dirs)
    errors = [d for d in lint_booth(doc) if d.severity is Severity.ERROR]
    if errors:
        raise LbsceneUserError(errors)
    say("conformance: compile")
    ir = compile_loaded(doc)
    names = list(ir.lighting) if lightings is None else list(dict.fromkeys(lightings))
    for n in names:
        if n not in ir.lighting:
            raise _user_error("LB202", f"--lighting: booth {ir.booth_name!r} has no lighting configuration {n!r}",
                              display_path(booth_file), value=repr(n), expected=f"one of {', '.join(ir.lighting)}")
    meas = None
    notes: list[str] = []
    if measurements is not None:
        from lbscene.engine.loop.measurements import load_measurements

        meas = load_measurements(Path(measurements), booth=booth_file, allowed_dirs=allowed_dirs)
        if meas.lighting not in names:
            notes.append(f"the measurements are of lighting {meas.lighting!r}: it is judged too")
            names.append(meas.lighting)
    area = viewing_area(ir)
    cache: dict = {}
    out = []
    surround = surround_check  # one evaluation per standard below
    surfaces = _surfaces(ir)
    for n in names:
        cfg = ir.lighting[n]
        say(f"conformance: {n}")
        uv = _lamp_uv_reached(doc, doc.model, cfg.lamps)
        model = _model_source(ir, n, area, tuple(int(g) for g in grid), cache, uv)
        checks = standard_checks(cfg.standard, model.figures())
        s = surround(cfg.standard, surfaces)
        if s is not None:
            checks.append(s)
        measured = None
        if meas is not None and meas.lighting == n:
            measured = _measured_source(meas, area, np.asarray(ir.sample_position_mm, float))
            checks += [c for c in standard_checks(cfg.standard, measured.figures())]
        out.append(LightingConformance(n, cfg.standard, cfg.description, model, measured, checks))
    return ConformanceResult(ir.booth_name, display_path(booth_file), ir.content_hash, sorted(ir.effects), area,
                             (int(grid[0]), int(grid[1])), out,
                             measurements=None if meas is None else display_path(meas.path),
                             measured_lighting=None if meas is None else meas.lighting, notes=notes)
