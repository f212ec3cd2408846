"""
Load a measurement set and its data files, with located errors (LB400–LB407).

* :func:`load_measurements` — the YAML (:class:`~lbscene.schemas.measurement.MeasurementSet`),
  its booth (compiled to the IR, measured surface reflectances applied), the
  illuminance readings and the white-tile spectrum.
* :func:`read_illuminance_csv` — ``x_mm,y_mm,illuminance_lx[,z_mm][,orientation|normal_*]``.

Every problem of the data files is reported at once with ``file:line:col``:
missing or unknown columns (LB400), non-numbers/NaN (LB401), negative or
zero readings (LB402), duplicate points (LB403), points outside the booth
(LB404), wavelengths not increasing (LB405), unit mistakes such as klx or
percent reflectances (LB406), too few rows (LB407).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, DiagnosticBag, LbsceneUserError, SourceLocation
from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM

__all__ = ["IlluminanceData", "TileData", "Measurements", "load_measurements",
           "read_illuminance_csv", "ILLUMINANCE_COLUMNS", "check_against_prediction", "likely_causes"]

ILLUMINANCE_COLUMNS = ("x_mm", "y_mm", "z_mm", "illuminance_lx", "orientation", "normal_x",
                       "normal_y", "normal_z", "label")
#: Columns people write when the unit is not lux: name → factor to lux.
_UNIT_COLUMNS = {"illuminance_klx": 1000.0, "illuminance_fc": 10.7639, "illuminance": None,
                 "lux": 1.0, "lx": 1.0, "illuminance_mlx": 1e-3}
_DUP_TOL_MM = 0.5


@dataclass
class IlluminanceData:
    """Illuminance readings: where, facing where, how much, and from which file line."""

    points_mm: np.ndarray          # (M, 3)
    normals: np.ndarray            # (M, 3)
    lux: np.ndarray                # (M,)
    files: list[str]               # per point: display path of its CSV
    lines: np.ndarray              # per point: line number in its CSV
    labels: list[str]

    def __len__(self) -> int:
        return len(self.lux)

    def subset(self, idx) -> "IlluminanceData":
        idx = np.asarray(idx)
        return IlluminanceData(self.points_mm[idx], self.normals[idx], self.lux[idx],
                               [self.files[i] for i in idx], self.lines[idx],
                               [self.labels[i] for i in idx])

    @property
    def horizontal_up(self) -> np.ndarray:
        return self.normals[:, 2] > 0.999

    def orientation_labels(self) -> list[str]:
        from lbscene.schemas.measurement import ORIENTATIONS

        out = []
        for n in self.normals:
            name = next((k for k, v in ORIENTATIONS.items() if np.allclose(n, v, atol=1e-6)), None)
            out.append(name or "(" + ", ".join(f"{c:.3g}" for c in n) + ")")
        return out


@dataclass
class TileData:
    """White-tile radiance measurement (1 nm reference grid)."""

    position_mm: np.ndarray
    normal: np.ndarray
    radiance_1nm: np.ndarray       # W·sr⁻¹·m⁻²·nm⁻¹
    covered: np.ndarray            # (471,) bool, where the instrument measured
    reflectance_1nm: np.ndarray
    display: str
    #: the instrument's sampling interval (median spacing of the tabulated wavelengths) and its
    #: first sample; None for a spectrum given as a formula
    sampling_nm: float | None = None
    first_sample_nm: float | None = None


@dataclass
class Measurements:
    """A loaded measurement set, ready for the fit."""

    path: Path
    name: str
    booth_file: Path
    lighting: str
    ir: object                     # SceneIR with measured reflectances applied
    illuminance: IlluminanceData | None
    tile: TileData | None
    declared_noise_percent: float | None
    spectral_noise_percent: float | None
    known_output_groups: list[str]
    doc: object = None
    model_uncertainty_percent: float = 0.0
    notes: list[str] = field(default_factory=list)

    @property
    def history_path(self) -> Path:
        return self.path.with_name(self.path.stem + ".history.jsonl")


# --------------------------------------------------------------------------- CSV

#: No booth reading is brighter than this (direct sunlight is about 100 000 lx).
MAX_PLAUSIBLE_LX = 1.0e6


def _colno(row: list[str], col: int) -> int:
    return sum(len(c) + 1 for c in row[:col]) + 1


def _shown(doc, spec, fallback: str) -> str:
    """Where messages about a spectrum point: its file as the user can open it, else the field."""
    from lbscene.engine.files.load import display_path

    raw = getattr(spec, "path", None)
    return display_path(doc.resolve(raw)) if raw else fallback


def read_illuminance_csv(path: Path, display: str, *, default_z_mm: float = 0.0,
                         default_orientation: str = "up", interior=None) -> tuple[IlluminanceData, list[Diagnostic]]:
    """Read one illuminance CSV; return the data and *all* problems found (errors)."""
    from lbscene.engine.files.yamlio import read_text_bounded
    from lbscene.schemas.measurement import ORIENTATIONS

    text = read_text_bounded(path, display, 16 * 1024 * 1024)
    diags: list[Diagnostic] = []

    def err(code, msg, line=0, col=0, **kw):
        diags.append(Diagnostic(code, msg, SourceLocation(display, line, col), **kw))

    from lbscene.engine.files.yamlio import csv_rows

    rows = [(i, r) for i, r in csv_rows(text, display)
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    empty = IlluminanceData(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), [], np.zeros(0, int), [])
    if not rows:
        err("LB407", "illuminance file has no rows", 1, 1,
            expected="a header 'x_mm,y_mm,illuminance_lx' and data rows")
        return empty, diags
    hline, header = rows[0]
    header = [h.strip() for h in header]
    for j, h in enumerate(header):
        if h in _UNIT_COLUMNS and h != "illuminance_lx":
            f = _UNIT_COLUMNS[h]
            hint = f"convert to lux (× {f:g}) and name the column illuminance_lx" if f else \
                "name the column illuminance_lx and give lux"
            diags.append(Diagnostic("LB406", f"column '{h}': illuminance must be given in lux",
                                    SourceLocation(display, hline, _colno(header, j)), value=repr(h),
                                    expected="illuminance_lx", hint=hint))
        elif h not in ILLUMINANCE_COLUMNS:
            err("LB400", f"unexpected column '{h}'", hline, _colno(header, j), value=repr(h),
                expected=f"columns from {', '.join(ILLUMINANCE_COLUMNS)}")
    for req in ("x_mm", "y_mm", "illuminance_lx"):
        if req not in header and not (req == "illuminance_lx" and any(d.code == "LB406" for d in diags)):
            err("LB400", f"missing column '{req}'", hline, 1, value=",".join(header),
                expected="a header with x_mm, y_mm and illuminance_lx")
    ncols = [c for c in ("normal_x", "normal_y", "normal_z") if c in header]
    if ncols and len(ncols) != 3:
        err("LB400", "normal columns must come as normal_x, normal_y and normal_z together", hline, 1,
            value=",".join(ncols))
    if ncols and "orientation" in header:
        err("LB400", "give the sensor orientation either as 'orientation' or as normal_x/y/z, not both",
            hline, 1)
    if diags:
        return empty, diags
    from lbscene.engine.files.limits import check_work

    check_work("readings", len(rows) - 1, SourceLocation(display, hline, 1))
    idx = {h: j for j, h in enumerate(header)}
    pts, nrm, lux, lines, labels = [], [], [], [], []
    for line, r in rows[1:]:
        if len(r) != len(header):
            err("LB400", f"row has {len(r)} fields, header has {len(header)}", line, 1)
            continue
        vals = {}
        bad = False
        for name in ("x_mm", "y_mm", "z_mm", "illuminance_lx", "normal_x", "normal_y", "normal_z"):
            if name not in idx:
                continue
            cell = r[idx[name]].strip()
            try:
                v = float(cell)
            except ValueError:
                v = float("nan")
            if not np.isfinite(v):
                err("LB401", f"'{name}' is not a finite number", line, _colno(r, idx[name]),
                    value=repr(cell), expected="a finite number")
                bad = True
            vals[name] = v
        if bad:
            continue
        e = vals["illuminance_lx"]
        if e <= 0:
            err("LB402", "illuminance must be positive" if e == 0 else "negative illuminance", line,
                _colno(r, idx["illuminance_lx"]), value=repr(r[idx["illuminance_lx"]].strip()),
                expected="a reading > 0 lx")
            continue
        if e > MAX_PLAUSIBLE_LX:
            err("LB406", "illuminance beyond any light booth (ten times direct sunlight)", line,
                _colno(r, idx["illuminance_lx"]), value=repr(r[idx["illuminance_lx"]].strip()),
                expected=f"a reading in lux below {MAX_PLAUSIBLE_LX:g} lx", hint="a unit or typing mistake?")
            continue
        if "orientation" in idx:
            o = r[idx["orientation"]].strip() or default_orientation
            if o not in ORIENTATIONS:
                err("LB104", f"unknown sensor orientation {o!r}", line, _colno(r, idx["orientation"]),
                    value=repr(o), expected=f"one of {', '.join(ORIENTATIONS)}")
                continue
            n = np.asarray(ORIENTATIONS[o])
        elif ncols:
            n = np.array([vals["normal_x"], vals["normal_y"], vals["normal_z"]])
            if np.linalg.norm(n) < 1e-9:
                err("LB104", "sensor normal is the zero vector", line, _colno(r, idx["normal_x"]),
                    expected="a direction such as 0,0,1")
                continue
            n = n / np.linalg.norm(n)
        else:
            n = np.asarray(ORIENTATIONS[default_orientation])
        p = np.array([vals["x_mm"], vals["y_mm"], vals.get("z_mm", default_z_mm)])
        if interior is not None:
            w, d, h = interior.width_mm / 2, interior.depth_mm / 2, interior.height_mm
            tol = 1.0
            if abs(p[0]) > w + tol or abs(p[1]) > d + tol or p[2] < -tol or p[2] > h + tol:
                col = idx["x_mm"] if abs(p[0]) > w + tol else (
                    idx["y_mm"] if abs(p[1]) > d + tol else idx.get("z_mm", idx["x_mm"]))
                where = "floor" if p[2] <= tol else "booth interior"
                err("LB404", f"point ({p[0]:g}, {p[1]:g}, {p[2]:g}) mm is outside the {where}", line,
                    _colno(r, col), value=f"({p[0]:g}, {p[1]:g}, {p[2]:g}) mm",
                    expected=f"|x| ≤ {w:g}, |y| ≤ {d:g}, 0 ≤ z ≤ {h:g} mm (origin at the floor centre)")
                continue
        pts.append(p)
        nrm.append(n)
        lux.append(e)
        lines.append(line)
        labels.append(r[idx["label"]].strip() if "label" in idx else "")
    if not diags and len(lux) < 3:
        err("LB407", f"only {len(lux)} reading(s)", hline, 1, expected="at least 3 readings")
    P = np.array(pts).reshape(-1, 3)
    N = np.array(nrm).reshape(-1, 3)
    # duplicates: same place and orientation
    if len(P) > 1:
        key = np.c_[np.round(P / _DUP_TOL_MM), np.round(N * 1000)]
        order = np.lexsort(key.T[::-1])
        ks = key[order]
        same = np.all(ks[1:] == ks[:-1], axis=1)
        for a in np.nonzero(same)[0]:
            i, j = sorted((order[a], order[a + 1]))
            err("LB403", f"duplicate point ({P[j][0]:g}, {P[j][1]:g}, {P[j][2]:g}) mm, already on line "
                f"{lines[i]}", lines[j], 1, value=f"line {lines[j]}",
                expected="one reading per point and orientation (average repeats first)")
    data = IlluminanceData(P, N, np.asarray(lux, float), [display] * len(lux),
                           np.asarray(lines, int), labels)
    # magnitude: booths are lit at hundreds to thousands of lux
    if len(lux) and not diags:
        med = float(np.median(lux))
        if med < 10.0 and max(lux) < 100.0:
            err("LB406", f"readings are implausibly small for a light booth (median {med:.4g})", hline,
                _colno(header, idx["illuminance_lx"]), value=f"median {med:.4g}",
                expected="lux (booths give ~500-5000 lx)",
                hint="the values look like klx: multiply by 1000")
        elif med > 200_000.0:
            err("LB406", f"readings are implausibly large (median {med:.4g} lx)", hline,
                _colno(header, idx["illuminance_lx"]), value=f"median {med:.4g}",
                expected="lux (booths give ~500-5000 lx)", hint="the values look like mlx: divide by 1000")
    return data, diags


def _tile_sampling_nm(spec, resolve) -> tuple[float | None, float | None]:
    """Median spacing of a tabulated tile spectrum's wavelengths and its first wavelength
    (None, None: not tabulated)."""
    wl = None
    if spec.type == "inline":
        wl = list(spec.wavelengths_nm)
    elif spec.type == "csv":
        from lbscene.engine.files.load import display_path
        from lbscene.engine.files.yamlio import csv_rows, read_text_bounded

        shown = display_path(resolve(spec.path))
        text = read_text_bounded(resolve(spec.path), shown, 16 * 1024 * 1024)
        rows = [r for _, r in csv_rows(text, shown) if r and not r[0].lstrip().startswith("#")]
        try:
            col = [c.strip() for c in rows[0]].index("wavelength_nm")
            wl = [float(r[col]) for r in rows[1:]]
        except (ValueError, IndexError):
            return None, None
    if not wl or len(wl) < 3:
        return None, None
    w = np.sort(np.asarray(wl, float))
    d = np.diff(w)
    d = d[d > 0]
    return (float(np.median(d)), float(w[0])) if d.size else (None, None)


def _tile_column(spec, resolve):
    """For a CSV radiance spec without `column:`, prefer a column named 'radiance'."""
    if spec.type != "csv" or spec.column is not None:
        return spec
    from lbscene.engine.files.load import display_path
    from lbscene.engine.files.yamlio import read_text_bounded

    from lbscene.engine.files.yamlio import csv_rows

    shown = display_path(resolve(spec.path))
    text = read_text_bounded(resolve(spec.path), shown, 16 * 1024 * 1024)
    rows = [r for _, r in csv_rows(text, shown) if r and not r[0].lstrip().startswith("#")]
    if rows and "radiance" in [c.strip() for c in rows[0]]:
        return spec.model_copy(update={"column": "radiance"})
    return spec


# --------------------------------------------------------------------------- loading

def load_measurements(path: Path | str, booth: Path | str | None = None,
                      allowed_dirs: Iterable[Path] = ()) -> Measurements:
    """Load, validate and read a measurement set and its booth (raises LbsceneUserError)."""
    from lbscene.engine.files.load import display_path, load_document
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.scene.ir import IRSpectrum
    from lbscene.engine.spectra.evaluate import evaluate_spectrum
    from lbscene.schemas.measurement import MeasurementSet

    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.scene.ir import IRSpectrum
    from lbscene.engine.files.load import display_path, load_document
    from lbscene.engine.spectra.evaluate import evaluate_spectrum

    from lbscene.engine.files.yamlio import path_kind

    path = Path(path)
    kind = path_kind(path)
    if kind == "dir":
        cands = sorted(path.glob("*.yaml"))
        from lbscene.engine.files.yamlio import read_bytes_bounded

        def is_set(c: Path) -> bool:
            try:
                return b"kind: measurement_set" in read_bytes_bounded(c, str(c), 4 * 1024 * 1024,
                                                                     is_input=False)
            except LbsceneUserError:
                return False

        ms = [c for c in cands if is_set(c)]
        if len(ms) != 1:
            raise LbsceneUserError.single("LB011", "cannot tell which measurement set to use in this "
                                          "folder", display_path(path),
                                          expected="a measurement-set YAML file (kind: measurement_set)")
        path = ms[0]
    elif kind == "missing":
        raise LbsceneUserError.single("LB010", "file not found", str(path))
    doc = load_document(path, MeasurementSet, allowed_dirs=allowed_dirs)
    m: MeasurementSet = doc.model
    bag = DiagnosticBag()
    # ---- booth
    if booth is not None:
        booth_file = find_booth_file(booth)
    else:
        raw = Path(m.booth)
        target = raw if raw.is_absolute() else path.resolve().parent / raw
        if not target.exists():
            raise LbsceneUserError([Diagnostic(
                "LB200", f"booth {m.booth!r} not found (looked for {target})", doc.locate("booth"),
                value=repr(m.booth), expected="a booth folder or booth.yaml, relative to this file "
                                              "(or give --booth)")])
        booth_file = find_booth_file(target.resolve())
    ir = compile_booth(booth_file, allowed_dirs=allowed_dirs)
    if m.lighting not in ir.lighting:
        raise LbsceneUserError([Diagnostic(
            "LB202", f"the booth has no lighting configuration '{m.lighting}'", doc.locate("lighting"),
            value=repr(m.lighting), expected=f"one of {', '.join(ir.lighting)}")])
    groups = {lp.group for lp in ir.lamps}
    for j, g in enumerate(m.known_output_groups):
        if g not in groups:
            bag.add(Diagnostic("LB202", f"unknown lamp group '{g}'", doc.locate("known_output_groups", j),
                               value=repr(g), expected=f"one of {', '.join(sorted(groups))}"))
    # ---- measured reflectances replace the booth's
    if m.surface_reflectances:
        mats = dict(ir.materials)
        for mid, spec in m.surface_reflectances.items():
            if mid not in mats:
                bag.add(Diagnostic("LB202", f"the booth has no material '{mid}'",
                                   doc.locate("surface_reflectances", mid, key=True), value=repr(mid),
                                   expected=f"one of {', '.join(sorted(mats))}"))
                continue
            try:
                vals = evaluate_spectrum(spec, doc.resolve, "reflectance",
                                         display=_shown(doc, spec, f"surface_reflectances.{mid}"))
            except LbsceneUserError as exc:
                bag.extend(exc.diagnostics)
                continue
            vis = vals[(REFERENCE_WAVELENGTHS_NM >= 390) & (REFERENCE_WAVELENGTHS_NM <= 710)]
            if vis.max() > 1.5:
                bag.add(Diagnostic("LB406", f"reflectance of '{mid}' goes up to {vis.max():.4g}",
                                   doc.locate("surface_reflectances", mid), value=f"max {vis.max():.4g}",
                                   expected="a reflectance factor between 0 and 1",
                                   hint="the values look like percent: divide by 100 (or use scale: 0.01)"))
                continue
            mats[mid] = mats[mid].model_copy(update={
                "reflectance": IRSpectrum.from_1nm(np.clip(vals, 0, 1), ir.grid)})
        ir = ir.model_copy(update={"materials": mats})
    # ---- illuminance
    ill = None
    parts = []
    for i, f in enumerate(m.illuminance):
        data, diags = read_illuminance_csv(doc.resolve(f.path), display_path(doc.resolve(f.path)), default_z_mm=f.z_mm,
                                           default_orientation=f.orientation, interior=ir.interior)
        bag.extend(diags)
        parts.append(data)
    if parts and not bag.errors:
        ill = IlluminanceData(np.concatenate([p.points_mm for p in parts]),
                              np.concatenate([p.normals for p in parts]),
                              np.concatenate([p.lux for p in parts]),
                              sum((p.files for p in parts), []),
                              np.concatenate([p.lines for p in parts]),
                              sum((p.labels for p in parts), []))
        if len(parts) > 1:  # the bound on readings holds for the set, not only for each file
            from lbscene.engine.files.limits import check_work

            check_work("readings", len(ill.lux), doc.locate("illuminance"))
        if len(parts) > 1:  # duplicates across files
            key = np.c_[np.round(ill.points_mm / _DUP_TOL_MM), np.round(ill.normals * 1000)]
            _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
            if np.any(counts > 1):
                seen = set(first.tolist())
                for j in range(len(ill.lux)):
                    if j not in seen:
                        k = int(np.nonzero(np.all(key == key[j], axis=1))[0][0])
                        bag.add(Diagnostic("LB403", f"duplicate point, already in {ill.files[k]} line "
                                           f"{ill.lines[k]}", SourceLocation(ill.files[j], int(ill.lines[j]), 1),
                                           expected="one reading per point and orientation"))
    # ---- white tile
    tile = None
    if m.white_tile is not None:
        wt = m.white_tile
        try:
            spec = _tile_column(wt.radiance, doc.resolve)
            disp = _shown(doc, spec, "white_tile.radiance")
            rad = evaluate_spectrum(spec, doc.resolve, "emission", display=disp)
            refl = evaluate_spectrum(wt.reflectance, doc.resolve, "reflectance",
                                     display=_shown(doc, wt.reflectance, "white_tile.reflectance"))
        except LbsceneUserError as exc:
            bag.extend(exc.diagnostics)
        else:
            from lbscene.engine.scene.lint import spectrum_coverage

            cov = spectrum_coverage(spec, doc.resolve)
            covered = (REFERENCE_WAVELENGTHS_NM >= cov[0]) & (REFERENCE_WAVELENGTHS_NM <= cov[1]) \
                if cov else rad > 0
            vis = refl[(REFERENCE_WAVELENGTHS_NM >= 390) & (REFERENCE_WAVELENGTHS_NM <= 710)]
            if vis.max() > 1.5:
                bag.add(Diagnostic("LB406", f"tile reflectance goes up to {vis.max():.4g}",
                                   doc.locate("white_tile", "reflectance"), value=f"max {vis.max():.4g}",
                                   expected="a reflectance factor between 0 and 1",
                                   hint="the values look like percent: divide by 100"))
            elif not np.any(rad[covered] > 0):
                bag.add(Diagnostic("LB407", "white-tile radiance is zero everywhere",
                                   doc.locate("white_tile", "radiance"), expected="a measured spectrum"))
            else:
                pos = np.asarray(wt.position_mm if wt.position_mm is not None else ir.sample_position_mm,
                                 float)
                n = np.asarray(wt.normal, float)
                tile = TileData(pos, n / np.linalg.norm(n), rad, covered, refl, str(disp),
                                *_tile_sampling_nm(spec, doc.resolve))
    bag.raise_if_errors()
    known = list(dict.fromkeys(list(ir.fit.get("known_output_groups") or []) + list(m.known_output_groups)))
    return Measurements(path=path, name=m.name, booth_file=booth_file, lighting=m.lighting, ir=ir,
                        illuminance=ill, tile=tile,
                        declared_noise_percent=m.instrument.repeatability_percent,
                        spectral_noise_percent=m.instrument.spectral_noise_percent,
                        known_output_groups=known, doc=doc,
                        model_uncertainty_percent=m.model_uncertainty_percent)


#: A lamp's filter that lets through less than this share of the lamp's visible light (V(λ)-weighted)
#: is named as the likely cause of readings far above the model.
OPAQUE_FILTER_SHARE = 0.01


def _lamp_segment(lamp) -> tuple[np.ndarray, np.ndarray, float]:
    """Ends of a lamp's axis segment (a point for bulbs and points) and the radius of its body (mm)."""
    kind = getattr(lamp, "kind", None) or lamp.type        # an IR lamp or a booth file's lamp
    c = np.asarray(lamp.position_mm, float)
    ax = np.asarray(lamp.axis, float)
    half = lamp.length_mm / 2 if kind in ("tube", "panel") else 0.0
    body = max(float(lamp.radius_mm), 0.0) if kind != "panel" else 0.0
    return c - ax * half, c + ax * half, body


def likely_causes(meas: Measurements, ratio: float) -> list[str]:
    """Why the readings are ``ratio`` × the model's prediction, from the data, most specific first.

    * readings at points inside a lamp's body (the model divides by a distance of ~0 there);
    * sensors facing away from every lamp that is on (``orientation: down`` on the floor reads
      light from below the floor: nothing), the orientation sign against the lamps;
    * a filter, modelled (``spectral_filter``), that lets through less than
      :data:`OPAQUE_FILTER_SHARE` of its lamp's visible light;
    * otherwise the unit of the readings and the lamp output.

    Returns
    -------
    list of str
        One sentence per cause found (the unit one when no other is).
    """
    from lbscene.engine.scene.lint import LAMP_CLEARANCE_MM, _segment_distance_mm
    from lbscene.engine.spectra.evaluate import luminous_efficacy_sum

    ill, ir = meas.illuminance, meas.ir
    lamps = [lp for lp, _ in ir.lamps_on(meas.lighting)]
    out: list[str] = []
    inside = []
    for k, p in enumerate(ill.points_mm):
        for lp in lamps:
            a, b, body = _lamp_segment(lp)
            if _segment_distance_mm(p, a, b) - body < LAMP_CLEARANCE_MM:
                inside.append((k, lp.id))
                break
    if inside:
        k, lid = inside[0]
        out.append(f"{len(inside)} reading(s) lie inside the body of a lamp (first: {ill.files[k]}:{ill.lines[k]} in "
                   f"lamp '{lid}'): is z_mm in another unit, or the point mistyped?")
    flipped, level = [], []        # facing away from every lamp: turned the other way they would see one
    for k, (p, n) in enumerate(zip(ill.points_mm, ill.normals)):
        dots = np.array([float(n @ (q - p)) for lp in lamps for q in _lamp_segment(lp)[:2]])
        if dots.size and np.all(dots <= 0.0):
            (flipped if np.any(dots < 0.0) else level).append(k)
    if ratio > 1 and len(flipped) * 2 >= len(ill):
        k = flipped[0]
        out.append(f"{len(flipped)} of {len(ill)} readings face away from every lamp of lighting '{meas.lighting}' "
                   f"(sensor facing {ill.orientation_labels()[k]} at {ill.files[k]}:{ill.lines[k]}): check the "
                   "orientation column or the file's orientation: (a meter on the floor faces up)")
    elif ratio > 1 and len(flipped) + len(level) > 0 and (len(flipped) + len(level)) * 2 >= len(ill):
        k = (level or flipped)[0]
        out.append(f"{len(flipped) + len(level)} of {len(ill)} readings are level with or beyond every lamp of "
                   f"lighting '{meas.lighting}' (z = {ill.points_mm[k][2]:g} mm at {ill.files[k]}:{ill.lines[k]}): "
                   "check z_mm (millimetres above the floor)")
    if ratio > 1:
        for lp in lamps:
            if not lp.filter:
                continue
            bare = float(luminous_efficacy_sum(ir.lamp_emission_1nm(lp, with_filter=False)))
            seen = float(luminous_efficacy_sum(ir.lamp_emission_1nm(lp)))
            if bare > 0 and seen < OPAQUE_FILTER_SHARE * bare:
                out.append(f"filter '{lp.filter}' of lamp '{lp.id}' lets through {seen / bare:.2g} of its visible "
                           "light: check its transmittance (a fraction 0..1; the right column, the right file)")
                break
    if not out:
        out.append("check the unit of illuminance_lx (klx? fc?) and the lamp output in the booth")
    return out


def check_against_prediction(meas: Measurements, predicted_lux: np.ndarray | None,
                             predicted_tile_bands: np.ndarray | None, measured_tile_bands=None) -> None:
    """Mistakes that only a prediction reveals: ``LB406`` when the readings are far (×500) from the
    model, with its likely cause found in the data (:func:`likely_causes`: points inside a lamp,
    sensors facing away from the lamps, an opaque filter, else the unit), and mW radiance."""
    diags = []
    if predicted_lux is not None and meas.illuminance is not None and len(meas.illuminance):
        ratio = float(np.median(meas.illuminance.lux / np.maximum(predicted_lux, 1e-12)))
        if ratio < 2e-3 or ratio > 500:
            f = meas.illuminance.files[0]
            diags.append(Diagnostic(
                "LB406", f"readings are {ratio:.3g}× the model's prediction", SourceLocation(f, 1, 1),
                value=f"median ratio {ratio:.3g}", expected="lux, within a factor of a few of the model",
                hint="; ".join(likely_causes(meas, ratio))))
    if predicted_tile_bands is not None and measured_tile_bands is not None and meas.tile is not None:
        ok = measured_tile_bands > 0
        if ok.any():
            ratio = float(np.median(measured_tile_bands[ok] / np.maximum(predicted_tile_bands[ok], 1e-30)))
            if ratio < 2e-3 or ratio > 500:
                diags.append(Diagnostic(
                    "LB406", f"white-tile radiance is {ratio:.3g}× the model's prediction",
                    SourceLocation(meas.tile.display, 1, 1), value=f"median ratio {ratio:.3g}",
                    expected="W·sr⁻¹·m⁻²·nm⁻¹", hint="mW instead of W? counts instead of radiance?"))
    if diags:
        raise LbsceneUserError(diags)
