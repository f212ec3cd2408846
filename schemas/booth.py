"""
The booth document: interior, surfaces, luminaires, lighting configurations,
viewing geometries, diffuser, filters, reflectors, observer and effects.

Booth coordinates: millimetres, origin at the centre of the booth floor, +x to
the observer's right, +y from the open front toward the rear wall, +z up.

A new booth is a new folder under ``booths/`` with a ``booth.yaml``; nothing
here is booth-specific.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal, Union

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from .base import Direction, Document, Identifier, Provenance, StrictModel, Vec3_mm
from .refs import FileRef
from .spectrum import SpectrumSpec

__all__ = [
    "Booth",
    "BoxInterior",
    "GeometryFile",
    "Material",
    "Lamp",
    "LampOutput",
    "AngularProfile",
    "Filter",
    "Reflector",
    "Diffuser",
    "Occluder",
    "LightingConfiguration",
    "ViewingGeometry",
    "Observer",
    "FitSpec",
    "GEOMETRY_NAME_PATTERN",
    "parse_geometry_name",
    "STANDARD_GEOMETRIES",
]

# --------------------------------------------------------------------------- geometry names

#: DIN 6175-2 / ASTM E2194 names: ``<illumination angle>as<aspecular angle>``.
GEOMETRY_NAME_PATTERN = r"^(\d{1,2})as(-?\d{1,3})$"
#: The six multi-angle geometries of effect-coating booths and spectrophotometers.
STANDARD_GEOMETRIES = ("45as-15", "45as15", "45as25", "45as45", "45as75", "45as110")


def parse_geometry_name(name: str) -> tuple[float, float]:
    """``'45as15'`` → ``(45.0, 15.0)``: illumination and aspecular angle in degrees.

    The aspecular angle is measured from the specular direction toward the
    illumination direction, so the viewing angle from the sample normal is
    ``illumination - aspecular`` (negative: on the illumination side).

    >>> parse_geometry_name("45as-15")
    (45.0, -15.0)
    """
    m = re.match(GEOMETRY_NAME_PATTERN, name)
    if not m:
        raise ValueError(f"{name!r} is not a geometry name like '45as15' (illumination 'as' aspecular)")
    ill, asp = float(m.group(1)), float(m.group(2))
    if not 0 <= ill < 90:
        raise ValueError(f"illumination angle {ill:g}° must be at least 0° and below 90°")
    view = ill - asp
    if not -90 < view < 90:
        raise ValueError(f"{name}: aspecular angle {asp:g}° puts the observer {abs(view):g}° from the "
                         "normal, below the sample plane")
    return ill, asp


GeometryName = Annotated[str, Field(examples=list(STANDARD_GEOMETRIES),
                                    description="'<illumination>as<aspecular>', e.g. '45as15'.")]

# --------------------------------------------------------------------------- interior


class BoxInterior(StrictModel):
    """A parametric rectangular viewing box with an open (or viewing) front."""

    type: Literal["box"]
    width_mm: float = Field(gt=0, le=10000, description="Inner width along x.")
    depth_mm: float = Field(gt=0, le=10000, description="Inner depth along y (front to rear wall).")
    height_mm: float = Field(gt=0, le=10000, description="Floor to ceiling (luminaire underside) along z.")
    open_front: bool = Field(True, description="The front (y = -depth/2) face is open.")


class UsdInterior(StrictModel):
    """Interior geometry from a USD file (meshes named by surface role)."""

    type: Literal["usd"]
    path: FileRef
    bounds_mm: tuple[float, float, float] = Field(
        description="Inner width, depth, height (mm) used for placement checks.")


Interior = Annotated[Union[BoxInterior, UsdInterior], Field(discriminator="type")]


class Transform(StrictModel):
    translate_mm: Vec3_mm = (0.0, 0.0, 0.0)
    rotate_xyz_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = Field(1.0, gt=0, description="Uniform scale; OBJ files in metres need 1000.")


class GeometryFile(StrictModel):
    """Extra meshes (luminaire cavity, platform, props) from USD or OBJ files."""

    type: Literal["obj", "usd"]
    id: Identifier
    path: FileRef
    material: Identifier = Field(description="Material (from `materials:`) applied to the meshes.")
    transform: Transform = Transform()
    mount: Literal["booth", "platform"] = Field(
        "booth", description="'platform': moves with the rotating platform. Coordinates are always "
                             "written with the platform at rotation 0.")


# --------------------------------------------------------------------------- materials


class Material(StrictModel):
    """An opaque surface: spectral reflectance factor plus gloss."""

    type: Literal["diffuse", "glossy"]
    reflectance: SpectrumSpec = Field(description="Spectral reflectance factor, 0..1.")
    gloss_GU: float = Field(0.0, ge=0, le=200, description="Specular gloss at 60° in gloss units.")
    roughness: float = Field(0.5, ge=0, le=1,
                             description="Microfacet roughness of the specular layer (glossy only).")
    provenance: Provenance | None = None


SurfaceRole = Literal["floor", "left_wall", "right_wall", "rear_wall", "ceiling", "platform", "front_wall"]


# --------------------------------------------------------------------------- lamps


class IsotropicProfile(StrictModel):
    type: Literal["isotropic"]


class GaussianProfile(StrictModel):
    """I(θ) = I0·exp(−(θ/2σ)²), θ from the aim direction (the seed's model)."""

    type: Literal["gaussian"]
    sigma_deg: float = Field(gt=0, le=1000, description="σ in degrees (large σ → isotropic).")


class CosinePowerProfile(StrictModel):
    """I(θ) = I0·cosⁿθ for θ < 90°, 0 beyond (n = 1: Lambertian emitter)."""

    type: Literal["cosine_power"]
    exponent: float = Field(ge=0, le=1000)


class IesProfile(StrictModel):
    """Candela distribution from an IES LM-63 photometric file."""

    type: Literal["ies"]
    path: FileRef


AngularProfile = Annotated[
    Union[IsotropicProfile, GaussianProfile, CosinePowerProfile, IesProfile],
    Field(discriminator="type"),
]


class LuminousIntensityOutput(StrictModel):
    """Reference luminous intensity of the whole lamp: a tube's perpendicular to its axis, a panel's
    along its normal, a bulb's or point's in any direction (along `aim` where a profile modulates it)."""

    type: Literal["peak_intensity_cd"]
    value_cd: float = Field(gt=0, le=1e7)


class LuminousFluxOutput(StrictModel):
    """Total luminous flux emitted by the bare lamp."""

    type: Literal["luminous_flux_lm"]
    value_lm: float = Field(gt=0, le=1e7)


class IlluminanceOutput(StrictModel):
    """Lamp scaled so that it alone gives this illuminance at a point (base model, no effects)."""

    type: Literal["illuminance_at_point_lx"]
    value_lx: float = Field(gt=0, le=1e6)
    point_mm: Vec3_mm = (0.0, 0.0, 0.0)


class RadiantIntensityOutput(StrictModel):
    """Peak radiant intensity (360–830 nm) of the whole lamp along its aim: for UV sources."""

    type: Literal["peak_radiant_intensity_W_sr"]
    value_W_sr: float = Field(gt=0, le=1e5)


class RadiantFluxOutput(StrictModel):
    """Total radiant flux (360–830 nm) of the bare lamp: for UV sources."""

    type: Literal["radiant_flux_W"]
    value_W: float = Field(gt=0, le=1e5)


class LuminanceOutput(StrictModel):
    """Luminance of the emitting surface (tube, panel, bulb): ``I_ref = L_v·A``.

    ``A`` = 2·r·ℓ (tube: intensity perpendicular to its axis), length·width (panel: along its
    normal), π·r² (bulb: every direction).
    """

    type: Literal["luminance_cd_m2"]
    value_cd_m2: float = Field(gt=0, le=1e9)


class RadianceOutput(StrictModel):
    """Radiance (360–830 nm) of the emitting surface (tube, panel, bulb): for UV sources."""

    type: Literal["radiance_W_sr_m2"]
    value_W_sr_m2: float = Field(gt=0, le=1e7)


LampOutput = Annotated[
    Union[LuminousIntensityOutput, LuminousFluxOutput, IlluminanceOutput, RadiantIntensityOutput,
          RadiantFluxOutput, LuminanceOutput, RadianceOutput],
    Field(discriminator="type"),
]


class Lamp(StrictModel):
    """One light source of a luminaire."""

    id: Identifier
    type: Literal["tube", "bulb", "panel", "point"]
    group: Identifier | None = Field(
        None, description="Lamps of one group share fitted parameters (default: the lamp's id).")
    position_mm: Vec3_mm = Field(description="Centre of the lamp.")
    axis: Direction = Field((1.0, 0.0, 0.0), description="Tube axis / panel first edge direction.")
    aim: Direction = Field((0.0, 0.0, -1.0), description="Direction of θ = 0 of the angular profile; a panel's "
                                                               "emitting normal.")
    length_mm: float = Field(0.0, ge=0, le=5000, description="Tube length or panel size along `axis`.")
    width_mm: float = Field(0.0, ge=0, le=5000, description="Panel size across `axis`.")
    radius_mm: float = Field(0.0, ge=0, le=500, description="Tube or bulb radius.")
    end_caps: bool = Field(False, description="Tube: its flat ends emit too, with the lateral "
                                              "surface's radiance (default: only the lateral surface).")
    spd: SpectrumSpec = Field(description="Relative spectral power distribution (shape only).")
    output: LampOutput = Field(description="Absolute level of the lamp.")
    profile: AngularProfile = Field(IsotropicProfile(type="isotropic"),
                                    description="Angular modulation around `aim` of the lamp's own "
                                                "Lambertian emission (tube: sin of the angle to its "
                                                "axis; panel: cos from its normal; bulb, point: "
                                                "uniform). IES: γ = 0 along `aim`, C = 0 along `axis`.")
    point_sources: int = Field(100, ge=1, le=10000,
                               description="Point sources approximating the lamp (seed: N = 100).")
    filter: Identifier | None = Field(None, description="Filter (from `filters:`) in front of the lamp.")
    reflector: Identifier | None = Field(None, description="Reflector (from `reflectors:`) behind the lamp.")
    mount: Literal["booth", "platform"] = Field(
        "booth", description="'platform': moves with the rotating platform. Coordinates are always "
                             "written with the platform at rotation 0.")
    provenance: Provenance | None = None

    @model_validator(mode="after")
    def _shape(self):
        if self.type == "tube" and (self.length_mm <= 0 or self.radius_mm <= 0):
            raise ValueError("a tube needs length_mm > 0 and radius_mm > 0")
        if self.type == "panel" and (self.length_mm <= 0 or self.width_mm <= 0):
            raise ValueError("a panel needs length_mm > 0 and width_mm > 0")
        if self.type == "bulb" and self.radius_mm <= 0:
            raise ValueError("a bulb needs radius_mm > 0")
        if self.type == "point" and self.output.type in ("luminance_cd_m2", "radiance_W_sr_m2"):
            raise ValueError(f"a point has no surface: give its output as an intensity or flux, "
                             f"not {self.output.type}")
        if self.end_caps and self.type != "tube":
            raise ValueError("end_caps applies to tubes only")
        for name in ("axis", "aim"):
            v = getattr(self, name)
            if sum(c * c for c in v) < 1e-12:
                raise ValueError(f"{name} must not be the zero vector")
        return self


# --------------------------------------------------------------------------- optics


class Filter(StrictModel):
    """A spectral filter (e.g. the D65 conversion filter in front of a halogen lamp)."""

    transmittance: SpectrumSpec = Field(description="Spectral transmittance, 0..1.")
    provenance: Provenance | None = None


class Reflector(StrictModel):
    """A mirror behind a lamp that sends part of its back-emitted light forward."""

    type: Literal["plane", "prism", "parabolic_trough"]
    reflectance: SpectrumSpec = Field(description="Spectral reflectance of the mirror, 0..1.")
    distance_mm: float = Field(gt=0, le=1000, description="Lamp axis to mirror distance.")
    normal: Direction = Field((0.0, 0.0, -1.0), description="Direction the mirror faces.")
    width_mm: float = Field(gt=0, le=5000, description="Mirror extent across the lamp axis (a prism: "
                            "both facets together, each width_mm / 2 from the apex).")
    apex_angle_deg: float | None = Field(
        None, gt=0, le=180,
        description="prism only: the angle between its two plane facets, on the lamp's side (180: a "
                    "plane). The facets meet at an apex parallel to the lamp's axis, distance_mm behind "
                    "the lamp, and fold toward it (a V reflector). Default 120 (the smallest angle at "
                    "which light from a lamp on the prism's axis meets one facet only).")
    provenance: Provenance | None = None

    @model_validator(mode="after")
    def _apex_only_for_prism(self):
        if self.apex_angle_deg is not None and self.type != "prism":
            raise ValueError(f"apex_angle_deg applies to prism reflectors only (this one is {self.type!r})")
        return self


#: a prism reflector's apex angle when the booth declares none (degrees)
PRISM_APEX_ANGLE_DEFAULT_DEG = 120.0


class RoughnessScattering(StrictModel):
    """Rough glass (GGX microfacet roughness as in Blender's Glass BSDF; seed: 0.04)."""

    type: Literal["roughness"]
    roughness: float = Field(ge=0, le=1)


class LambertianScattering(StrictModel):
    """An opal plate: a fraction of transmitted light is scattered diffusely, the rest passes
    straight."""

    type: Literal["lambertian"]
    diffuse_fraction: float = Field(ge=0, le=1, description="Scattered part of the total normal "
                                    "transmittance (1 − regular / total), as a spectrophotometer "
                                    "with an integrating sphere measures it.")
    reflectance: float | None = Field(None, ge=0, le=1, description="Total reflectance at normal "
                                      "incidence (both surfaces and the bulk, measured); default: "
                                      "1 − transmittance (a plate that does not absorb).")


class Diffuser(StrictModel):
    """A plate below the lamps (glass or opal) that transmits and scatters."""

    z_mm: float = Field(description="Height of the plate (mm).")
    size_mm: tuple[float, float] = Field(description="Extent along x and y (mm), centred on x=0.")
    centre_mm: tuple[float, float] = Field((0.0, 0.0), description="Plate centre (x, y) in mm.")
    thickness_mm: float = Field(4.0, gt=0, le=50)
    transmittance: SpectrumSpec = Field(
        description="Total spectral transmittance at normal incidence (regular and scattered light, "
                    "both surfaces included), 0..1: the datasheet's or a spectrophotometer's value. "
                    "The plate model's own non-absorbing transmittance (clear, rough or opal plate) "
                    "sets the bulk absorption.")
    scattering: Annotated[Union[RoughnessScattering, LambertianScattering], Field(discriminator="type")]
    ior: float = Field(1.52, ge=1.0, le=3.0)
    provenance: Provenance | None = None


class Occluder(StrictModel):
    """Something that blocks lamp light: a luminaire cavity wall or an aperture plate."""

    id: Identifier
    type: Literal["aperture_plate", "panel"]
    centre_mm: Vec3_mm
    normal: Direction = (0.0, 0.0, -1.0)
    size_mm: tuple[float, float] = Field(description="Outer extent (u, v) of the plate in mm.")
    opening_mm: tuple[float, float] | None = Field(
        None, description="For aperture_plate: rectangular opening (u, v) in mm, centred.")
    u_axis: Direction = (1.0, 0.0, 0.0)
    lamps: list[Identifier] | None = Field(None, description="Lamps it occludes (default: all).")
    material: Identifier | None = None
    mount: Literal["booth", "platform"] = Field(
        "booth", description="'platform': moves with the rotating platform. Coordinates are always "
                             "written with the platform at rotation 0.")


# --------------------------------------------------------------------------- lighting & viewing


class LightingConfiguration(StrictModel):
    """A named state of the booth's switches: which lamps are on, at what level."""

    lamps: list[Identifier] = Field(min_length=1, max_length=256)
    dimming: dict[Identifier, float] = Field(
        default_factory=dict, description="Relative level per lamp (default 1).")
    description: str = ""
    nominal_illuminance_lx: float | None = Field(
        None, gt=0, description="Illuminance the manufacturer states at the sample position.")
    standard: Literal["ASTM_D1729", "ISO_3668", "ISO_3664_P1", "ISO_3664_P2", "none"] = Field(
        "none", description="Viewing standard whose illuminance range the linter checks.")


class ViewingGeometry(StrictModel):
    """One illumination/viewing geometry of the sample platform."""

    name: GeometryName
    platform_rotation_deg: float | None = Field(
        None, description="Platform tilt that realises it (booths with a rotating platform).")

    @field_validator("name")
    @classmethod
    def _parse(cls, v: str) -> str:
        try:
            parse_geometry_name(v)
        except ValueError as exc:
            raise PydanticCustomError("lb_geometry_name", "{reason}", {"reason": str(exc)}) from None
        return v


class Observer(StrictModel):
    """Where the observer looks from."""

    type: Literal["eye_point", "viewing_slit"]
    position_mm: Vec3_mm = Field(description="Eye point, or the slit centre.")
    slit_size_mm: tuple[float, float] | None = Field(None, description="Viewing slit width, height.")
    look_at_mm: Vec3_mm = (0.0, 0.0, 0.0)


class Surfaces(StrictModel):
    """Material of each interior surface (names from `materials:`)."""

    floor: Identifier
    left_wall: Identifier
    right_wall: Identifier
    rear_wall: Identifier
    ceiling: Identifier
    platform: Identifier | None = None
    front_wall: Identifier | None = None


class FreeParameter(StrictModel):
    """A model parameter the fit may change."""

    target: str = Field(pattern=r"^(group|lamp|effect)\.[A-Za-z0-9_.\-]+\.[A-Za-z0-9_]+$",
                        description="'group.<id>.intensity_scale', 'lamp.<id>.sigma_deg', "
                                    "'effect.<id>.<param>'.")
    bounds: tuple[float, float] | None = None
    initial: float | None = None


class FitSpec(StrictModel):
    """What the measurement loop may fit."""

    free: list[FreeParameter] | None = Field(
        None, description="Free parameters; default: each lamp group's intensity scale, and σ "
                          "where a Gaussian profile is on.")
    known_output_groups: list[Identifier] = Field(
        default_factory=list,
        description="Lamp groups whose absolute output is trusted (not fitted): a level "
                    "mismatch then counts as evidence for a missing effect.")


class Platform(StrictModel):
    """The sample platform (rotating on effect booths)."""

    centre_mm: Vec3_mm = (0.0, 0.0, 0.0)
    size_mm: tuple[float, float] = Field(description="Platform extent (x, y) in mm.")
    rotation_axis: Direction = (1.0, 0.0, 0.0)
    pivot_mm: Vec3_mm | None = Field(
        None, description="A point of the rotation axis, in mm (default: centre_mm). A wedge "
                          "viewing stand that rests on the floor turns about its front edge.")
    illumination_fixed_to_platform: bool = Field(
        False, description="The luminaire rotates with the platform (fixed illumination angle).")
    illumination_angle_deg: float | None = Field(None, ge=0, lt=90)


# --------------------------------------------------------------------------- document


class Booth(Document):
    """A light booth."""

    kind: Literal["booth"] = Field(description="Document kind.")
    name: str = Field(min_length=1, max_length=200)
    manufacturer: str = ""
    model: str = ""
    provenance: Provenance
    interior: Interior
    materials: dict[Identifier, Material] = Field(min_length=1)
    surfaces: Surfaces
    geometry_files: list[GeometryFile] = Field(default_factory=list, max_length=256)
    lamps: list[Lamp] = Field(min_length=1, max_length=256)
    filters: dict[Identifier, Filter] = Field(default_factory=dict)
    reflectors: dict[Identifier, Reflector] = Field(default_factory=dict)
    diffuser: Diffuser | None = None
    occluders: list[Occluder] = Field(default_factory=list, max_length=256)
    lighting: dict[Identifier, LightingConfiguration] = Field(min_length=1)
    geometries: list[ViewingGeometry] = Field(default_factory=list)
    platform: Platform | None = None
    observer: Observer
    sample_position_mm: Vec3_mm = (0.0, 0.0, 0.0)
    effects: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="Physical effects the forward model includes, by registered effect id, with "
                    "their parameters (see `lbscene effects`).")
    fit: FitSpec = FitSpec()

    @field_validator("effects", mode="before")
    @classmethod
    def _effects_none(cls, v):
        # `effects:` with nothing under it means "no effects"
        return {} if v is None else v
