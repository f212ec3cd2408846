"""
The scene IR: one typed, immutable, hashable description of a compiled booth.

Everything downstream (USD stage, Cycles bake jobs, realtime render graphs,
the analytic forward model, the measurement loop) reads the IR, never the
YAML.  The IR is self-contained: spectra are carried as numbers (1 nm on
360–830 nm plus band values), files are already read, geometry is in
triangles, lamp output is absolute.

Conventions
-----------
* Booth coordinates in millimetres; origin at the floor centre, +x to the
  observer's right, +y toward the rear wall, +z up.
* ``*_1nm`` arrays are sampled on
  :data:`~lbscene.engine.spectra.bands.REFERENCE_WAVELENGTHS_NM`; ``*_bands`` are
  band means on the IR's :class:`~lbscene.engine.spectra.bands.BandGrid`.
* A lamp's emission: its reference spectral radiant intensity, of the *whole*
  lamp, is ``intensity_scale_W_sr_nm × spd_1nm`` in W·sr⁻¹·nm⁻¹ (bare lamp,
  before filter/reflector/diffuser): a tube's perpendicular to its axis, a
  panel's along its normal, a bulb's or point's in any direction.  What each
  lamp type emits around it is :mod:`lbscene.engine.light.emitters`.

``IR_VERSION`` changes whenever the serialised form changes meaning.
"""

from __future__ import annotations

import hashlib
import json
from functools import cached_property
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

__all__ = [
    "IR_VERSION",
    "IRSpectrum",
    "IRMaterial",
    "IRSurface",
    "IRLamp",
    "IRFilter",
    "IRReflector",
    "IRDiffuser",
    "IROccluder",
    "IRLighting",
    "IRGeometry",
    "IRObserver",
    "IRPlatform",
    "IRInterior",
    "SceneIR",
    "canonical_json",
]

IR_VERSION = 3                          # 2: platform pivot_mm; 3: Lambertian emitters, end_caps

Vec3 = tuple[float, float, float]


class _IR(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _round(x: float) -> float:
    # 10 significant digits: stable across platforms' last-bit float noise, far below any physics
    return float(f"{x:.10g}")


class IRSpectrum(_IR):
    """A spectrum as numbers: 1 nm reference samples and band means."""

    values_1nm: tuple[float, ...]
    bands: tuple[float, ...]

    @classmethod
    def from_1nm(cls, values_1nm, grid) -> "IRSpectrum":
        v = np.asarray(values_1nm, float)
        return cls(values_1nm=tuple(_round(x) for x in v),
                   bands=tuple(_round(x) for x in grid.integrate(v)))

    @property
    def array_1nm(self) -> np.ndarray:
        return np.asarray(self.values_1nm, float)

    @property
    def array_bands(self) -> np.ndarray:
        return np.asarray(self.bands, float)


class IRMaterial(_IR):
    id: str
    type: Literal["diffuse", "glossy"]
    reflectance: IRSpectrum
    #: lighting-dependent band reflectances (see lbscene.engine.colour.band_weighting)
    reflectance_bands_by_lighting: dict[str, tuple[float, ...]] = Field(default_factory=dict)
    gloss_GU: float = 0.0
    roughness: float = 0.5


class IRSurface(_IR):
    """A triangle mesh with one material (walls, floor, imported meshes)."""

    id: str
    role: str                      # floor, left_wall, …, platform, mesh
    material: str
    vertices_mm: tuple[Vec3, ...]
    triangles: tuple[tuple[int, int, int], ...]
    source: str = "parametric"     # parametric, obj:<path>, usd:<path>
    mount: str = "booth"           # 'platform': rotates with the platform (coordinates at rotation 0)

    @property
    def vertex_array(self) -> np.ndarray:
        return np.asarray(self.vertices_mm, float)

    @property
    def triangle_array(self) -> np.ndarray:
        return np.asarray(self.triangles, np.int64)

    def area_mm2(self) -> float:
        v = self.vertex_array
        t = self.triangle_array
        cr = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        return float(0.5 * np.linalg.norm(cr, axis=1).sum())


class IRLamp(_IR):
    id: str
    group: str
    kind: Literal["tube", "bulb", "panel", "point"]
    position_mm: Vec3
    axis: Vec3                     # unit vector
    aim: Vec3                      # unit vector (θ = 0 of the profile)
    length_mm: float
    width_mm: float
    radius_mm: float
    spd: IRSpectrum                # relative, bare lamp
    intensity_scale_W_sr_nm: float
    peak_luminous_intensity_cd: float
    luminous_flux_lm: float        # of the bare lamp with its profile
    profile: dict[str, Any]        # {'type': ..., params...}; IES tables inline under 'data'
    point_sources: int
    filter: str | None = None
    reflector: str | None = None
    mount: str = "booth"
    end_caps: bool = False

    @property
    def peak_intensity_1nm(self) -> np.ndarray:
        """Spectral radiant intensity at θ = 0 of the whole lamp, W·sr⁻¹·nm⁻¹."""
        return self.intensity_scale_W_sr_nm * self.spd.array_1nm

    def point_positions_mm(self, n: int | None = None) -> np.ndarray:
        """Point-source positions: centres of ``n`` equal segments along a tube, a grid of about
        ``n`` equal cells over a panel (length × width), the centre otherwise; shape (k, 3)."""
        n = n or self.point_sources
        p = np.asarray(self.position_mm, float)
        if self.kind == "panel" and self.length_mm > 0 and self.width_mm > 0:
            nu = max(1, int(round(np.sqrt(n * self.length_mm / self.width_mm))))
            nv = max(1, int(round(n / nu)))
            ax = np.asarray(self.axis, float)
            wdir = np.cross(np.asarray(self.aim, float), ax)
            wdir /= np.linalg.norm(wdir)
            su = ((np.arange(nu) + 0.5) / nu - 0.5) * self.length_mm
            sv = ((np.arange(nv) + 0.5) / nv - 0.5) * self.width_mm
            U, V = np.meshgrid(su, sv, indexing="ij")
            return p + np.outer(U.ravel(), ax) + np.outer(V.ravel(), wdir)
        if self.kind in ("tube", "panel") and self.length_mm > 0:
            s = (np.arange(n) + 0.5) / n - 0.5
            return p + np.outer(s * self.length_mm, np.asarray(self.axis))
        return np.repeat(p[None, :], n, axis=0)


class IRFilter(_IR):
    id: str
    transmittance: IRSpectrum


class IRReflector(_IR):
    id: str
    type: str
    reflectance: IRSpectrum
    distance_mm: float
    normal: Vec3
    width_mm: float
    #: a prism's apex angle (degrees, the declared or the default one); None for other types
    apex_angle_deg: float | None = None


class IRDiffuser(_IR):
    z_mm: float
    size_mm: tuple[float, float]
    centre_mm: tuple[float, float]
    thickness_mm: float
    transmittance: IRSpectrum
    scattering: dict[str, Any]
    ior: float


class IROccluder(_IR):
    id: str
    type: str
    centre_mm: Vec3
    normal: Vec3
    u_axis: Vec3
    size_mm: tuple[float, float]
    opening_mm: tuple[float, float] | None
    lamps: tuple[str, ...] | None
    material: str | None
    mount: str = "booth"


class IRLighting(_IR):
    name: str
    lamps: tuple[str, ...]
    dimming: dict[str, float]
    description: str = ""
    nominal_illuminance_lx: float | None = None
    standard: str = "none"


class IRGeometry(_IR):
    name: str
    illumination_deg: float
    aspecular_deg: float
    viewing_deg: float             # from the sample normal; negative: illumination side
    platform_rotation_deg: float | None = None


class IRObserver(_IR):
    type: str
    position_mm: Vec3
    look_at_mm: Vec3
    slit_size_mm: tuple[float, float] | None = None


class IRPlatform(_IR):
    centre_mm: Vec3
    size_mm: tuple[float, float]
    rotation_axis: Vec3
    pivot_mm: Vec3                      # a point of the rotation axis
    illumination_fixed_to_platform: bool
    illumination_angle_deg: float | None


class IRInterior(_IR):
    width_mm: float
    depth_mm: float
    height_mm: float
    open_front: bool


class SceneIR(_IR):
    """A compiled booth.  Immutable; ``content_hash`` identifies it."""

    ir_version: int = IR_VERSION
    booth_name: str
    booth_source: str                  # path of the booth file as given to the compiler
    provenance_status: str
    bands: dict[str, float | int]      # BandGrid.to_json()
    interior: IRInterior
    materials: dict[str, IRMaterial]
    surfaces: tuple[IRSurface, ...]
    lamps: tuple[IRLamp, ...]
    filters: dict[str, IRFilter]
    reflectors: dict[str, IRReflector]
    diffuser: IRDiffuser | None
    occluders: tuple[IROccluder, ...]
    lighting: dict[str, IRLighting]
    geometries: tuple[IRGeometry, ...]
    platform: IRPlatform | None
    observer: IRObserver
    sample_position_mm: Vec3
    effects: dict[str, dict[str, Any]]  # effect id → validated params (defaults filled in)
    fit: dict[str, Any]

    # ------------------------------------------------------------------ identity
    def to_json(self) -> str:
        return canonical_json(self.model_dump(mode="json"))

    @property
    def content_hash(self) -> str:
        """sha256 of the canonical JSON (hex).  Not cached: ``model_copy`` would carry a stale one."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()

    @property
    def light_hash(self) -> str:
        """sha256 (hex) of what the light depends on: the canonical JSON without the colour data
        the compiler derives from it (the materials' ``reflectance_bands_by_lighting``, a
        projection whose last digit depends on the machine's linear algebra: the SpectraLight's
        grey under UV light is 0.4289462734 on one processor and …733 on another).  The key of
        the light kept across processes and machines (the disk cache, the shipped tables)."""
        d = self.model_dump(mode="json")
        for m in d["materials"].values():
            m.pop("reflectance_bands_by_lighting", None)
        return hashlib.sha256(canonical_json(d).encode()).hexdigest()

    # ------------------------------------------------------------------ lookups
    @cached_property
    def grid(self):
        from lbscene.engine.spectra.bands import BandGrid

        return BandGrid(float(self.bands["first_centre_nm"]), float(self.bands["width_nm"]),
                        int(self.bands["count"]))

    def lamp(self, lamp_id: str) -> IRLamp:
        for lp in self.lamps:
            if lp.id == lamp_id:
                return lp
        raise KeyError(lamp_id)

    def lamps_on(self, lighting: str) -> list[tuple[IRLamp, float]]:
        """Lamps switched on in a lighting configuration, with their dimming level."""
        cfg = self.lighting[lighting]
        return [(self.lamp(i), float(cfg.dimming.get(i, 1.0))) for i in cfg.lamps]

    def lamp_emission_1nm(self, lamp: IRLamp, *, with_filter: bool | None = None) -> np.ndarray:
        """Peak spectral intensity of a lamp, W·sr⁻¹·nm⁻¹, after the booth's lamp-spectrum
        effects (:func:`lbscene.engine.light.lamp_spectrum.lamp_spectrum_1nm`: a spectrum shift, its
        filter when modelled).

        ``with_filter=None`` follows the model: the filter applies when the
        ``spectral_filter`` effect is enabled; True/False force it on/off.
        """
        from lbscene.engine.light.lamp_spectrum import lamp_spectrum_1nm

        eff = dict(self.effects)
        if with_filter is False:
            eff.pop("spectral_filter", None)
        elif with_filter and "spectral_filter" not in eff:
            eff["spectral_filter"] = {}
        return lamp_spectrum_1nm(self, lamp, eff)

    def lighting_spd_1nm(self, lighting: str, point_mm: Vec3 | None = None) -> np.ndarray:
        """Spectral irradiance (W·m⁻²·nm⁻¹) on an upward surface at ``point_mm``
        (default: the sample position) from the bare point-source model: lamps
        on, their filters when modelled, isotropic/declared profile; no
        inter-reflection, diffuser or occlusion.  Use the forward model
        (:mod:`lbscene.engine.light.forward`) for predictions with effects.
        """
        from lbscene.engine.light.emitters import emitter_from_lamp, unit_irradiance
        from lbscene.engine.spectra.profiles import profile_shape

        p = np.asarray(point_mm if point_mm is not None else self.sample_position_mm, float)
        total = np.zeros(len(self.lamps[0].spd.values_1nm))
        use_profile = "angular_profile" in self.effects
        for lamp, level in self.lamps_on(lighting):
            shape = profile_shape(lamp.profile) if use_profile else None
            geo = unit_irradiance(emitter_from_lamp(lamp, shape), p, (0.0, 0.0, 1.0),
                                  n_along=400, n_around=16)
            total += level * geo * self.lamp_emission_1nm(lamp)
        return total


def canonical_json(obj: Any) -> str:
    """Deterministic JSON: sorted keys, no whitespace variance, finite floats only."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=False)
