"""
Validation of the forward model against committed reference renders (the "truth").

A validation scene is a booth folder whose inputs are all declared (lamp output
known, no fit).  Its reference renders are CSV files beside the booth,
``truth-<grid>.csv``, made by an independent renderer (the Mitsuba truth
provider, :mod:`~lbscene.engine.truth.mitsuba`) and committed as data, so the
comparison in the test suite and in ``benchmarks/bench_truth.py`` costs one
forward evaluation.

CSV format: ``# key: value`` header lines (renderer, version, variant, samples
per pass, effects, ``booth_sha256`` of the booth folder's files), then the
columns ``x_mm,y_mm,z_mm,normal_x,normal_y,normal_z,illuminance_lx,
std_error_lx,passes``.  ``booth_sha256`` lets a test see that a booth was
edited after its truth was rendered.

The deviation reported is the relative one per point,
:math:`δ_i = E_\\text{model}(p_i)/E_\\text{truth}(p_i) − 1`, summarised as RMS
:math:`\\sqrt{\\overline{δ^2}}` and max :math:`\\max |δ_i|` (percent).
The truth's own Monte Carlo noise :math:`ν = \\sqrt{\\overline{(σ_i/E_i)^2}}`
(σ its standard error) adds to the RMS in quadrature, independent of the model's
error, so :func:`compare_with_truth` also reports the model's RMS with that noise
removed, :math:`\\sqrt{\\max(0, \\overline{δ^2} − ν^2)}`.

Examples
--------
>>> floor_grid_mm(900, 600, nx=3, ny=2, margin_mm=50)[:, :2].tolist()
[[-400.0, -250.0], [0.0, -250.0], [400.0, -250.0], [-400.0, 250.0], [0.0, 250.0], [400.0, 250.0]]
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lbscene.engine.files.atomic import write_atomic

__all__ = ["TruthData", "floor_grid_mm", "validation_grid", "GRIDS", "booth_files_sha256",
           "write_truth_csv", "read_truth_csv", "render_truth_grid", "deviation_percent", "TRUTH_COLUMNS",
           "TruthComparison", "compare_with_truth"]

TRUTH_COLUMNS = ("x_mm", "y_mm", "z_mm", "normal_x", "normal_y", "normal_z", "illuminance_lx",
                 "std_error_lx", "passes")

#: the grids every validation scene is rendered on
GRIDS = ("a3", "floor")


def floor_grid_mm(width_mm: float, depth_mm: float, nx: int = 9, ny: int = 7,
                  margin_mm: float = 25.0) -> np.ndarray:
    """``nx × ny`` points (z = 0) covering a floor of ``width_mm × depth_mm`` centred on the
    origin, ``margin_mm`` in from its edges; shape (nx·ny, 3)."""
    x = np.linspace(-width_mm / 2 + margin_mm, width_mm / 2 - margin_mm, nx)
    y = np.linspace(-depth_mm / 2 + margin_mm, depth_mm / 2 - margin_mm, ny)
    X, Y = np.meshgrid(x, y, indexing="xy")
    return np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]


def validation_grid(ir, name: str) -> np.ndarray:
    """Receiver points of grid ``name``: ``'a3'`` (the 55-point A3 sheet) or ``'floor'`` (9 × 7
    over the booth's whole floor)."""
    from .synthetic import a3_grid

    if name == "a3":
        return a3_grid()
    if name == "floor":
        return floor_grid_mm(ir.interior.width_mm, ir.interior.depth_mm)
    raise KeyError(f"unknown grid {name!r}; known: {list(GRIDS)}")


def booth_files_sha256(booth_dir: Path | str) -> str:
    """sha256 over the booth folder's input files (YAML and spectra, not the truth CSVs)."""
    root = Path(booth_dir)
    h = hashlib.sha256()
    for f in sorted(root.rglob("*")):
        if f.is_file() and not f.name.startswith("truth-") and f.suffix in (".yaml", ".csv", ".ies", ".obj"):
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


@dataclass
class TruthData:
    """A reference render: receivers, illuminance and its Monte Carlo standard error."""

    points_mm: np.ndarray
    normals: np.ndarray
    illuminance_lx: np.ndarray
    std_error_lx: np.ndarray
    passes: np.ndarray
    meta: dict[str, str] = field(default_factory=dict)


def write_truth_csv(path: Path | str, data: TruthData) -> None:
    """Write ``data`` atomically (never a half-written file)."""
    lines = [f"# {k}: {v}" for k, v in data.meta.items()]
    lines.append(",".join(TRUTH_COLUMNS))
    for p, n, e, s, k in zip(data.points_mm, data.normals, data.illuminance_lx, data.std_error_lx,
                             data.passes):
        lines.append(f"{p[0]:.6g},{p[1]:.6g},{p[2]:.6g},{n[0]:.6g},{n[1]:.6g},{n[2]:.6g},"
                     f"{e:.8g},{s:.4g},{int(k)}")
    write_atomic(Path(path), "\n".join(lines) + "\n")


def render_truth_grid(truth, ir, grid: str, path: Path | str, meta: dict, *, target_rel_error: float,
                      max_passes: int) -> TruthData:
    """Render the illuminance on the validation grid ``grid`` of ``ir`` (receivers facing +z)
    with the truth provider ``truth`` to ``target_rel_error`` per receiver (at most
    ``max_passes`` passes), and write it to ``path`` with ``meta`` and the grid's name."""
    P = validation_grid(ir, grid)
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    res = truth.illuminance_with_error_lx(P, N, target_rel_error=target_rel_error, max_passes=max_passes)
    data = TruthData(P, N, res.illuminance_lx, res.std_error_lx, res.passes, {**meta, "grid": grid})
    write_truth_csv(path, data)
    return data


def read_truth_csv(path: Path | str) -> TruthData:
    meta, rows = {}, []
    header = None
    for line in Path(path).read_text().splitlines():
        if line.startswith("#"):
            k, _, v = line[1:].partition(":")
            meta[k.strip()] = v.strip()
        elif header is None:
            header = tuple(line.split(","))
            if header != TRUTH_COLUMNS:
                raise ValueError(f"{path}: columns {header}, expected {TRUTH_COLUMNS}")
        elif line.strip():
            rows.append([float(x) for x in line.split(",")])
    a = np.asarray(rows, float)
    return TruthData(a[:, 0:3], a[:, 3:6], a[:, 6], a[:, 7], a[:, 8].astype(int), meta)


def deviation_percent(model_lx, truth_lx) -> tuple[float, float]:
    """(RMS, max) of the relative deviation model/truth − 1, in percent."""
    d = np.asarray(model_lx, float) / np.asarray(truth_lx, float) - 1.0
    return float(100 * np.sqrt(np.mean(d ** 2))), float(100 * np.max(np.abs(d)))


@dataclass(frozen=True)
class TruthComparison:
    """The forward model against a committed truth on one grid (percentages of the truth).

    ``rms_percent`` and ``max_percent``: :func:`deviation_percent`; ``truth_noise_percent``:
    :math:`ν = 100\\sqrt{\\overline{(σ_i/E_i)^2}}`; ``rms_noise_removed_percent``:
    :math:`\\sqrt{\\max(0, \\text{rms}^2 − ν^2)}`, the model's own RMS deviation.
    ``booth_sha256_ok``: the booth folder is the one the truth was rendered from.
    """

    grid: str
    points: int
    rms_percent: float
    max_percent: float
    truth_noise_percent: float
    rms_noise_removed_percent: float
    booth_sha256_ok: bool
    model_lx: np.ndarray
    truth: TruthData


def compare_with_truth(booth_dir: Path | str, grid: str, *, ir=None, cache: dict | None = None
                       ) -> TruthComparison:
    """Forward model (physical surfaces, ``meter=False``; the lighting and effects of the booth,
    the lighting named in the CSV) against ``truth-<grid>.csv`` beside the booth.

    ``ir``: the compiled booth (compiled here if not given); ``cache``: the forward model's cache.
    Raises ``FileNotFoundError`` when the truth has not been rendered.
    """
    from lbscene.engine.light.forward import ForwardModel

    booth_dir = Path(booth_dir)
    truth = read_truth_csv(booth_dir / f"truth-{grid}.csv")
    if ir is None:
        from lbscene.engine.scene.compile import compile_booth

        ir = compile_booth(booth_dir)
    lighting = truth.meta.get("lighting") or next(iter(ir.lighting))
    model = ForwardModel(ir, lighting, cache=cache).illuminance_lx(truth.points_mm, truth.normals, meter=False)
    rms, mx = deviation_percent(model, truth.illuminance_lx)
    noise = float(100 * np.sqrt(np.mean((truth.std_error_lx / truth.illuminance_lx) ** 2)))
    return TruthComparison(grid=grid, points=len(truth.illuminance_lx), rms_percent=rms, max_percent=mx,
                           truth_noise_percent=noise,
                           rms_noise_removed_percent=float(np.sqrt(max(0.0, rms ** 2 - noise ** 2))),
                           booth_sha256_ok=truth.meta.get("booth_sha256") == booth_files_sha256(booth_dir),
                           model_lx=np.asarray(model, float), truth=truth)
