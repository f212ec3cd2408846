"""
Angular intensity profiles of lamps: I(θ) = I0 · f(θ), f(0) = 1.

θ is the angle from the lamp's ``aim`` direction.  Profiles are axially
symmetric about ``aim`` except IES files, which are read in full (LM-63
type C photometry: vertical angle from nadir, horizontal angle around it).

* ``isotropic``: f = 1
* ``gaussian``: f = exp(−(θ/2σ)²) (the seed's model; θ and σ in the same unit)
* ``cosine_power``: f = cosⁿθ for θ < 90°, else 0
* ``ies``: candela table of an IES LM-63 file, normalised by its peak

Examples
--------
>>> import numpy as np
>>> p = GaussianShape(sigma_deg=30.0)
>>> float(p(np.radians(60.0)))  # exp(-(60/60)^2)
0.36787944117144233
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .diagnostics import LbsceneUserError
from .yamlio import read_text_bounded

__all__ = ["IsotropicShape", "GaussianShape", "CosinePowerShape", "IesShape", "profile_shape",
           "solid_angle_weight_sr", "read_ies", "IesData"]


@dataclass(frozen=True)
class IsotropicShape:
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
    data: IesData

    def __call__(self, theta_rad, phi_rad=None):
        d = self.data
        t = np.degrees(np.asarray(theta_rad, float))
        peak = d.candela.max()
        if d.horizontal_deg.size == 1 or phi_rad is None:
            prof = d.candela.mean(axis=0)
            return np.interp(t, d.vertical_deg, prof, right=0.0) / peak
        ph = np.degrees(np.asarray(phi_rad, float)) % 360.0
        hmax = d.horizontal_deg[-1]
        if hmax <= 90.0:  # quadrant symmetry
            ph = np.where(ph > 180, 360 - ph, ph)
            ph = np.where(ph > 90, 180 - ph, ph)
        elif hmax <= 180.0:  # bilateral symmetry
            ph = np.where(ph > 180, 360 - ph, ph)
        from scipy.interpolate import RegularGridInterpolator

        interp = RegularGridInterpolator((d.horizontal_deg, d.vertical_deg), d.candela,
                                         bounds_error=False, fill_value=0.0)
        pts = np.stack(np.broadcast_arrays(ph, t), axis=-1)
        return interp(pts) / peak


def read_ies(path: Path, display: str) -> IesData:
    """Read an IES LM-63 (1995/2002/2019) photometric file (TILT=NONE only)."""
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
    try:
        nums = [float(x) for x in " ".join(lines[tilt_idx + 1:]).replace(",", " ").split()]
        _n_lamps, lm_per_lamp, mult, nv, nh = nums[0], nums[1], nums[2], int(nums[3]), int(nums[4])
        rest = nums[13:]  # skip photometric type, units, dimensions, ballast factors, watts
        v = np.array(rest[:nv])
        h = np.array(rest[nv:nv + nh])
        cd = np.array(rest[nv + nh: nv + nh + nv * nh]).reshape(nh, nv) * mult
    except (ValueError, IndexError) as exc:
        raise LbsceneUserError.single("LB203", f"malformed IES data: {exc}", display,
                                      expected="IES LM-63 numeric block after TILT=NONE")
    if cd.size != nv * nh or nv < 2 or np.any(np.diff(v) <= 0) or cd.max() <= 0:
        raise LbsceneUserError.single("LB203", "malformed IES candela table", display,
                                      expected="increasing vertical angles and positive candela")
    return IesData(v, h, cd, lm_per_lamp)


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


def solid_angle_weight_sr(shape, n: int = 2049) -> float:
    """∫ f(θ) dΩ over the sphere (axially averaged): flux = I0 · this."""
    theta = np.linspace(0.0, np.pi, n)
    f = np.asarray(shape(theta), float)
    return float(2.0 * np.pi * np.trapz(f * np.sin(theta), theta))
