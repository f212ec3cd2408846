"""
Bake jobs: a self-contained, versioned description of one Cycles bake.

A job file carries everything the baker needs as numbers — band grid,
triangle meshes with per-band reflectances, emitters with absolute per-band
output, transmissive sheets (diffuser, filter panes), spectral filters,
the requested products and the sampling quality — so any machine with
``lbscene`` and ``bpy`` can run it (``python -m lbscene.bakers.run_job JOB.json
OUTDIR``) without the booth's files.

Conventions
-----------
* Booth coordinates in **millimetres**: origin at the floor centre, +x to the
  observer's right, +y toward the rear wall, +z up.  The baker converts to
  metres (1 Blender unit = 1 m).
* Every spectral quantity is a tuple of **band means** on the job's band grid
  (default 16 bands, edges 390–710 nm); channel names come from
  :func:`lbscene.engine.spectra.bands.band_labels`.
* Absolute radiometry: point emitters give spectral radiant intensity
  I(θ=0) in W·sr⁻¹·nm⁻¹ **per point**; area emitters give spectral radiance in
  W·sr⁻¹·m⁻²·nm⁻¹.  Products come out in W·m⁻²·nm⁻¹ (irradiance) and
  W·sr⁻¹·m⁻²·nm⁻¹ (radiance).
* Angular profiles are relative, f(0) = 1, θ measured from ``aim``; an
  :class:`IesProfile` is two-dimensional (type C: γ from ``aim``, C = 0 along
  its ``c0_axis``, C = 90° along its ``c90_axis``) and carries the LM-63 text,
  which Cycles' own IES parser reads.
* Area emitters may carry an :class:`AxialWeight` (tube-end falloff) and a
  :class:`Window` (a mirror image's light leaves only through the mirror).

``JOB_VERSION`` changes whenever the meaning of the serialised form changes;
versions in :data:`READABLE_JOB_VERSIONS` still load (version 2 only added
fields: a version 1 job means what it meant; version 3 made an area emitter hidden from the
camera a black body to camera rays instead of one they pass through, and a thin sheet with an
``ior`` reflect, and older jobs are rendered that way too; version 4 added the ``opal`` sheet,
a volumetric slab);
:attr:`BakeJob.content_hash` (sha256 of the canonical JSON) identifies a job
for the bake cache.

Examples
--------
>>> job = BakeJob(
...     name="one-lamp",
...     emitters=[PointEmitters(type="points", id="bulb", positions_mm=[(0, 0, 1000)],
...                             intensity_W_sr_nm=[0.01] * 16)],
...     products=[IrradiancePointsProduct(type="irradiance_points", id="centre",
...                                       points=[MeasurementPoint(position_mm=(0, 0, 0))])])
>>> len(job.content_hash), job.samples_for(job.products[0]) == QUALITY_PRESETS["preview"].points
(64, True)
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Annotated, Literal, Union

from pydantic import Field, field_validator, model_validator

from lbscene.schemas.base import StrictModel

__all__ = [
    "JOB_VERSION",
    "READABLE_JOB_VERSIONS",
    "JOB_KIND",
    "BandGridSpec",
    "JobMaterial",
    "JobMesh",
    "IsotropicProfile",
    "GaussianProfile",
    "CosinePowerProfile",
    "TableProfile",
    "IesProfile",
    "AxialWeight",
    "PointEmitters",
    "Window",
    "AreaEmitter",
    "TransmissiveSheet",
    "JobFilter",
    "MeasurementPoint",
    "RigidTransform",
    "EnvironmentMapProduct",
    "IrradianceMapProduct",
    "IrradiancePointsProduct",
    "QualityPreset",
    "QUALITY_PRESETS",
    "Quality",
    "BakeJob",
    "load_job",
    "save_job",
    "canonical_json",
]

JOB_VERSION = 4
#: versions this lbscene loads (2 added IES profiles, axial weights and windows on area emitters;
#: 3: an area emitter with ``visible_to_camera`` False stops camera rays as a black body, a thin
#: sheet with an ``ior`` reflects; 4: the ``opal`` sheet model, a scattering medium in a slab)
READABLE_JOB_VERSIONS = (1, 2, 3, 4)
JOB_KIND = "lbscene.bake_job"

Vec3 = tuple[float, float, float]
Bands = tuple[float, ...]
Triangles = tuple[tuple[int, int, int], ...]
JobId = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.\-]*$", max_length=96)]


def canonical_json(obj) -> str:
    """Deterministic JSON: sorted keys, compact, finite floats only."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=False)


def _unit(v: Vec3, what: str) -> Vec3:
    n = math.sqrt(sum(c * c for c in v))
    if n < 1e-12:
        raise ValueError(f"{what} must not be the zero vector")
    if abs(n - 1.0) < 1e-9:   # already unit: keep the bits (a saved job reloads identically)
        return tuple(float(c) for c in v)
    return tuple(float(c / n) for c in v)


def _rounded(obj, digits: int = 12):
    """Floats to ``digits`` significant digits (hash stable against last-bit noise)."""
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}")
    if isinstance(obj, dict):
        return {k: _rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_rounded(v, digits) for v in obj]
    return obj


# --------------------------------------------------------------------------- bands


class BandGridSpec(StrictModel):
    """Contiguous equal-width bands (the engine's :class:`~lbscene.engine.spectra.bands.BandGrid`)."""

    first_centre_nm: float = 400.0
    width_nm: float = Field(20.0, gt=0)
    count: int = Field(16, ge=1, le=64)

    def grid(self):
        from lbscene.engine.spectra.bands import BandGrid

        return BandGrid(self.first_centre_nm, self.width_nm, self.count)

    def labels(self) -> list[str]:
        """Channel names such as ``'390-410nm'``."""
        from lbscene.engine.spectra.bands import band_labels

        return band_labels(self.grid())

    def edges_nm(self) -> list[float]:
        return [float(x) for x in self.grid().edges_nm]

    def centres_nm(self) -> list[float]:
        return [float(x) for x in self.grid().centres_nm]


# --------------------------------------------------------------------------- geometry


class JobMaterial(StrictModel):
    """An opaque surface.

    * ``diffuse``: Lambertian, reflectance factor ``reflectance`` per band.
    * ``glossy``: Lambertian base ``reflectance`` under a dielectric coat of
      roughness ``roughness`` (Blender's Principled BSDF, IOR 1.5).
    * ``mirror``: metallic GGX reflector of spectral reflectance ``reflectance``
      and roughness ``roughness`` (Blender's convention, α = roughness²).
      Light reaching a receiver via a mirror is *indirect* light in Cycles; a
      roughness > 0 lets Cycles sample point lamps through it.
    """

    type: Literal["diffuse", "glossy", "mirror"] = "diffuse"
    reflectance: Bands
    roughness: float = Field(0.5, ge=0, le=1)

    @field_validator("reflectance")
    @classmethod
    def _range(cls, v):
        if any(not (0.0 <= x <= 1.0) for x in v):
            raise ValueError("reflectance band values must lie in [0, 1]")
        return v


class JobMesh(StrictModel):
    """A triangle mesh in booth millimetres with one material."""

    id: JobId
    material: JobId
    vertices_mm: tuple[Vec3, ...] = Field(min_length=3)
    triangles: Triangles = Field(min_length=1)
    role: str = "surface"
    #: hide from camera rays (environment maps) while still reflecting/occluding
    visible_to_camera: bool = True
    #: transform group (see ``group_transforms`` of products)
    group: str | None = None

    @model_validator(mode="after")
    def _indices(self):
        n = len(self.vertices_mm)
        if any(not (0 <= i < n) for t in self.triangles for i in t):
            raise ValueError(f"triangle index out of range (mesh has {n} vertices)")
        return self


# --------------------------------------------------------------------------- emitters


class IsotropicProfile(StrictModel):
    type: Literal["isotropic"] = "isotropic"


class GaussianProfile(StrictModel):
    """f(θ) = exp(−(θ/2σ)²) (the seed's lamp model)."""

    type: Literal["gaussian"] = "gaussian"
    sigma_deg: float = Field(gt=0)


class CosinePowerProfile(StrictModel):
    """f(θ) = cosⁿθ for θ < 90°, 0 beyond."""

    type: Literal["cosine_power"] = "cosine_power"
    exponent: float = Field(ge=0)


class TableProfile(StrictModel):
    """Axially symmetric tabulated profile, linear interpolation in θ (e.g. from an IES file)."""

    type: Literal["table"] = "table"
    theta_deg: tuple[float, ...] = Field(min_length=2)
    relative: tuple[float, ...] = Field(min_length=2)

    @model_validator(mode="after")
    def _table(self):
        t = self.theta_deg
        if len(t) != len(self.relative):
            raise ValueError("theta_deg and relative must have the same length")
        if any(b <= a for a, b in zip(t, t[1:])) or t[0] < 0 or t[-1] > 180:
            raise ValueError("theta_deg must increase strictly within 0..180")
        if any(x < 0 for x in self.relative):
            raise ValueError("relative intensities must be >= 0")
        return self


class IesProfile(StrictModel):
    """IES LM-63 type C photometry in two dimensions: f(γ, C) = I(γ, C) / ``peak_cd``.

    γ is the angle from the emitter's ``aim``; C the angle around it, 0 along ``c0_axis``
    and 90° along ``c90_axis`` (both ⊥ ``aim``; for a lamp ``c90 = c0 × aim``, for its mirror
    image the mirrored vectors, a frame of the other handedness).  ``ies_text`` is the file
    (TILT=NONE), read by Cycles' own IES parser, which unfolds the file's symmetry itself;
    ``peak_cd`` is its largest candela value (× multiplier).
    """

    type: Literal["ies"] = "ies"
    ies_text: str = Field(min_length=1, max_length=4_000_000)
    c0_axis: Vec3
    c90_axis: Vec3
    peak_cd: float = Field(gt=0)

    @field_validator("c0_axis", "c90_axis")
    @classmethod
    def _axes(cls, v):
        return _unit(v, "IES frame axis")

    @model_validator(mode="after")
    def _frame(self):
        if abs(sum(a * b for a, b in zip(self.c0_axis, self.c90_axis))) > 1e-6:
            raise ValueError("c0_axis and c90_axis must be perpendicular")
        if "TILT=NONE" not in self.ies_text.upper().replace(" ", ""):
            raise ValueError("ies_text must be an IES LM-63 file with TILT=NONE")
        return self


Profile = Annotated[Union[IsotropicProfile, GaussianProfile, CosinePowerProfile, TableProfile, IesProfile],
                    Field(discriminator="type")]


class AxialWeight(StrictModel):
    """Tube-end falloff on an emitting surface: radiance × w(d), d the distance (mm) from the
    nearer end along ``axis`` of a tube of ``length_mm`` centred at ``centre_mm``:

    .. math:: w = e + (1 - e)\\,\\mathrm{clip}(d / ℓ_f, 0, 1)

    (``end_level`` e, ``falloff_length_mm`` ℓ_f; the ``tube_end_falloff`` effect).  Evaluated
    in the emitter's own (untransformed) coordinates, so it turns with its group.
    """

    type: Literal["linear_ends"] = "linear_ends"
    centre_mm: Vec3
    axis: Vec3
    length_mm: float = Field(gt=0)
    end_level: float = Field(ge=0, le=1)
    falloff_length_mm: float = Field(gt=0)

    @field_validator("axis")
    @classmethod
    def _axis(cls, v):
        return _unit(v, "axial weight axis")


class Window(StrictModel):
    """A rectangle that an emitter's light must pass through (a mirror, for its image).

    ``normal`` points to the side the light goes to.  Objects lying entirely on
    or behind the window plane do not block the emitter (they are behind the
    mirror, between it and the image).
    """

    centre_mm: Vec3
    normal: Vec3
    u_axis: Vec3
    half_size_mm: tuple[float, float]

    @field_validator("normal", "u_axis")
    @classmethod
    def _dirs(cls, v):
        return _unit(v, "window direction")


class PointEmitters(StrictModel):
    """Point sources sharing a spectrum and a profile (e.g. N points along a tube).

    ``intensity_W_sr_nm`` is the spectral radiant intensity **of each point** along
    ``aim`` (θ = 0), band means in W·sr⁻¹·nm⁻¹.  I(θ) = I0·f(θ).
    """

    type: Literal["points"] = "points"
    id: JobId
    positions_mm: tuple[Vec3, ...] = Field(min_length=1, max_length=100000)
    aim: Vec3 = (0.0, 0.0, -1.0)
    intensity_W_sr_nm: Bands
    profile: Profile = IsotropicProfile()
    #: 0: true points (invisible to the camera); > 0: uniform spheres of that radius with the
    #: same intensity, visible in environment maps (keep spheres from overlapping)
    radius_mm: float = Field(0.0, ge=0)
    #: relative weight of each point (tube-end falloff); default all 1
    weights: tuple[float, ...] | None = None
    filter: JobId | None = None
    group: str | None = None
    #: light leaves only through this rectangle (mirror images); None: everywhere
    window: Window | None = None

    @field_validator("aim")
    @classmethod
    def _aim(cls, v):
        return _unit(v, "aim")

    @model_validator(mode="after")
    def _weights(self):
        if self.weights is not None and len(self.weights) != len(self.positions_mm):
            raise ValueError("weights must have one value per position")
        return self


class AreaEmitter(StrictModel):
    """A Lambertian emitting surface of spectral radiance ``radiance_W_sr_m2_nm``.

    Emits on the side its triangles face (right-hand rule), or both sides
    when ``two_sided``.
    """

    type: Literal["area"] = "area"
    id: JobId
    vertices_mm: tuple[Vec3, ...] = Field(min_length=3)
    triangles: Triangles = Field(min_length=1)
    radiance_W_sr_m2_nm: Bands
    two_sided: bool = False
    filter: JobId | None = None
    group: str | None = None
    #: angular modulation f(θ) of the radiance, θ from ``aim`` (a lamp's declared profile)
    profile: Profile = IsotropicProfile()
    aim: Vec3 = (0.0, 0.0, -1.0)
    #: False for lamps: environment maps leave their straight light to the direct products and
    #: see the lamp as a black body (opaque: camera rays stop at it, as they do at the real lamp);
    #: every other ray sees its emission.  A mirror image (``window``) is virtual: camera rays
    #: pass it
    visible_to_camera: bool = True
    #: radiance × w(position along a tube) (tube-end falloff); None: uniform
    axial_weight: AxialWeight | None = None
    #: light leaves only through this rectangle (a mirror image of a lamp); None: everywhere
    window: Window | None = None

    @field_validator("aim")
    @classmethod
    def _aim(cls, v):
        return _unit(v, "aim")


Emitter = Annotated[Union[PointEmitters, AreaEmitter], Field(discriminator="type")]


class JobFilter(StrictModel):
    """A spectral filter: multiplies the output of the emitters that name it."""

    transmittance: Bands


class TransmissiveSheet(StrictModel):
    r"""A diffuser plate or filter pane.

    ``model='thin'`` (default): a non-refracting sheet.  ``transmittance`` is the
    plate's total transmittance at normal incidence (surface reflections included);
    when ``ior`` is set its regular part falls with incidence angle like a clear
    plate's Fresnel transmittance (both faces, incoherent multiple reflections),
    normalised to ``transmittance`` at 0°.  A ``diffuse_fraction`` of the
    transmitted light is scattered (Translucent BSDF), leaving with the opal exit
    law (1 − F(θ))/(1 − F_h) at the viewing angle when ``ior`` is set.  With ``ior``
    its faces also reflect, as a sharp mirror of the clear plate's reflectance
    R(θ) = 1 − S(θ) (both faces, incoherent; 8.2 % at 0° for n = 1.52), so the
    light a plate sends back into a luminaire cavity or down into the booth takes
    part in the inter-reflection (job version 3).  Light
    goes straight through, so Cycles samples point lamps behind it directly
    (shadow rays are attenuated, not blocked); ``roughness`` is recorded but
    only blurs in the ``glass`` model (for the seed's 0.04, α = 0.0016: a spread
    far below a degree).  A shader sees one direction only: a thin sheet has no
    entry law and no diffuse reflection (what an opal plate needs: ``opal``).

    ``model='glass'``: a closed slab of ``thickness_mm`` with Cycles' Glass BSDF
    (roughness, ior).  Physically complete but a refracting surface blocks
    shadow rays, so lamps behind it are reached only by path tracing
    (caustics): use area emitters and many samples.  The absorption is the
    declared ``transmittance`` over ``reference_transmittance`` (the
    non-absorbing plate's total at normal incidence; default the clear slab's).

    ``model='opal'`` (job version 4): an opal plate as the scattering layer it is, as the
    Mitsuba truth draws it: a closed slab of ``thickness_mm`` (mid-plane on the sheet) whose
    faces are a smooth dielectric of ``ior`` (no surface at all for ``ior`` 1 or None: shadow
    rays cross it, attenuated by the medium, and reach the lamps from every scattering event),
    filled with a homogeneous medium: scattering coefficient ``scattering_per_mm``
    :math:`σ_s`, Henyey–Greenstein ``anisotropy`` :math:`g`, and per band
    ``absorption_per_mm`` :math:`σ_a` (None: none).  :func:`lbscene.bakers.opal_slab.opal_slab_medium`
    makes them from the declared total transmittance and diffuse fraction;
    ``transmittance`` and ``diffuse_fraction`` are recorded, not used.
    """

    id: JobId
    role: Literal["diffuser", "filter"] = "diffuser"
    vertices_mm: tuple[Vec3, ...] = Field(min_length=3)
    triangles: Triangles = Field(min_length=1)
    transmittance: Bands
    ior: float | None = Field(1.52, ge=1.0, le=3.0)
    roughness: float = Field(0.0, ge=0, le=1)
    diffuse_fraction: float = Field(0.0, ge=0, le=1)
    model: Literal["thin", "glass", "opal"] = "thin"
    thickness_mm: float = Field(4.0, gt=0)
    reference_transmittance: float | None = Field(None, gt=0, le=1)
    #: ``opal``: the medium's scattering coefficient σ_s (mm⁻¹), HG asymmetry g and absorption
    #: coefficient σ_a per band (mm⁻¹; None: a non-absorbing medium)
    scattering_per_mm: float | None = Field(None, gt=0)
    anisotropy: float = Field(0.0, gt=-1, lt=1)
    absorption_per_mm: Bands | None = None
    group: str | None = None

    @field_validator("transmittance")
    @classmethod
    def _range(cls, v):
        if any(not (0.0 <= x <= 1.0) for x in v):
            raise ValueError("transmittance band values must lie in [0, 1]")
        return v

    @field_validator("absorption_per_mm")
    @classmethod
    def _absorption(cls, v):
        if v is not None and any(not (x >= 0.0) for x in v):
            raise ValueError("absorption_per_mm band values must be >= 0")
        return v

    @model_validator(mode="after")
    def _opal(self):
        if self.model == "opal" and self.scattering_per_mm is None:
            raise ValueError("an 'opal' sheet needs scattering_per_mm (its medium)")
        return self


# --------------------------------------------------------------------------- products


class MeasurementPoint(StrictModel):
    position_mm: Vec3
    normal: Vec3 = (0.0, 0.0, 1.0)
    name: str | None = None

    @field_validator("normal")
    @classmethod
    def _normal(cls, v):
        return _unit(v, "normal")


class RigidTransform(StrictModel):
    """A rotation by ``angle_deg`` (right-hand rule) about ``axis`` through ``centre_mm``."""

    axis: Vec3
    angle_deg: float
    centre_mm: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("axis")
    @classmethod
    def _axis(cls, v):
        return _unit(v, "axis")

    def matrix(self):
        """4×4 homogeneous matrix acting on column vectors in millimetres."""
        import numpy as np

        from lbscene.engine.light.geometry import rotation_matrix

        R = rotation_matrix(self.axis, self.angle_deg)
        c = np.asarray(self.centre_mm, float)
        M = np.eye(4)
        M[:3, :3] = R
        M[:3, 3] = c - R @ c
        return M


class _Product(StrictModel):
    id: JobId
    #: samples per pixel/texel for this product; default from the job's quality
    samples: int | None = Field(None, ge=2, le=1_000_000)
    #: objects of these groups are moved for this product only (e.g. a luminaire that
    #: turns with a rotating platform)
    group_transforms: dict[str, RigidTransform] = Field(default_factory=dict)


class EnvironmentMapProduct(_Product):
    """Spectral radiance arriving at ``position_mm`` from all directions.

    Map frame: ``forward`` (the centre of an equirect map), ``up``;
    left = up × forward.  **Equirect** (width W, height W/2): pixel
    column u∈[0,1) → azimuth φ = π(1 − 2u) measured from ``forward`` toward
    left, row v∈[0,1) from the top → elevation π(½ − v) toward ``up``.
    **Cube**: six square faces in a horizontal strip, order +F, −F, +L, −L, +U,
    −U (see :func:`lbscene.bakers.products.cube_face_directions`).
    Units W·sr⁻¹·m⁻²·nm⁻¹.
    """

    type: Literal["environment_map"] = "environment_map"
    position_mm: Vec3
    forward: Vec3 = (0.0, 1.0, 0.0)
    up: Vec3 = (0.0, 0.0, 1.0)
    projection: Literal["equirect", "cube"] = "equirect"
    width_px: int = Field(256, ge=4, le=16384)
    geometry: str | None = None
    #: camera rays start this far from the position (skip the sample's own support)
    clip_start_mm: float = Field(0.1, gt=0)
    #: point lamps of radius 0 are invisible to camera rays: the map then holds all light
    #: *except* that seen directly from them, whose irradiance this points product gives
    #: (same position, several normals; see lbscene.bakers.from_ir)
    direct_product: JobId | None = None

    @model_validator(mode="after")
    def _frame(self):
        f = _unit(self.forward, "forward")
        u = _unit(self.up, "up")
        if abs(sum(a * b for a, b in zip(f, u))) > 1e-6:
            raise ValueError("forward and up must be perpendicular")
        if self.projection == "equirect" and self.width_px % 2:
            raise ValueError("an equirect map needs an even width_px (height = width/2)")
        return self


class IrradianceMapProduct(_Product):
    """Spectral irradiance over a rectangle (floor, platform), W·m⁻²·nm⁻¹.

    The rectangle spans ``origin_mm + s·size[0]·u_axis + t·size[1]·v_axis``,
    s, t ∈ [0, 1]; receiver normal = u × v (the side that is measured).
    Pixel (row j from the top, column i) is the irradiance at the point
    s = (i + ½)/nx, t = 1 − (j + ½)/ny (a point value, ready for bilinear
    interpolation, not a texel mean), measured by a small cosine sensor
    ``offset_mm`` above the surface that is invisible to every other ray.
    """

    type: Literal["irradiance_map"] = "irradiance_map"
    origin_mm: Vec3
    u_axis: Vec3 = (1.0, 0.0, 0.0)
    v_axis: Vec3 = (0.0, 1.0, 0.0)
    size_mm: tuple[float, float]
    resolution: tuple[int, int] = (64, 64)
    offset_mm: float = Field(0.05, ge=0)
    light_paths: Literal["all", "direct"] = "all"

    @model_validator(mode="after")
    def _frame(self):
        u = _unit(self.u_axis, "u_axis")
        v = _unit(self.v_axis, "v_axis")
        if abs(sum(a * b for a, b in zip(u, v))) > 1e-6:
            raise ValueError("u_axis and v_axis must be perpendicular")
        if min(self.size_mm) <= 0 or min(self.resolution) < 1 or max(self.resolution) > 8192:
            raise ValueError("size_mm must be > 0 and resolution within 1..8192")
        return self


class IrradiancePointsProduct(_Product):
    """Spectral irradiance (W·m⁻²·nm⁻¹) and illuminance (lx) at points with normals.

    Each point is a small square cosine sensor (``sensor_size_mm``) placed
    ``offset_mm`` along its normal, invisible to every other ray.
    ``light_paths='direct'`` keeps light arriving straight from emitters
    (through transparent sheets), the cross-check of the analytic model.
    """

    type: Literal["irradiance_points"] = "irradiance_points"
    points: tuple[MeasurementPoint, ...] = Field(min_length=1, max_length=100000)
    sensor_size_mm: float = Field(1.0, gt=0)
    #: lift off the surface the point lies on (float precision); the bias is ~2·offset/distance
    offset_mm: float = Field(0.05, ge=0)
    light_paths: Literal["all", "direct"] = "all"


Product = Annotated[Union[EnvironmentMapProduct, IrradianceMapProduct, IrradiancePointsProduct],
                    Field(discriminator="type")]


# --------------------------------------------------------------------------- quality


class QualityPreset(StrictModel):
    """Samples per product kind and light-path depth.

    ``points_noise_target``: irradiance-points products (the grid, measurement
    points) keep sampling, in rounds, until the RMS relative noise of their
    illuminance is at most this (two-half estimate), up to
    ``points_max_samples`` samples; ``None``: a fixed ``points`` samples.
    """

    points: int
    map: int
    environment: int
    max_bounces: int
    points_noise_target: float | None = None
    points_max_samples: int | None = None


#: preview: one lighting of a booth in well under a minute on 2 CPU cores (8 bounces: light
#: that bounced inside the BYK's white luminaire cavity is 2 % short of converged, 4 bounces
#: missed 10 %, at nearly the same cost);
#: final: ≤ 1 % noise at grid points (see benchmarks/bench_bake.py): 2048 samples are
#: enough for open booths (~0.3 %); a white luminaire cavity lit from inside (BYK), seen by
#: the points only through its aperture, needs ~14 000; 32 bounces: 12 left the cavity's light
#: 0.6 % short, and a 64-bounce bake of the BYK grid took no longer than a 12-bounce one.
QUALITY_PRESETS: dict[str, QualityPreset] = {
    "preview": QualityPreset(points=192, map=24, environment=8, max_bounces=8),
    "final": QualityPreset(points=2048, map=128, environment=64, max_bounces=32,
                           points_noise_target=0.01, points_max_samples=32768),
}


class Quality(StrictModel):
    preset: Literal["preview", "final"] = "preview"
    #: overrides every product's preset samples when given
    samples: int | None = Field(None, ge=2, le=1_000_000)
    max_bounces: int | None = Field(None, ge=0, le=1024)
    seed: int = Field(0, ge=0, le=2**31 - 1)
    #: render twice at half the samples with different seeds; the halves' difference
    #: estimates the noise of their mean (the product)
    noise_estimate: bool = True
    #: Cycles path guiding (CPU only, unbiased): less noise from hot spots such as a lamp
    #: close to a ceiling, at some cost per sample; results then differ between CPU and GPU runs
    path_guiding: bool = False
    #: RMS relative illuminance noise irradiance-points products sample down to (None: the
    #: preset's ``points_noise_target``); ignored when ``samples`` fixes the samples
    noise_target: float | None = Field(None, gt=0, lt=1)


# --------------------------------------------------------------------------- job


class BakeJob(StrictModel):
    """One self-contained Cycles bake (one Blender scene, several products)."""

    kind: Literal["lbscene.bake_job"] = JOB_KIND
    job_version: int = JOB_VERSION
    name: JobId
    #: where the job came from (IR hash, booth, lighting); informative, part of the hash
    source: dict[str, str] = Field(default_factory=dict)
    bands: BandGridSpec = BandGridSpec()
    materials: dict[JobId, JobMaterial] = Field(default_factory=dict)
    meshes: tuple[JobMesh, ...] = ()
    emitters: tuple[Emitter, ...] = Field(min_length=1)
    filters: dict[JobId, JobFilter] = Field(default_factory=dict)
    sheets: tuple[TransmissiveSheet, ...] = ()
    products: tuple[Product, ...] = Field(min_length=1)
    quality: Quality = Quality()

    @field_validator("job_version")
    @classmethod
    def _version(cls, v):
        if v not in READABLE_JOB_VERSIONS:
            raise ValueError(f"unsupported bake job version {v}; this lbscene reads versions "
                             f"{', '.join(map(str, READABLE_JOB_VERSIONS))}")
        return v

    @model_validator(mode="after")
    def _consistent(self):
        n = self.bands.count

        def check(values, what):
            if len(values) != n:
                raise ValueError(f"{what}: {len(values)} band values for a {n}-band grid")

        for mid, m in self.materials.items():
            check(m.reflectance, f"material {mid}")
        for mesh in self.meshes:
            if mesh.material not in self.materials:
                raise ValueError(f"mesh {mesh.id}: unknown material {mesh.material!r}")
        for fid, f in self.filters.items():
            check(f.transmittance, f"filter {fid}")
        for e in self.emitters:
            check(e.intensity_W_sr_nm if e.type == "points" else e.radiance_W_sr_m2_nm,
                  f"emitter {e.id}")
            if e.filter is not None and e.filter not in self.filters:
                raise ValueError(f"emitter {e.id}: unknown filter {e.filter!r}")
        for s in self.sheets:
            check(s.transmittance, f"sheet {s.id}")
        groups = {x.group for x in (*self.meshes, *self.emitters, *self.sheets)} - {None}
        by_id = {p.id: p for p in self.products}
        for p in self.products:
            if getattr(p, "direct_product", None) is not None and \
                    getattr(by_id.get(p.direct_product), "type", None) != "irradiance_points":
                raise ValueError(f"product {p.id}: direct_product {p.direct_product!r} is not an "
                                 "irradiance_points product of this job")
            unknown = set(p.group_transforms) - groups
            if unknown:
                raise ValueError(f"product {p.id}: unknown transform group(s) {', '.join(sorted(unknown))}")
        ids = [x.id for x in (*self.meshes, *self.emitters, *self.sheets)]
        pids = [p.id for p in self.products]
        for group, what in ((ids, "object"), (pids, "product")):
            dup = {i for i in group if group.count(i) > 1}
            if dup:
                raise ValueError(f"duplicate {what} id(s): {', '.join(sorted(dup))}")
        return self

    # ------------------------------------------------------------------ identity
    def to_json(self) -> str:
        """Canonical JSON (the hashed form)."""
        return canonical_json(self.model_dump(mode="json"))

    @property
    def content_hash(self) -> str:
        """sha256 (hex) of the canonical JSON, floats to 12 significant digits: the cache key."""
        text = canonical_json(_rounded(self.model_dump(mode="json")))
        return hashlib.sha256(text.encode()).hexdigest()

    # ------------------------------------------------------------------ quality
    @property
    def preset(self) -> QualityPreset:
        return QUALITY_PRESETS[self.quality.preset]

    def samples_for(self, product) -> int:
        """Samples per pixel/texel: job override > product's own > preset."""
        if self.quality.samples is not None:
            return self.quality.samples
        if product.samples is not None:
            return product.samples
        kind = {"environment_map": "environment", "irradiance_map": "map",
                "irradiance_points": "points"}[product.type]
        return getattr(self.preset, kind)

    def noise_target_for(self, product) -> float | None:
        """Noise target of an irradiance-points product sampled adaptively, else None.

        Only when nothing fixes its samples (no job override, no product samples) and the
        two-half noise estimate is on.
        """
        if product.type != "irradiance_points" or not self.quality.noise_estimate:
            return None
        if self.quality.samples is not None or product.samples is not None:
            return None
        return self.quality.noise_target if self.quality.noise_target is not None else \
            self.preset.points_noise_target

    def max_samples_for(self, product) -> int:
        """Upper bound of an adaptively sampled product's samples."""
        cap = self.preset.points_max_samples
        return max(self.samples_for(product), cap if cap is not None else 16 * self.samples_for(product))

    @property
    def max_bounces(self) -> int:
        return self.quality.max_bounces if self.quality.max_bounces is not None else self.preset.max_bounces

    def with_quality(self, preset: str | None = None, samples: int | None = None) -> "BakeJob":
        """A copy with another quality preset and/or sample override."""
        q = self.quality.model_copy(update={k: v for k, v in
                                            (("preset", preset), ("samples", samples)) if v is not None})
        return self.model_copy(update={"quality": Quality.model_validate(q.model_dump())})


def save_job(job: BakeJob, path: Path) -> Path:
    """Write a job file (indented canonical JSON, written atomically)."""
    from lbscene.engine.files.atomic import write_atomic

    text = json.dumps(json.loads(job.to_json()), indent=1, sort_keys=True, ensure_ascii=False) + "\n"
    write_atomic(Path(path), text)
    return Path(path)


def load_job(path: Path | str) -> BakeJob:
    """Read and validate a job file (raises :class:`LbsceneUserError` with code LB602)."""
    from pydantic import ValidationError

    from lbscene.engine.files.diagnostics import LbsceneUserError

    from lbscene.engine.files.yamlio import parse_json_text, read_text_bounded

    from lbscene.engine.files.diagnostics import Diagnostic

    p = Path(path)
    text = read_text_bounded(p, str(p), 256 * 1024 * 1024)
    try:
        data = parse_json_text(text, str(p))         # syntax and nesting depth, located
    except LbsceneUserError as exc:
        d = exc.diagnostics[0]
        raise LbsceneUserError(Diagnostic("LB602", f"not a bake job: {d.message}", d.location,
                                          expected="a JSON bake job")) from None
    if not isinstance(data, dict) or data.get("kind") != JOB_KIND:
        raise LbsceneUserError.single("LB602", "not a bake job", str(p),
                                      value=repr(data.get("kind")) if isinstance(data, dict) else None,
                                      expected=f"kind: {JOB_KIND!r}")
    try:
        return BakeJob.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = ".".join(str(x) for x in err["loc"])
        raise LbsceneUserError.single("LB602", f"invalid bake job at {where or '<root>'}: {err['msg']}",
                                      str(p), expected=f"bake job version {JOB_VERSION}") from None
