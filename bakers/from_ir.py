"""
Bake jobs from the scene IR: one job per lighting configuration.

:func:`lighting_job` turns a :class:`~lbscene.engine.scene.ir.SceneIR` and a
lighting name into a self-contained :class:`~lbscene.bakers.job.BakeJob`:

* **surfaces**: every IR surface (box walls, floor, ceiling, platform, OBJ/USD
  meshes) with its material's band reflectance (the lighting-dependent
  projection when the IR has one, else the band mean);
  ``surfaces='black'`` keeps the geometry but absorbs everything (direct light
  only, through diffuser and mirrors: the cross-check of the model without
  inter-reflection).
* **lamps** that are on, at their dimming level, as the surfaces they are
  (:mod:`lbscene.engine.light.emitters`): emissive meshes — a tube's lateral
  surface (and caps), a panel's rectangle, a bulb's sphere — of spectral
  radiance ``I_ref / A`` (band means of the 1 nm spectrum, through the lamp's
  filter when ``spectral_filter`` is on), modulated by the declared profile,
  black bodies to camera rays (the environment maps see the lamp, not what lies behind it,
  and leave its light to their direct products); point lamps as true points.  No lamp falls back
  to points.  Lamps that are off are there too, as black bodies in the light's
  way (as the model's inter-reflection has them, ``lamp_bodies``).
* **effects** follow the booth's ``effects:`` (or ``effects=``) exactly as the
  analytic model reads them — angular profile (IES files in two dimensions
  through Cycles' own IES parser, C = 0 along the lamp's axis), tube-end
  falloff (the tube's surface weighted along its axis), spectral filter,
  diffuser (an opal plate as a slab of a scattering medium between its faces, as the
  Mitsuba truth draws it: :mod:`lbscene.bakers.opal_slab`; any other plate as a clear sheet
  with Fresnel angular transmittance), aperture occlusion (occluders become geometry that blocks
  *every* lamp), reflector (the lamp's surface mirrored across the mirror,
  radiance × the mirror's reflectance, shining only through the mirror's
  rectangle: the image method; the lamp's own body is in the image's way, as
  it is in a real luminaire; a prism mirror is its two facets, one image
  through each, first order as in the model) — while Cycles does the geometry: visibility,
  occlusion, inter-reflection.
* **products**: an equirect environment map 1 mm above the sample position
  (and one per geometry where the platform turns: above the turned sample,
  in its frame) holding all light *but* that seen straight from the lamps
  (black to its camera rays; a point lamp no camera ray can hit), plus
  ``sample_direct``: that direct
  irradiance at the same point for the map's up normal and 62 directions over
  the sphere; the floor (and platform) irradiance maps; the irradiance at
  measurement points (default: the seed's 11 × 5 A3 grid around the sample).

:func:`write_build_products` is the hook ``lbscene build`` calls: it writes
``lighting/<NAME>/bake/job.json``.
"""

from __future__ import annotations

import functools
import math
import re
from pathlib import Path
from typing import Iterable, Literal

import numpy as np

from .job import (AreaEmitter, AxialWeight, BakeJob, BandGridSpec, CosinePowerProfile,
                  EnvironmentMapProduct, GaussianProfile, IesProfile, IrradianceMapProduct,
                  IrradiancePointsProduct, IsotropicProfile, JobMaterial, JobMesh, MeasurementPoint,
                  PointEmitters, Quality, RigidTransform, TransmissiveSheet, Window, save_job)
from lbscene.engine.light.geometry import OCCLUDER_OFFSET_MM, plate_pieces

__all__ = ["lighting_job", "grid_points", "write_build_products", "job_path_in_build", "diffuser_is_thin_sheet",
           "ENV_WIDTH", "MAP_CELL_MM", "LUMINAIRE_GROUP", "OCCLUDER_OFFSET_MM"]

#: environment map width (px) per quality preset
ENV_WIDTH = {"preview": 128, "final": 256}
#: floor map cell size (mm) per quality preset
MAP_CELL_MM = {"preview": 50.0, "final": 25.0}
LUMINAIRE_GROUP = "luminaire"
BLACK = "lbscene_black"


def _jid(s: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.\-]", "_", s)
    return s if re.match(r"^[A-Za-z_]", s) else f"_{s}"


def grid_points(ir, nx: int = 11, ny: int = 5, width_mm: float = 400.0, depth_mm: float = 240.0):
    """The seed's 55-point grid (11 × 5 over 400 × 240 mm, an A3 sheet) around the sample, facing up."""
    sx, sy, sz = ir.sample_position_mm
    x = sx + np.linspace(-width_mm / 2, width_mm / 2, nx)
    y = sy + np.linspace(-depth_mm / 2, depth_mm / 2, ny)
    X, Y = np.meshgrid(x, y, indexing="xy")
    return np.c_[X.ravel(), Y.ravel(), np.full(X.size, float(sz))]


def _effect(effects: dict, eid: str, lamp_id: str | None = None):
    """Params dict of an enabled effect (None when off or the lamp is not selected)."""
    if eid not in effects:
        return None
    p = effects[eid] or {}
    if lamp_id is not None and p.get("lamps") is not None and lamp_id not in p["lamps"]:
        return None
    return p


def _profile(lamp, effects):
    p = _effect(effects, "angular_profile", lamp.id)
    if p is None:
        return IsotropicProfile()
    prof = lamp.profile
    t = prof.get("type")
    if t == "gaussian":
        return GaussianProfile(sigma_deg=float(prof["sigma_deg"]))
    if t == "cosine_power":
        return CosinePowerProfile(exponent=float(prof["exponent"]))
    if t == "ies":
        from lbscene.engine.spectra.profiles import ies_text

        d = prof["data"]
        # LM-63 type C: γ = 0 along aim, C = 0 along the lamp's axis made ⊥ aim, C = 90° along
        # C0 × aim (the documented orientation, written out here rather than taken from the
        # model); the file itself goes to Cycles' own IES parser
        aim = np.asarray(lamp.aim, float) / np.linalg.norm(lamp.aim)
        ax = np.asarray(lamp.axis, float)
        e0 = ax - (ax @ aim) * aim
        if np.linalg.norm(e0) < 1e-9:
            e0 = np.cross(aim, [1.0, 0.0, 0.0] if abs(aim[0]) < 0.9 else [0.0, 1.0, 0.0])
        e0 = e0 / np.linalg.norm(e0)
        return IesProfile(ies_text=ies_text(d), c0_axis=tuple(e0), c90_axis=tuple(np.cross(e0, aim)),
                          peak_cd=float(np.max(d["candela"])))
    if p.get("sigma_deg") is not None:
        return GaussianProfile(sigma_deg=float(p["sigma_deg"]))
    return IsotropicProfile()


def _reflect(u, n) -> np.ndarray:
    """A direction mirrored in the plane of unit normal ``n``."""
    u = np.asarray(u, float)
    return u - 2.0 * (u @ n) * n


def _reflect_point(p, c, n) -> np.ndarray:
    """Points ``p`` (3,) or (N, 3) mirrored in the plane through ``c`` of unit normal ``n``."""
    p = np.asarray(p, float)
    return p - 2.0 * ((p - c) @ n)[..., None] * n


def _mirrored_profile(profile, n):
    """A lamp's profile as its mirror image emits it: axially symmetric profiles are unchanged
    (the image's aim is mirrored); an IES frame is mirrored too (the other handedness)."""
    if isinstance(profile, IesProfile):
        return profile.model_copy(update={"c0_axis": tuple(_reflect(profile.c0_axis, n)),
                                          "c90_axis": tuple(_reflect(profile.c90_axis, n))})
    return profile


#: facets around a tube's or bulb's mesh
MESH_FACETS = 64


def _lamp_mesh(lamp) -> tuple[tuple, tuple, float]:
    """Emitting surface of a tube, panel or bulb: (vertices mm, triangles facing out, area m²).

    Polygonal meshes are scaled so their area equals the true surface's (a 64-gon
    cylinder of the same radius would have 0.16 % less), so radiance × area = ``I_ref``'s
    share exactly.
    """
    from lbscene.engine.light.emitters import emitter_from_lamp

    em = emitter_from_lamp(lamp)
    c, ax, aim = em.centre_mm, em.axis, em.aim
    if lamp.kind == "panel":
        v = em.corners_mm()[[0, 3, 2, 1]]          # counter-clockwise seen from the aim side
        nrm = np.cross(v[1] - v[0], v[2] - v[0])
        if nrm @ aim < 0:
            v = v[::-1]
        return (tuple(tuple(float(x) for x in p) for p in v), ((0, 1, 2), (0, 2, 3)),
                em.projected_area_m2)
    k = MESH_FACETS
    helper = [0.0, 0.0, 1.0] if abs(ax[2]) < 0.9 else [1.0, 0.0, 0.0]
    e1 = np.cross(ax, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(ax, e1)
    phi = 2 * np.pi * np.arange(k) / k
    ring = np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2)
    if lamp.kind == "tube":
        r = lamp.radius_mm * (np.pi / k) / np.sin(np.pi / k)      # lateral area = 2πrℓ
        h = ax * lamp.length_mm / 2
        verts = list(c - h + r * ring) + list(c + h + r * ring)
        tris = []
        for i in range(k):
            j = (i + 1) % k
            tris += [(i, j, k + j), (i, k + j, k + i)]       # outward (right-hand rule)
        if lamp.end_caps:
            rc = lamp.radius_mm * np.sqrt((2 * np.pi / k) / np.sin(2 * np.pi / k))  # cap area πr²
            a0, a1 = len(verts), len(verts) + 1
            verts += [c - h, c + h]
            b0, b1 = len(verts), len(verts) + k
            verts += list(c - h + rc * ring) + list(c + h + rc * ring)
            for i in range(k):
                j = (i + 1) % k
                tris += [(a0, b0 + j, b0 + i), (a1, b1 + i, b1 + j)]
    else:                                                  # bulb: UV sphere of the same area
        m = k // 2
        th = np.pi * (np.arange(1, m)) / m
        z = np.cross(e1, e2)
        pts = [c - z]
        for t_ in th:
            pts += list(c + (-np.cos(t_)) * z + np.sin(t_) * ring)
        pts.append(c + z)
        unit = np.asarray(pts) - c                          # unit sphere, south pole first
        tris = []
        for i in range(k):
            j = (i + 1) % k
            tris.append((0, 1 + j, 1 + i))
        for ring_i in range(m - 2):
            o0, o1 = 1 + ring_i * k, 1 + (ring_i + 1) * k
            for i in range(k):
                j = (i + 1) % k
                tris += [(o0 + i, o0 + j, o1 + j), (o0 + i, o1 + j, o1 + i)]
        top = len(unit) - 1
        o0 = 1 + (m - 2) * k
        for i in range(k):
            j = (i + 1) % k
            tris.append((top, o0 + i, o0 + j))
        tri = np.asarray(tris)
        cr = np.cross(unit[tri[:, 1]] - unit[tri[:, 0]], unit[tri[:, 2]] - unit[tri[:, 0]])
        unit_area = 0.5 * np.linalg.norm(cr, axis=1).sum()
        r = lamp.radius_mm * np.sqrt(4 * np.pi / unit_area)
        verts = list(c + r * unit)
    # I_ref = L·A with A the emitter's reference projected area (tube 2rℓ, bulb πr²)
    return (tuple(tuple(float(x) for x in p) for p in verts), tuple(tuple(int(i) for i in t) for t in tris),
            em.projected_area_m2)


def _mirror_windows(ir, lamp, refl) -> list[Window]:
    """The mirror behind a lamp as the ``reflector`` effect draws it: one rectangle (a plane
    mirror), or one per facet (a prism,
    :func:`~lbscene.engine.light.effects.builtin.reflector.mirror_facets`)."""
    from lbscene.engine.light.effects.builtin.reflector import mirror_facets

    return [Window(centre_mm=tuple(float(x) for x in r.centre), normal=tuple(float(x) for x in r.normal),
                   u_axis=tuple(float(x) for x in r.u), half_size_mm=(float(r.half[0]), float(r.half[1])))
            for r in mirror_facets(ir, lamp, refl)]


def _rect_quads(centre, normal, u, half, hole=None):
    """Triangles of a rectangle (or a frame around a rectangular hole), facing ``normal``."""
    c, n, u = (np.asarray(x, float) for x in (centre, normal, u))
    u = u - n * (u @ n)
    u = u / np.linalg.norm(u)
    v = np.cross(n, u)

    def quad(u0, u1, v0, v1):
        return [c + a * u + b * v for a, b in ((u0, v0), (u1, v0), (u1, v1), (u0, v1))]

    quads = [quad(*q) for q in plate_pieces(half, hole)]
    verts, tris = [], []
    for q in quads:
        b = len(verts)
        verts += [tuple(float(x) for x in p) for p in q]
        tris += [(b, b + 1, b + 2), (b, b + 2, b + 3)]
    return tuple(verts), tuple(tris)


def _job_materials(ir, lighting: str, nb: int) -> dict[str, JobMaterial]:
    """The booth's materials with the lighting's band reflectances, and the black of the job."""
    materials = {BLACK: JobMaterial(type="diffuse", reflectance=(0.0,) * nb)}
    for mid, m in ir.materials.items():
        refl = m.reflectance_bands_by_lighting.get(lighting) or m.reflectance.bands
        refl = tuple(float(min(max(x, 0.0), 1.0)) for x in refl)
        materials[_jid(mid)] = JobMaterial(type=m.type, reflectance=refl, roughness=m.roughness)
    return materials


def _occluder_meshes(ir, lighting: str, effects: dict, mat, lum_group, notes: list[str]) -> list[JobMesh]:
    """The occluders the ``aperture_occlusion`` effect selects, their openings scaled."""
    occ = _effect(effects, "aperture_occlusion")
    if occ is None:
        return []
    meshes = []
    scale = float(occ.get("opening_scale", 1.0))
    su, sv = scale * float(occ.get("opening_scale_u", 1.0)), scale * float(occ.get("opening_scale_v", 1.0))
    on = set(ir.lighting[lighting].lamps)
    for o in ir.occluders:
        if occ.get("occluders") is not None and o.id not in occ["occluders"]:
            continue
        half = (o.size_mm[0] / 2, o.size_mm[1] / 2)
        hole = None
        if o.type == "aperture_plate" and o.opening_mm is not None:
            hole = (min(o.opening_mm[0] * su / 2, half[0]), min(o.opening_mm[1] * sv / 2, half[1]))
        # drawn a hair to the side the normal points to (away from the lamps it shades): an
        # occluder often coincides with a face of a luminaire mesh (BYK: the aperture plate is
        # the cavity's front face) and two coplanar faces z-fight in Cycles, so random parts
        # of the cavity's white inside would turn the plate's black
        c = np.asarray(o.centre_mm, float) + OCCLUDER_OFFSET_MM * np.asarray(o.normal, float)
        v, t = _rect_quads(c, o.normal, o.u_axis, half, hole)
        meshes.append(JobMesh(id=_jid(f"occluder.{o.id}"), material=mat(o.material), vertices_mm=v,
                              triangles=t, role="occluder", group=lum_group))
        if o.lamps is not None and on - set(o.lamps):
            notes.append(f"occluder {o.id} blocks every lamp in Cycles (the model: only "
                         f"{', '.join(o.lamps)})")
    return meshes


def _image_id(lamp, wins, k) -> str:
    """``lamp.<id>.mirror`` (one mirror rectangle) or ``lamp.<id>.mirror<k>`` (facet k of a prism)."""
    return _jid(f"lamp.{lamp.id}.mirror" + ("" if len(wins) == 1 else str(k)))


def _point_lamp(lamp, bands, R_bands, profile, wins, lum_group) -> list:
    """A point lamp (radius 0, as in the analytic model: exact inverse-square law, hard shadows;
    camera rays do not see it, see the environment maps' direct product) and its mirror images
    (one per window: a plane mirror's, or each facet of a prism)."""
    pos = tuple(float(c) for c in lamp.position_mm)
    out = [PointEmitters(id=_jid(f"lamp.{lamp.id}"), aim=lamp.aim, positions_mm=(pos,),
                         intensity_W_sr_nm=tuple(float(x) for x in bands), profile=profile,
                         radius_mm=0.0, group=lum_group)]
    for k, win in enumerate(wins):
        n, c = np.asarray(win.normal), np.asarray(win.centre_mm)
        img = _reflect_point(pos, c, n)
        out.append(PointEmitters(
            id=_image_id(lamp, wins, k), aim=tuple(_reflect(lamp.aim, n)),
            positions_mm=(tuple(float(x) for x in img),),
            intensity_W_sr_nm=tuple(float(x) for x in R_bands),
            profile=_mirrored_profile(profile, n), radius_mm=0.0, group=lum_group, window=win))
    return out


def _surface_lamp(lamp, bands, R_bands, profile, wins, effects: dict, lum_group) -> list:
    """The lamp's own surface — a tube's lateral surface (and caps), a panel's rectangle, a
    bulb's sphere — of radiance I_ref / A (a tube-end falloff weights it along the axis), and
    its mirror images (one per window: a plane mirror's, or each facet of a prism)."""
    v, t, area_m2 = _lamp_mesh(lamp)
    tef = _effect(effects, "tube_end_falloff", lamp.id)
    aw = None
    if tef is not None and lamp.kind == "tube":
        aw = AxialWeight(centre_mm=tuple(float(x) for x in lamp.position_mm), axis=lamp.axis,
                         length_mm=float(lamp.length_mm), end_level=float(tef.get("end_level", 0.5)),
                         falloff_length_mm=float(tef.get("falloff_length_mm", 100.0)))
    out = [AreaEmitter(
        id=_jid(f"lamp.{lamp.id}"), vertices_mm=v, triangles=t,
        radiance_W_sr_m2_nm=tuple(float(x) for x in bands / area_m2),
        profile=profile, aim=lamp.aim, group=lum_group, visible_to_camera=False, axial_weight=aw)]
    for k, win in enumerate(wins):
        # its mirror image (the image method): the same surface mirrored across the mirror
        # plane, radiance × the mirror's reflectance, shining only through the mirror
        n, c = np.asarray(win.normal), np.asarray(win.centre_mm)
        mv = _reflect_point(v, c, n)
        mt = tuple((a, cc, b) for a, b, cc in t)           # mirrored: keep facing out
        maw = None if aw is None else aw.model_copy(update={
            "centre_mm": tuple(float(x) for x in _reflect_point(aw.centre_mm, c, n)),
            "axis": tuple(_reflect(aw.axis, n))})
        out.append(AreaEmitter(
            id=_image_id(lamp, wins, k), vertices_mm=tuple(tuple(float(x) for x in p) for p in mv),
            triangles=mt, radiance_W_sr_m2_nm=tuple(float(x) for x in R_bands / area_m2),
            profile=_mirrored_profile(profile, n), aim=tuple(_reflect(lamp.aim, n)),
            group=lum_group, visible_to_camera=False, axial_weight=maw, window=win))
    return out


def _lamp_emitters(ir, lighting: str, effects: dict, lum_group, turning: bool,
                   notes: list[str]) -> tuple[list, list[JobMesh]]:
    """The emitters of the lamps the lighting switches on (and their mirror images), and the
    mirrors themselves as absorbing plates."""
    from lbscene.engine.light.lamp_spectrum import lamp_spectrum_1nm

    g = ir.grid
    emitters, meshes = [], []
    for lamp, level in ir.lamps_on(lighting):
        # shifted and filtered as the forward model's emitters are (one definition)
        spec = lamp_spectrum_1nm(ir, lamp, effects) * float(level)
        bands = g.integrate(spec)
        profile = _profile(lamp, effects)
        rp = _effect(effects, "reflector", lamp.id)
        refl = ir.reflectors.get(lamp.reflector) if (rp is not None and lamp.reflector) else None
        wins = _mirror_windows(ir, lamp, refl) if refl is not None else []
        if wins and turning:
            notes.append(f"lamp {lamp.id}: its mirror image shines through the mirror as it lies at "
                         "platform rotation 0; at other rotations the window does not turn with the "
                         "luminaire (products with a group transform are not exact there)")
        R_bands = None
        if refl is not None:
            R = np.clip(refl.reflectance.array_1nm * float(rp.get("reflectance_scale", 1.0)), 0, 1)
            R_bands = g.integrate(spec * R)
        if lamp.kind == "point":
            emitters.extend(_point_lamp(lamp, bands, R_bands, profile, wins, lum_group))
        else:
            emitters.extend(_surface_lamp(lamp, bands, R_bands, profile, wins, effects, lum_group))
        for k, win in enumerate(wins):
            # the mirror itself (each facet of a prism): an absorbing plate that blocks the
            # lamp's back light
            mv_, mt_ = _rect_quads(win.centre_mm, win.normal, win.u_axis, win.half_size_mm)
            mid = f"mirror.{lamp.id}" + ("" if len(wins) == 1 else f".facet{k}")
            meshes.append(JobMesh(id=_jid(mid), material=BLACK, vertices_mm=mv_,
                                  triangles=mt_, role="mirror", group=lum_group))
    return emitters, meshes


def _lamp_bodies_off(ir, lighting: str, effects: dict) -> list[JobMesh]:
    """The bodies of the lamps that are off: black objects in the light's way, as they are in
    the booth (and in the model's inter-reflection, ``lamp_bodies``)."""
    ip = effects.get("interreflection") or {}
    if ip.get("lamp_bodies", True) is False:
        return []
    meshes = []
    on_ids = {lp.id for lp, _ in ir.lamps_on(lighting)}
    for lamp in ir.lamps:
        if lamp.id in on_ids or lamp.kind == "point" or lamp.mount != "booth":
            continue
        v, t, _ = _lamp_mesh(lamp)
        meshes.append(JobMesh(id=_jid(f"lamp_body.{lamp.id}"), material=BLACK, vertices_mm=v,
                              triangles=t, role="lamp_body", group=None))
    return meshes


def _opal_medium(T, fd: float, ior: float | None, thickness_mm: float):
    """:func:`~lbscene.bakers.opal_slab.opal_slab_medium`, kept for the process (every job of a
    booth asks for the same plate)."""
    return _opal_medium_cached(tuple(round(float(x), 9) for x in T), round(float(fd), 9), ior,
                               round(float(thickness_mm), 9))


@functools.lru_cache(maxsize=32)
def _opal_medium_cached(T: tuple, fd: float, ior: float | None, thickness_mm: float):
    from .opal_slab import opal_slab_medium

    return opal_slab_medium(np.asarray(T, float), fd, ior, thickness_mm)


def _diffuser_sheet(ir, effects: dict, lum_group, notes: list[str]) -> list[TransmissiveSheet]:
    """The diffuser plate, when the ``diffuser`` effect is on: an opal (``lambertian``) plate as a
    volumetric slab (``model='opal'``, :mod:`lbscene.bakers.opal_slab`), any other as a thin
    transmissive sheet."""
    dp = _effect(effects, "diffuser")
    if dp is None or ir.diffuser is None:
        return []
    d = ir.diffuser
    T = np.clip(np.asarray(d.transmittance.bands) * float(dp.get("transmittance_scale", 1.0)), 0, 1)
    sc = d.scattering
    fd = dp.get("diffuse_fraction")
    if fd is None:
        fd = sc.get("diffuse_fraction", 0.0) if sc.get("type") == "lambertian" else 0.0
    v, t = _rect_quads((d.centre_mm[0], d.centre_mm[1], d.z_mm), (0, 0, -1), (1, 0, 0),
                       (d.size_mm[0] / 2, d.size_mm[1] / 2))
    if sc.get("type") == "roughness":
        from lbscene.engine.light.plates import plate_slab, slab_relative
        from lbscene.engine.light.rough_slab import fresnel_slab_transmittance

        r = float(sc["roughness"])
        c60 = np.array([0.5])
        dev = float(slab_relative(ir, c60)[0] / (fresnel_slab_transmittance(c60, d.ior)[0] /
                                                  fresnel_slab_transmittance(np.ones(1), d.ior)[0])) - 1
        notes.append(f"diffuser roughness {r:g} (GGX α = {r * r:.4g}): a thin sheet with the clear "
                     f"plate's Fresnel angular transmittance; the rough slab's T(θ) ({100 * dev:+.1f} % "
                     f"at 60°) and its lobe (90 % within "
                     f"{float(plate_slab(ir).lobe_deg(1.0, 0.9)):.2g}° at normal incidence) are not "
                     f"in the bake")
    medium = None
    if sc.get("type") == "lambertian" and fd > 0:
        try:
            medium = _opal_medium(T, float(fd), d.ior, d.thickness_mm)
        except ValueError as exc:
            notes.append(f"opal diffuser: {exc}; drawn as a thin sheet instead (transparent and "
                         f"translucent parts: no entry law, no diffuse reflection)")
    if medium is not None:
        notes.append(f"opal diffuser: a {d.thickness_mm:g} mm slab of a scattering medium (optical depth "
                     f"{medium.optical_depth:.3g}, HG g {medium.anisotropy:.3f}"
                     + (f", faces of ior {d.ior:g}" if d.ior is not None and d.ior > 1 else
                        ", faces matched to the air") + ")")
        if np.ptp(T) > 1e-9:
            notes.append("opal diffuser: its transmittance varies over wavelength; the medium scatters "
                         "as fitted at the most transmissive band and absorbs in the others (the diffuse "
                         "fraction holds at that band)")
        if sc.get("reflectance") is not None:
            notes.append("opal diffuser: its declared reflectance is not in the bake (the medium does "
                         "not absorb what the transmittance leaves: R = 1 - T)")
        absorb = medium.absorption_per_mm if any(a > 0 for a in medium.absorption_per_mm) else None
        return [TransmissiveSheet(id="diffuser", role="diffuser", vertices_mm=v, triangles=t,
                                  transmittance=tuple(float(x) for x in T), ior=d.ior,
                                  diffuse_fraction=float(fd), model="opal", thickness_mm=d.thickness_mm,
                                  scattering_per_mm=medium.scattering_per_mm,
                                  anisotropy=medium.anisotropy, absorption_per_mm=absorb,
                                  group=lum_group)]
    if fd > 0:
        notes.append(f"diffuser diffuse fraction {float(fd):g}: the scattered light leaves the sheet with "
                     f"the opal exit law; its entry weight (1 - F(θi)) and the diffuse reflection are not "
                     f"in the bake (the model has them); the plate reflects as a clear plate's faces do")
    from lbscene.engine.light.plates import reference_transmittance

    if d.ior is not None and d.ior > 1.0 and d.thickness_mm > 0:
        notes.append(f"diffuser: a sheet of no thickness; the {d.thickness_mm:g} mm plate's refraction (the "
                     f"model's paths through it, lamps behind it "
                     f"{d.thickness_mm * (1 - 1 / d.ior):.2g} mm closer near its normal) is not in the bake, "
                     f"and the cross-check compares it with the model's plate of no thickness")
    return [TransmissiveSheet(id="diffuser", role="diffuser", vertices_mm=v, triangles=t,
                              transmittance=tuple(float(x) for x in T), ior=d.ior,
                              roughness=float(sc.get("roughness", 0.0)),
                              diffuse_fraction=float(fd), thickness_mm=d.thickness_mm,
                              reference_transmittance=(reference_transmittance(ir)
                                                       if sc.get("type") == "roughness" else None),
                              group=lum_group)]


def diffuser_is_thin_sheet(ir, effects: dict) -> bool:
    """Does the bake draw the booth's diffuser as a sheet of no thickness (a clear or rough plate,
    an opal plate without a diffuse part or whose medium cannot be fitted), the sheet
    :func:`_diffuser_sheet` makes?"""
    sheets = _diffuser_sheet(ir, effects, None, [])
    return bool(sheets) and sheets[0].model == "thin"


def _environment_products(ir, quality: str, env_width: int | None, turning: bool) -> list:
    """Environment maps of the sample's surroundings (with their direct-light points): one at the
    sample, and one per geometry where the sample is, in its frame, where the platform moves it."""
    products = []
    pf = ir.platform
    sample = np.asarray(ir.sample_position_mm, float)
    width = env_width or ENV_WIDTH[quality]

    def env_pair(suffix, up, fwd, geometry, transforms, centre=sample):
        pos = tuple(float(x) for x in centre + 1.0 * up)
        dirs = [("up", up)] + [(f"dir{k:02d}", d) for k, d in enumerate(_sphere_dirs(62))]
        direct = IrradiancePointsProduct(
            id=_jid(f"sample_direct{suffix}"), light_paths="direct", group_transforms=transforms,
            points=tuple(MeasurementPoint(position_mm=pos, normal=tuple(map(float, d)), name=nm)
                         for nm, d in dirs), offset_mm=0.0)
        env = EnvironmentMapProduct(id=_jid(f"env{suffix}"), position_mm=pos, forward=tuple(fwd),
                                    up=tuple(up), width_px=width, geometry=geometry,
                                    group_transforms=transforms, direct_product=direct.id)
        products.extend([env, direct])

    z, y = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
    if not turning:
        env_pair("", z, y, None, {})
    # one map per geometry where the sample is, in its frame: every geometry of a luminaire
    # that turns with the platform (the luminaire turned with it); the tilted ones of a
    # platform under fixed lamps (the SpectraLight's 45° stand carries the sample 105 mm up,
    # ~1.4× the rest position's direct light)
    for geo in (ir.geometries if pf is not None else ()):
        if not (turning or geo.platform_rotation_deg):
            continue
        tr = RigidTransform(axis=pf.rotation_axis, angle_deg=float(geo.platform_rotation_deg or 0.0),
                            centre_mm=pf.pivot_mm)
        M = tr.matrix()[:3, :3]
        pivot = np.asarray(pf.pivot_mm, float)
        env_pair(f".{geo.name}", M @ z, M @ y, geo.name, {LUMINAIRE_GROUP: tr} if turning else {},
                 centre=M @ (sample - pivot) + pivot)
    return products


def _map_products(ir, quality: str, light_paths: str, turning: bool) -> list:
    """Irradiance maps of the floor, and of a platform that does not carry the lamps."""
    cell = MAP_CELL_MM[quality]
    it = ir.interior
    pf = ir.platform
    nx, ny = max(2, round(it.width_mm / cell)), max(2, round(it.depth_mm / cell))
    products = [IrradianceMapProduct(id="floor", origin_mm=(-it.width_mm / 2, -it.depth_mm / 2, 0.0),
                                     size_mm=(it.width_mm, it.depth_mm), resolution=(nx, ny),
                                     light_paths=light_paths)]
    if pf is not None and not turning:
        cx, cy, cz = pf.centre_mm
        sx, sy = pf.size_mm
        products.append(IrradianceMapProduct(
            id="platform", origin_mm=(cx - sx / 2, cy - sy / 2, cz), size_mm=(sx, sy),
            resolution=(max(2, round(sx / cell)), max(2, round(sy / cell))), light_paths=light_paths))
    return products


def _points_product(ir, points, normals, point_names, light_paths: str) -> IrradiancePointsProduct:
    """Irradiance at points: the given ones, or the 55-point grid around the sample (facing up)."""
    if points is None:
        P = grid_points(ir)
        names = [f"g{i:02d}" for i in range(len(P))]
        N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    else:
        P = np.atleast_2d(np.asarray(points, float))
        N = np.tile([0.0, 0.0, 1.0], (len(P), 1)) if normals is None else \
            np.broadcast_to(np.asarray(normals, float), P.shape)
        names = list(point_names) if point_names is not None else [f"p{i}" for i in range(len(P))]
    return IrradiancePointsProduct(
        id="grid" if points is None else "points",
        points=tuple(MeasurementPoint(position_mm=tuple(map(float, p)), normal=tuple(map(float, n)),
                                      name=nm) for p, n, nm in zip(P, N, names)),
        light_paths=light_paths)


def lighting_job(ir, lighting: str, *, quality: str = "preview", samples: int | None = None,
                 effects: dict | None = None, surfaces: Literal["actual", "black"] = "actual",
                 points=None, normals=None, point_names: Iterable[str] | None = None,
                 light_paths: Literal["all", "direct"] = "all",
                 environment: bool = True, maps: bool = True, grid: bool = True,
                 env_width: int | None = None, name: str | None = None, seed: int = 0) -> BakeJob:
    """The bake job of one lighting configuration of a compiled booth."""
    if lighting not in ir.lighting:
        raise KeyError(lighting)
    effects = dict(ir.effects if effects is None else effects)
    grid_spec = BandGridSpec(**{k: ir.bands[k] for k in ("first_centre_nm", "width_nm", "count")})
    notes = []
    from lbscene.engine.light.effects.physics import BACKENDS
    from lbscene.engine.light.effects.registry import get_effect

    # effects a bake does not model are named in the job, never silently dropped (instrument
    # effects describe a meter's reading, not the light in the booth)
    off = sorted(e for e in effects if "cycles" not in getattr(get_effect(e), "backends", BACKENDS))
    if off:
        notes.append(f"not modelled by the bake (its effect declares no 'cycles' backend): {', '.join(off)}")

    # a turning luminaire (illumination fixed to a rotating platform) is one group
    pf = ir.platform
    turning = bool(pf is not None and pf.illumination_fixed_to_platform
                   and any(x.platform_rotation_deg for x in ir.geometries))
    lum_group = LUMINAIRE_GROUP if turning else None

    def mat(mid):
        return BLACK if (surfaces == "black" or mid is None) else _jid(mid)

    meshes = [JobMesh(id=_jid(f"surface.{s.id}"), material=mat(s.material), vertices_mm=s.vertices_mm,
                      triangles=s.triangles, role=s.role,
                      group=lum_group if s.role in ("mesh", "platform") else None)
              for s in ir.surfaces]
    meshes += _occluder_meshes(ir, lighting, effects, mat, lum_group, notes)
    emitters, mirrors = _lamp_emitters(ir, lighting, effects, lum_group, turning, notes)
    meshes += mirrors
    meshes += _lamp_bodies_off(ir, lighting, effects)
    sheets = _diffuser_sheet(ir, effects, lum_group, notes)
    if any(s.model == "opal" and (s.ior or 1.0) > 1.0 for s in sheets) and \
            any(e.type == "points" for e in emitters):
        notes.append("opal diffuser: its faces refract, which stops Cycles' shadow rays, and no path "
                     "hits a point lamp: point lamps send no light through the plate in the bake")

    products = []
    if environment:
        products += _environment_products(ir, quality, env_width, turning)
    if maps:
        products += _map_products(ir, quality, light_paths, turning)
    if grid or points is not None:
        products.append(_points_product(ir, points, normals, point_names, light_paths))

    source = {"ir_hash": ir.content_hash, "booth": ir.booth_name, "lighting": lighting,
              "surfaces": surfaces, "effects": ",".join(sorted(effects))}
    if notes:
        source["notes"] = "; ".join(notes)
    return BakeJob(name=_jid(name or lighting), source=source, bands=grid_spec,
                   materials=_job_materials(ir, lighting, ir.grid.count), meshes=tuple(meshes),
                   emitters=tuple(emitters), sheets=tuple(sheets), products=tuple(products),
                   quality=Quality(preset=quality, samples=samples, seed=seed))


def _sphere_dirs(n: int) -> np.ndarray:
    """``n`` near-uniform unit vectors (Fibonacci sphere)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (1.0 + math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.c_[r * np.cos(phi), r * np.sin(phi), z]


def job_path_in_build(build_dir: Path, lighting: str) -> Path:
    return Path(build_dir) / "lighting" / lighting / "bake" / "job.json"


def write_build_products(ir, lighting: str, folder: Path) -> list[Path]:
    """``lbscene build`` hook: the preview bake job of this lighting, ``bake/job.json``."""
    path = Path(folder) / "bake" / "job.json"
    save_job(lighting_job(ir, lighting), path)
    return [path]
