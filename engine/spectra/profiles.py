"""
Angular intensity profiles of lamps: I(θ) = I0 · f(θ), f(0) = 1.

θ is the angle from the lamp's ``aim`` direction.  Profiles are axially
symmetric about ``aim`` except IES files, which are read in full (LM-63
type C photometry: vertical angle from nadir, horizontal angle around it).

* ``isotropic``: f = 1
* ``gaussian``: f = exp(−(θ/2σ)²) (the seed's model; θ and σ in the same unit)
* ``cosine_power``: f = cosⁿθ for θ < 90°, else 0
* ``ies``: candela table of an IES LM-63 file, normalised by its peak

A lamp's whole angular law is the law of its shape times its profile,
``I(u) = I_ref · b(u) · f(u)`` (see :mod:`lbscene.engine.light.emitters` for the shapes):
the photometric frame of a lamp (:func:`ies_frame`, :func:`ies_angles`: LM-63 type C,
γ = 0 along ``aim``, C = 0 along ``axis``), the shape's base law ``b``
(:func:`base_law`, :func:`base_solid_angle_sr`), the profile's value toward directions
(:func:`modulation`) and ``Φ / I_ref`` of the product (:func:`solid_angle_weight_sr`).

Examples
--------
>>> import numpy as np
>>> p = GaussianShape(sigma_deg=30.0)
>>> float(p(np.radians(60.0)))  # exp(-(60/60)^2)
0.36787944117144233
>>> round(base_solid_angle_sr("tube"), 6)  # π²
9.869604
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from lbscene.engine.files.diagnostics import LbsceneUserError
from lbscene.engine.files.yamlio import read_text_bounded

__all__ = ["IsotropicShape", "GaussianShape", "CosinePowerShape", "IesShape", "profile_shape",
           "modulation_solid_angle_sr", "read_ies", "IesData", "ies_text", "ies_frame", "ies_angles",
           "base_law", "base_solid_angle_sr", "sphere_directions", "solid_angle_weight_sr",
           "modulation", "MAX_IES_ANGLES"]


@dataclass(frozen=True)
class IsotropicShape:
    isotropic = True

    def __call__(self, theta_rad, phi_rad=None):
        return np.ones_like(np.asarray(theta_rad, float))


@dataclass(frozen=True)
class GaussianShape:
    sigma_deg: float

    def __call__(self, theta_rad, phi_rad=None):
        t = np.degrees(np.asarray(theta_rad, float))
        return np.exp(-(t / (2.0 * self.sigma_deg)) ** 2)


@dataclass(frozen=True)
class CosinePowerShape:
    exponent: float

    def __call__(self, theta_rad, phi_rad=None):
        c = np.cos(np.asarray(theta_rad, float))
        return np.where(c > 0, np.abs(c) ** self.exponent, 0.0)


@dataclass(frozen=True)
class IesData:
    vertical_deg: np.ndarray      # (nv,)
    horizontal_deg: np.ndarray    # (nh,)
    candela: np.ndarray           # (nh, nv), already multiplied by the file's multiplier
    lumens_per_lamp: float


@dataclass(frozen=True, eq=False)
class IesShape:
    """Candela table of an LM-63 type C file, normalised by its peak: f(γ, C).

    Bilinear in C and γ over the file's planes, unfolded by the file's symmetry
    (last horizontal angle 0: rotational; 90: quadrant; 180: bilateral about the
    C0–C180 plane; 360 or a full set without its 360° plane: none).  γ = 0 along
    the lamp's ``aim``, C = 0 along its ``axis`` (see :mod:`lbscene.engine.light.emitters`);
    0 outside the file's vertical range.
    """

    data: IesData
    two_d = True

    @cached_property
    def _table(self):
        d = self.data
        h = np.asarray(d.horizontal_deg, float)
        cd = np.asarray(d.candela, float)
        if h.size == 1:
            return None, cd[0]
        hmax = h[-1]
        if hmax <= 90.0:                     # quadrant symmetry: mirror to 0–180, then 0–360
            h, cd = np.r_[h, 180.0 - h[-2::-1]], np.r_[cd, cd[-2::-1]]
            hmax = 180.0
        if hmax <= 180.0:                    # bilateral symmetry about C0–C180
            h, cd = np.r_[h, 360.0 - h[-2::-1]], np.r_[cd, cd[-2::-1]]
        if h[-1] < 360.0:                    # full set written without its 360° plane
            h, cd = np.r_[h, 360.0], np.r_[cd, cd[:1]]
        return h, cd

    def __call__(self, theta_rad, phi_rad=None):
        d = self.data
        t = np.degrees(np.asarray(theta_rad, float))
        v = np.asarray(d.vertical_deg, float)
        peak = float(np.max(d.candela))
        h, cd = self._table
        inside = (t >= v[0] - 1e-9) & (t <= v[-1] + 1e-9)
        if h is None:
            return np.where(inside, np.interp(t, v, cd), 0.0) / peak
        if phi_rad is None:
            raise ValueError("this IES file is not rotationally symmetric: f needs the C angle")
        c = np.degrees(np.asarray(phi_rad, float)) % 360.0
        t, c = np.broadcast_arrays(t, c)
        j = np.clip(np.searchsorted(h, c, side="right") - 1, 0, h.size - 2)
        wc = np.clip((c - h[j]) / (h[j + 1] - h[j]), 0.0, 1.0)
        k = np.clip(np.searchsorted(v, t, side="right") - 1, 0, v.size - 2)
        wv = np.clip((t - v[k]) / (v[k + 1] - v[k]), 0.0, 1.0)
        val = ((1 - wc) * ((1 - wv) * cd[j, k] + wv * cd[j, k + 1])
               + wc * ((1 - wv) * cd[j + 1, k] + wv * cd[j + 1, k + 1]))
        return np.where(inside, val, 0.0) / peak


#: Most vertical or horizontal angles an IES file may declare (LM-63 files have at most a few
#: hundred; the count sizes the candela table before it is read).
MAX_IES_ANGLES = 10_000


def _ies_tokens(lines: list[str], first: int) -> list[tuple[str, int, int]]:
    """Whitespace- or comma-separated tokens after the TILT line, each with its line and column."""
    import re

    out = []
    for no in range(first, len(lines)):
        for m in re.finditer(r"[^\s,]+", lines[no]):
            out.append((m.group(0), no + 1, m.start() + 1))
    return out


def read_ies(path: Path, display: str) -> IesData:
    """Read an IES LM-63 (1995/2002/2019) photometric file (TILT=NONE only).

    Every number is checked where it stands (``LB203`` at its line and column): the counts of
    vertical and horizontal angles are whole numbers (1 …, vertical at least 2) whose table
    the file holds exactly (13 header numbers, the angles, the candela values: no more, no
    fewer); every value is a finite number; the multiplier is positive and the candela values
    (times the multiplier) are non-negative, with a positive peak.

    Raises
    ------
    LbsceneUserError
        ``LB203`` located in the IES file; ``LB0xx`` for a file that cannot be read.
    """
    text = read_text_bounded(path, display, 2 * 1024 * 1024)
    lines = text.splitlines()
    tilt_idx = next((i for i, ln in enumerate(lines) if ln.strip().upper().startswith("TILT=")), None)
    if tilt_idx is None:
        raise LbsceneUserError.single("LB203", "not an IES LM-63 file: no TILT= line", display,
                                      expected="an IES LM-63 photometric file")
    if lines[tilt_idx].strip().upper() != "TILT=NONE":
        raise LbsceneUserError.single("LB203", "IES files with lamp tilt data are not supported",
                                      display, tilt_idx + 1, 1, value=lines[tilt_idx].strip(),
                                      expected="TILT=NONE")
    toks = _ies_tokens(lines, tilt_idx + 1)

    def err(message, k=None, **kw):
        line, col = (toks[k][1], toks[k][2]) if k is not None and k < len(toks) else \
            ((toks[-1][1], toks[-1][2]) if toks else (tilt_idx + 1, 1))
        return LbsceneUserError.single("LB203", message, display, line, col, **kw)

    names = ("number of lamps", "lumens per lamp", "candela multiplier", "number of vertical angles",
             "number of horizontal angles", "photometric type", "units type", "width", "length", "height",
             "ballast factor", "ballast-lamp photometric factor", "input watts")
    if len(toks) < len(names):
        raise err(f"IES header has {len(toks)} of its {len(names)} numbers after TILT=NONE",
                  expected="lamps, lumens, multiplier, vertical and horizontal angle counts, photometric "
                           "type, units, width, length, height, ballast factor, future use, watts")

    def number(k: int, what: str) -> float:
        tok = toks[k][0]
        try:
            x = float(tok)
        except ValueError:
            x = float("nan")
        if not np.isfinite(x):
            raise err(f"IES {what} is not a finite number", k, value=repr(tok[:40]), expected="a finite number")
        return x

    head = [number(k, names[k]) for k in range(len(names))]
    counts = []
    for k in (3, 4):
        n = head[k]
        lo = 2 if k == 3 else 1
        if n != int(n) or not lo <= n <= MAX_IES_ANGLES:
            raise err(f"IES {names[k]} must be a whole number from {lo} to {MAX_IES_ANGLES}", k,
                      value=repr(toks[k][0]), expected=f"a whole number {lo} … {MAX_IES_ANGLES}")
        counts.append(int(n))
    nv, nh = counts
    mult, lm_per_lamp = head[2], head[1]
    if mult <= 0:
        raise err("IES candela multiplier must be positive", 2, value=repr(toks[2][0]), expected="a number > 0")
    need = len(names) + nv + nh + nv * nh
    if len(toks) != need:
        k = need if len(toks) > need else None
        raise err(f"IES file has {len(toks) - len(names)} values after its header; its counts "
                  f"({nv} vertical × {nh} horizontal angles) need {need - len(names)}", k,
                  value=f"{len(toks) - len(names)} values",
                  expected=f"{nv} vertical angles, {nh} horizontal angles and {nv} × {nh} candela values"
                           + (": the first extra value is here" if k is not None else ""))
    vals = np.array([number(k, "angle" if k < len(names) + nv + nh else "candela value")
                     for k in range(len(names), need)])
    v = vals[:nv]
    h = vals[nv:nv + nh]
    with np.errstate(over="ignore", invalid="ignore"):
        cd = vals[nv + nh:].reshape(nh, nv) * mult
    first_cd = len(names) + nv + nh
    bad = np.nonzero(~np.isfinite(cd.ravel()) | (cd.ravel() < 0))[0]
    if bad.size:
        k = first_cd + int(bad[0])
        raise err("IES candela value is negative" if cd.ravel()[bad[0]] < 0 else
                  "IES candela value times the multiplier overflows", k, value=repr(toks[k][0]),
                  expected="candela values ≥ 0 (finite after the multiplier)")
    if cd.max() <= 0:
        raise err("IES candela table is zero everywhere", first_cd, expected="a positive peak intensity")
    bad = np.nonzero(np.diff(v) <= 0)[0]
    if bad.size:
        k = len(names) + int(bad[0]) + 1
        raise err("IES vertical angles are not increasing", k, value=f"{v[bad[0] + 1]:g} after {v[bad[0]]:g}",
                  expected="strictly increasing vertical angles")
    if v[0] < 0 or v[-1] > 180:
        raise err(f"IES vertical angles {v[0]:g}..{v[-1]:g} outside 0..180°", len(names),
                  expected="type C vertical angles within 0..180°")
    full = h[-1] > 180.0 and h[-1] <= 360.0       # full set, with or without its 360° plane
    if h[0] != 0 or np.any(np.diff(h) <= 0) or not (nh == 1 or h[-1] in (90.0, 180.0) or full):
        raise err(
            f"IES horizontal angles {h[0]:g}..{h[-1]:g} are not a type C set", len(names) + nv,
            expected="horizontal angles increasing from 0 and ending at 0 (rotational), 90 "
                     "(quadrant), 180 (bilateral) or up to 360° (full; the 360° plane may be left out)")
    return IesData(v, h, cd, lm_per_lamp)


def ies_text(data: dict) -> str:
    """An IES LM-63-2002 file (type C, TILT=NONE, multiplier 1) of an IR profile's ``data`` table.

    Builds carry the lamp's photometry as a file (``ies/<lamp id>.ies``) for other tools;
    the numbers are the IR's, so :func:`read_ies` gives the same table back.
    """
    v = [float(x) for x in data["vertical_deg"]]
    h = [float(x) for x in data["horizontal_deg"]]
    cd = [[float(x) for x in row] for row in data["candela"]]
    fmt = lambda xs: " ".join(f"{x:.10g}" for x in xs)  # noqa: E731
    lines = ["IESNA:LM-63-2002", "[MANUFAC] written by lbscene from the scene IR", "TILT=NONE",
             f"1 {float(data['lumens_per_lamp']):.10g} 1 {len(v)} {len(h)} 1 2 0 0 0", "1 1 0",
             fmt(v), fmt(h)] + [fmt(row) for row in cd]
    return "\n".join(lines) + "\n"


def profile_shape(profile, resolve=None):
    """Shape function f(θ[, φ]) of a schema profile node (``Lamp.profile``) or IR dict."""
    p = profile if isinstance(profile, dict) else profile.model_dump()
    t = p["type"]
    if t == "isotropic":
        return IsotropicShape()
    if t == "gaussian":
        return GaussianShape(float(p["sigma_deg"]))
    if t == "cosine_power":
        return CosinePowerShape(float(p["exponent"]))
    if t == "ies":
        if "data" in p:  # IR form: the table is carried inline
            d = p["data"]
            return IesShape(IesData(np.array(d["vertical_deg"]), np.array(d["horizontal_deg"]),
                                    np.array(d["candela"]), float(d["lumens_per_lamp"])))
        path = resolve(p["path"])
        return IesShape(read_ies(path, p["path"]))
    raise ValueError(f"unknown profile type {t!r}")


def modulation_solid_angle_sr(shape, n: int = 2049) -> float:
    """∫ f dΩ over the sphere (sr) of a modulation alone: flux of a point = I0 · this."""
    if getattr(shape, "two_d", False):
        return solid_angle_weight_sr("point", (1.0, 0.0, 0.0), (0.0, 0.0, -1.0), shape)
    theta = np.linspace(0.0, np.pi, n)
    f = np.asarray(shape(theta), float)
    return float(2.0 * np.pi * np.trapz(f * np.sin(theta), theta))


# --------------------------------------------------------------------------- a lamp's angular law

def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def ies_frame(axis, aim) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal frame ``(e_C0, e_C90, aim)`` of a lamp's photometry.

    ``e_C0`` is ``axis`` made perpendicular to ``aim`` (any perpendicular when
    they are parallel), ``e_C90 = e_C0 × aim``.
    """
    aim = _unit(aim)
    a = np.asarray(axis, float)
    e0 = a - (a @ aim) * aim
    if np.linalg.norm(e0) < 1e-9:
        e0 = np.cross(aim, [1.0, 0.0, 0.0] if abs(aim[0]) < 0.9 else [0.0, 1.0, 0.0])
    e0 = _unit(e0)
    return e0, np.cross(e0, aim), aim


def ies_angles(u, axis, aim) -> tuple[np.ndarray, np.ndarray]:
    """(γ, C) in radians of unit directions ``u`` (..., 3) in a lamp's photometric frame."""
    e0, e90, a = ies_frame(axis, aim)
    u = np.asarray(u, float)
    gamma = np.arccos(np.clip(u @ a, -1.0, 1.0))
    c = np.arctan2(u @ e90, u @ e0) % (2 * np.pi)
    return gamma, c


def base_law(kind: str, u, axis, aim) -> np.ndarray:
    """Relative intensity ``b(u)`` of an unmodulated emitter (1 at its reference direction).

    tube: ``sin`` of the angle to ``axis``; panel: ``max(0, cos)`` of the angle to ``aim``;
    bulb and point: 1.
    """
    u = np.asarray(u, float)
    if kind == "tube":
        c = u @ _unit(axis)
        return np.sqrt(np.clip(1.0 - c * c, 0.0, None))
    if kind == "panel":
        return np.clip(u @ _unit(aim), 0.0, None)
    return np.ones(u.shape[:-1])


def base_solid_angle_sr(kind: str, end_caps_ratio: float = 0.0) -> float:
    """``Φ / I_ref`` of an unmodulated emitter, sr: tube π² (+ caps), panel π, bulb/point 4π.

    ``end_caps_ratio`` = cap area / lateral area, ``r / ℓ`` (cap flux π·L·2πr² over π²·L·2rℓ).
    """
    if kind == "tube":
        return float(np.pi ** 2 * (1.0 + end_caps_ratio))
    if kind == "panel":
        return float(np.pi)
    return float(4.0 * np.pi)


def sphere_directions(n: int) -> np.ndarray:
    """Fibonacci lattice: ``n`` nearly uniform unit vectors (equal solid angle 4π/n)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5 ** 0.5) * i
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def solid_angle_weight_sr(kind: str, axis, aim, shape=None, *, radius_mm: float = 0.0,
                          length_mm: float = 0.0, end_caps: bool = False, n: int = 200_000) -> float:
    """``Φ / I_ref`` (sr): ∫ b(u)·f(u) dΩ over the sphere (caps included), closed form when f ≡ 1."""
    ratio = radius_mm / length_mm if (kind == "tube" and end_caps and length_mm > 0) else 0.0
    if shape is None or getattr(shape, "isotropic", False):
        return base_solid_angle_sr(kind, ratio)
    u = sphere_directions(n)
    f = modulation(shape, u, axis, aim)
    b = base_law(kind, u, axis, aim)
    if ratio:
        # caps: two discs of area πr², normal ±axis: I = L·πr²·|cos| = I_ref·(π r/2ℓ)·|cos|
        b = b + (np.pi * ratio / 2.0) * np.abs(u @ _unit(axis))
    return float(4.0 * np.pi * np.mean(b * f))


def modulation(shape, u, axis, aim) -> np.ndarray:
    """Value of a profile ``shape`` toward unit directions ``u``: f(γ[, C])."""
    if shape is None:
        return np.ones(np.shape(u)[:-1])
    gamma, c = ies_angles(u, axis, aim)
    if getattr(shape, "two_d", False):
        return np.asarray(shape(gamma, c), float)
    return np.asarray(shape(gamma), float)
