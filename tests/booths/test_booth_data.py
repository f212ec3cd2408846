"""Physical checks of the shipped booth data (booths/*/booth.yaml and spectra/*.csv).

The spectra and dimensions of the shipped booths are estimates; these tests pin what
makes them *plausible*, with expected values taken from standards and lamp
designations, not from the data themselves:

* CIE 15:2004 white points (D65 x, y = 0.31272, 0.32903, 6504 K; D50 2° and 10°;
  illuminant A = Planckian radiator at 2856 K);
* ISO 3664:2009 (P1: D50 within 0.005 in u'10 v'10, Ra >= 90, 2000 lx ± 500 lx;
  P2: 500 lx ± 125 lx; surround reflectance below 60 %);
* lamp designations (TL84 and /8xx: 4000 K; /950: 5000 K, Ra >= 90);
* ASTM E2194 / DIN 6175-2 geometry names (45as15: 45° illumination, 15° from specular).

Colorimetry is computed here with colour-science straight from the CSV files, not with
lbscene's own spectral code.
"""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import numpy as np
import pytest

# colour-science warns when it aligns a 380-780 nm table to its 360-780 nm data; expected here
pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning",
                                        "ignore::colour.utilities.ColourWarning")

REPO = Path(__file__).resolve().parents[2]
BOOTHS = REPO / "booths"
QC = BOOTHS / "xrite-spectralight-qc"
BYK = BOOTHS / "byk-byko-spectra-effect"
ISO = BOOTHS / "iso3664-p1-d50"

# CIE 15:2004, Table T.3 / T.8 (chromaticity coordinates of the CIE illuminants)
D65_XY_2DEG = (0.31272, 0.32903)
D50_XY_2DEG = (0.34567, 0.35850)
D50_XY_10DEG = (0.34773, 0.35952)
D65_CCT_K = 6504.0
A_CCT_K = 2856.0


@pytest.fixture(scope="module")
def colour():
    import colour as _colour

    return _colour


def _booth(folder: Path):
    from lbscene.engine.files.load import load_document
    from lbscene.schemas.booth import Booth

    return load_document(folder / "booth.yaml", Booth).model


def _read_csv(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header = [h.strip() for h in rows[0]]
    data = np.array([[float(c) for c in r] for r in rows[1:] if r], float)
    return header, data[:, 0], data[:, 1]


def _sd(colour, path: Path):
    _, wl, v = _read_csv(path)
    return colour.SpectralDistribution(dict(zip(wl, v)), name=path.name)


def _cmfs(colour, deg: int = 2):
    name = {2: "CIE 1931 2 Degree Standard Observer", 10: "CIE 1964 10 Degree Standard Observer"}[deg]
    return colour.MSDS_CMFS[name]


def _xy(colour, sd, deg: int = 2) -> np.ndarray:
    # an emission spectrum: chromaticity of its XYZ (sd_to_XYZ without illuminant = under E)
    return colour.XYZ_to_xy(colour.sd_to_XYZ(sd, _cmfs(colour, deg)))


def _duv_prime(colour, xy1, xy2) -> float:
    """Distance in the CIE 1976 u'v' diagram."""
    return float(np.hypot(*(colour.xy_to_Luv_uv(np.asarray(xy1)) - colour.xy_to_Luv_uv(np.asarray(xy2)))))


def _cct(colour, sd) -> float:
    uv = colour.xy_to_UCS_uv(_xy(colour, sd))
    return float(colour.temperature.uv_to_CCT_Ohno2013(uv)[0])


def _lamp(booth, lamp_id):
    return next(lp for lp in booth.lamps if lp.id == lamp_id)


def _spd_of(colour, folder: Path, spec):
    """SpectralDistribution of a lamp's `spd:` spec (the kinds used by the shipped booths)."""
    if spec.type == "csv":
        return _sd(colour, folder / spec.path)
    if spec.type == "blackbody":
        return colour.sd_blackbody(spec.cct_K, colour.SpectralShape(380, 780, 5))
    if spec.type == "cie_illuminant":
        return colour.SDS_ILLUMINANTS[spec.name].copy().trim(colour.SpectralShape(380, 780, 5))
    if spec.type == "light_source":
        return colour.SDS_LIGHT_SOURCES[spec.name].copy()
    raise AssertionError(f"unexpected spd type {spec.type}")


# --------------------------------------------------------------------------- files

CSV_FILES = sorted(BOOTHS.glob("*/spectra/*.csv"))


def test_the_three_booths_have_their_spectra():
    assert {p.parent.parent.name for p in CSV_FILES} >= {QC.name, BYK.name, ISO.name}


@pytest.mark.parametrize("path", CSV_FILES, ids=[f"{p.parent.parent.name}/{p.name}" for p in CSV_FILES])
def test_spectrum_csv_format(path):
    header, wl, v = _read_csv(path)
    assert header[0] == "wavelength_nm" and len(header) == 2
    assert header[1] in {"transmittance", "reflectance", "relative_power"}
    np.testing.assert_allclose(np.diff(wl), 5.0)
    assert wl[0] <= 380 and wl[-1] >= 780, "5 nm table over at least 380-780 nm"
    assert np.all(np.isfinite(v)) and v.min() >= 0
    if header[1] != "relative_power":
        assert v.max() <= 1.0, "reflectance/transmittance within [0, 1]"


def test_every_yaml_starts_with_the_schema_line_and_is_version_1():
    for f in sorted(BOOTHS.glob("*/booth.yaml")):
        first = f.read_text().splitlines()[0]
        assert first == "# yaml-language-server: $schema=../../schemas/json/booth.schema.json", f
        b = _booth(f.parent)
        assert b.version == 1 and b.provenance.status in {"estimate", "measured", "published"}


def test_generated_csvs_are_up_to_date():
    """booths/tools/make_spectra.py regenerates exactly the committed CSVs (no hand edits)."""
    spec = importlib.util.spec_from_file_location("make_spectra", BOOTHS / "tools" / "make_spectra.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for path, text in mod.build_all().items():
        assert path.read_text() == text, f"{path} is stale: run booths/tools/make_spectra.py"


# --------------------------------------------------------------------------- SpectraLight QC

def test_qc_d65_simulator_is_a_d65_within_booth_tolerance(colour):
    """halogen (blackbody at the lamp's CCT) × D65 filter: CCT 6504 ± 300 K, Δu'v' <= 0.015."""
    booth = _booth(QC)
    on = booth.lighting["D65"].lamps
    assert len(on) == 2
    for lid in on:
        lamp = _lamp(booth, lid)
        assert lamp.spd.type == "blackbody" and 2900 <= lamp.spd.cct_K <= 3300, "tungsten halogen"
        halogen = colour.sd_blackbody(lamp.spd.cct_K, colour.SpectralShape(380, 780, 5))
        filt = _sd(colour, QC / booth.filters[lamp.filter].transmittance.path)
        sim = halogen * filt
        assert abs(_cct(colour, sim) - D65_CCT_K) <= 300
        assert _duv_prime(colour, _xy(colour, sim), D65_XY_2DEG) <= 0.015
        # commercial daylight simulators are sold with CIE Ra above 90
        assert colour.colour_rendering_index(sim) >= 90


def test_qc_d65_simulator_is_not_a_copy_of_d65(colour):
    """The seed: commercial filtered-halogen D65 deviates from CIE D65 (e.g. near 560 nm)."""
    booth = _booth(QC)
    lamp = _lamp(booth, "D65_left")
    wl = np.arange(400, 701, 5)
    halogen = colour.sd_blackbody(lamp.spd.cct_K, colour.SpectralShape(380, 780, 5))
    sim = (halogen * _sd(colour, QC / booth.filters[lamp.filter].transmittance.path))[wl]
    d65 = colour.SDS_ILLUMINANTS["D65"][wl]
    ratio = (sim / sim.mean()) / (d65 / d65.mean())
    assert 0.02 <= np.abs(ratio - 1).max() <= 0.30


def test_qc_d65_filter_is_a_blue_conversion_filter():
    """A tungsten → daylight filter passes blue far better than red."""
    booth = _booth(QC)
    _, wl, t = _read_csv(QC / booth.filters["d65_filter"].transmittance.path)
    t_450, t_650 = np.interp([450, 650], wl, t)
    assert t_450 > 3 * t_650


def test_qc_a_lamp_is_2856_k(colour):
    booth = _booth(QC)
    (lid,) = booth.lighting["A"].lamps
    lamp = _lamp(booth, lid)
    assert abs(lamp.position_mm[0]) < 1 and abs(lamp.position_mm[1]) < 1, "A lamp at the centre (seed)"
    assert abs(_cct(colour, _spd_of(colour, QC, lamp.spd)) - A_CCT_K) <= 50


def test_qc_horizon_is_2300_k(colour):
    booth = _booth(QC)
    (lid,) = booth.lighting["HZ"].lamps
    assert abs(_cct(colour, _spd_of(colour, QC, _lamp(booth, lid).spd)) - 2300.0) <= 50


def test_qc_fluorescent_is_three_tl84_tubes(colour):
    booth = _booth(QC)
    on = [_lamp(booth, i) for i in booth.lighting["TL84"].lamps]
    assert len(on) == 3 and all(lp.type == "tube" for lp in on)
    for lp in on:  # TL84 = a 4000 K ("84") triphosphor tube
        assert abs(_cct(colour, _spd_of(colour, QC, lp.spd)) - 4000.0) <= 200


def test_qc_uv_lamp_emits_uva(colour):
    booth = _booth(QC)
    (lid,) = booth.lighting["UV"].lamps
    _, wl, p = _read_csv(QC / _lamp(booth, lid).spd.path)
    assert 355 <= wl[np.argmax(p)] <= 375, "blacklight-blue peak"
    uva = (wl >= 315) & (wl <= 400)
    assert p[uva].sum() / p.sum() > 0.95, "almost all radiant power in the UVA"


def test_qc_seven_sources_and_their_optics():
    booth = _booth(QC)
    # the seed's list: two D65 lamps, HZ, A, three fluorescent tubes and a UV source (8 lamps)
    assert len(booth.lamps) == 8
    assert [len(booth.lighting[n].lamps) for n in ("D65", "A", "HZ", "TL84", "UV")] == [2, 1, 1, 3, 1]
    d65 = [_lamp(booth, i) for i in booth.lighting["D65"].lamps]
    assert all(lp.filter and lp.reflector for lp in d65)
    assert all(booth.reflectors[lp.reflector].type == "prism" for lp in d65)
    masks = [o for o in booth.occluders if o.type == "aperture_plate"]
    # one filter mask under each D65 lamp, above the diffuser; the boxes are objects in the
    # cavity, stopping every lamp's light (no `lamps:` on them)
    assert all(o.lamps is None for o in booth.occluders)
    assert len(masks) == len(d65)
    for lamp in d65:
        (o,) = [m for m in masks if abs(m.centre_mm[0] - lamp.position_mm[0]) < 1e-9
                and abs(m.centre_mm[1] - lamp.position_mm[1]) < 1e-9]
        assert booth.diffuser.z_mm < o.centre_mm[2] < lamp.position_mm[2]
    # every lamp above the glass diffuser (roughness 0.04, seed), inside the box
    assert booth.diffuser.scattering.type == "roughness" and booth.diffuser.scattering.roughness == 0.04
    for lp in booth.lamps:
        assert booth.diffuser.z_mm < lp.position_mm[2] <= booth.interior.height_mm
    assert {"D65", "A", "HZ", "TL84", "UV"} <= set(booth.lighting)


def test_qc_grey_interior_is_neutral_n7(colour):
    booth = _booth(QC)
    sd = _sd(colour, QC / booth.materials[booth.surfaces.floor].reflectance.path)
    Y, lab = _Y_and_lab(colour, sd)
    assert abs(Y - 0.42) <= 0.02, "Munsell N7: Y = 42.0 % (ASTM D1535)"
    assert np.hypot(lab[1], lab[2]) <= 2.0, "neutral"


# --------------------------------------------------------------------------- byko-spectra effect

def test_byk_pl_l_950_is_a_5000_k_ra_90_lamp_more_peaked_than_d50(colour):
    booth = _booth(BYK)
    lamps = [_lamp(booth, i) for i in booth.lighting["FL950"].lamps]
    assert len({lp.group for lp in lamps}) == 1, "the legs of one PL-L lamp share a group"
    sd = _spd_of(colour, BYK, lamps[0].spd)
    # "/950": colour rendering 9x (Ra >= 90), 5000 K
    assert abs(_cct(colour, sd) - 5000.0) <= 300
    assert colour.colour_rendering_index(sd) >= 90
    # seed, Fig. 3: the measured SPD is more peaked than D50
    wl = np.arange(400, 701, 5)
    peakiness = lambda v: v.max() / np.median(v)  # noqa: E731
    assert peakiness(sd[wl]) > 1.5 * peakiness(colour.SDS_ILLUMINANTS["D50"][wl])


def _rot(axis, deg):
    from scipy.spatial.transform import Rotation

    a = np.asarray(axis, float)
    return Rotation.from_rotvec(np.radians(deg) * a / np.linalg.norm(a)).as_matrix()


def _angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def test_byk_geometries_follow_from_platform_rotation():
    """Rotating the platform (lamp fixed to it) by each geometry's rotation gives, for the
    fixed viewing slit, exactly the illumination and aspecular angles of the geometry name
    (ASTM E2194: aspecular measured from the specular direction toward the illumination)."""
    booth = _booth(BYK)
    p = booth.platform
    assert p.illumination_fixed_to_platform and p.illumination_angle_deg == 45
    names = [g.name for g in booth.geometries]
    assert names == ["45as-15", "45as15", "45as25", "45as45", "45as75", "45as110"]
    c = np.asarray(p.centre_mm)
    lamp_centre = np.mean([_lamp(booth, i).position_mm for i in booth.lighting["FL950"].lamps], axis=0)
    to_eye = np.asarray(booth.observer.position_mm) - c
    for g in booth.geometries:
        ill_deg, asp_deg = float(g.name.split("as")[0]), float(g.name.split("as")[1])
        R = _rot(p.rotation_axis, g.platform_rotation_deg)
        normal = R @ np.array([0.0, 0.0, 1.0])
        to_lamp = R @ (lamp_centre - c)
        specular = 2 * (to_lamp @ normal) / (normal @ normal) * normal - to_lamp
        assert _angle_deg(normal, to_lamp) == pytest.approx(ill_deg, abs=0.5), g.name
        # unsigned angle from the specular direction, signed: + toward the illumination side
        asp = _angle_deg(specular, to_eye)
        side = np.sign(np.cross(specular, to_eye) @ np.cross(specular, to_lamp))
        assert side * asp == pytest.approx(asp_deg, abs=0.5), g.name
        assert normal @ to_eye > 0, f"{g.name}: the slit must see the front of the sample"


def test_byk_cavity_obj_matches_the_aperture_plate():
    """The OBJ luminaire cavity, placed by its transform, has its aperture where the
    `aperture_plate` occluder is, facing the same way, around the lamp."""
    import trimesh

    booth = _booth(BYK)
    (g,) = [g for g in booth.geometry_files if g.type == "obj"]
    mesh = trimesh.load(str(BYK / g.path), file_type="obj", force="mesh", process=False)
    ext = mesh.bounds[1] - mesh.bounds[0]
    assert 100 < ext.max() < 2000, "millimetres"
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", g.transform.rotate_xyz_deg, degrees=True).as_matrix()
    place = lambda v: (np.asarray(v, float) * g.transform.scale) @ R.T + g.transform.translate_mm  # noqa: E731
    (plate,) = [o for o in booth.occluders if o.type == "aperture_plate"]
    # the aperture face of the mesh: the face (plane z = min z) with a hole
    zmin = mesh.vertices[:, 2].min()
    front = mesh.vertices[np.isclose(mesh.vertices[:, 2], zmin)]
    np.testing.assert_allclose(place(front.mean(axis=0)), plate.centre_mm, atol=1.0)
    n = R @ np.array([0.0, 0.0, -1.0])
    np.testing.assert_allclose(n, np.asarray(plate.normal) / np.linalg.norm(plate.normal), atol=1e-6)
    lamp_centre = np.mean([_lamp(booth, i).position_mm for i in booth.lighting["FL950"].lamps], axis=0)
    lo, hi = place(mesh.bounds[0]), place(mesh.bounds[1])
    assert np.all(np.minimum(lo, hi) - 1 <= lamp_centre) and np.all(lamp_centre <= np.maximum(lo, hi) + 1)
    # the lamps aim through the aperture
    for lid in booth.lighting["FL950"].lamps:
        aim = np.asarray(_lamp(booth, lid).aim, float)
        assert _angle_deg(aim, n) < 1.0


def test_byk_walls_and_floor_are_about_5_percent():
    booth = _booth(BYK)
    for role in ("floor", "left_wall", "right_wall", "rear_wall", "ceiling"):
        spec = booth.materials[getattr(booth.surfaces, role)].reflectance
        assert spec.type == "constant" and 0.03 <= spec.value <= 0.07, role


# --------------------------------------------------------------------------- ISO 3664 P1 booth

def _Y_and_lab(colour, refl_sd, illuminant="D50"):
    ill = colour.SDS_ILLUMINANTS[illuminant]
    cmfs = _cmfs(colour, 2)
    XYZ = colour.sd_to_XYZ(refl_sd, cmfs, ill) / 100
    white = colour.sd_to_XYZ(colour.sd_ones(refl_sd.shape), cmfs, ill) / 100
    return float(XYZ[1]), colour.XYZ_to_Lab(XYZ, colour.XYZ_to_xy(white))


def test_iso_p1_source_meets_iso_3664_chromaticity_and_colour_rendering(colour):
    booth = _booth(ISO)
    (lid,) = booth.lighting["P1"].lamps
    sd = _spd_of(colour, ISO, _lamp(booth, lid).spd)
    # ISO 3664:2009: D50 chromaticity within 0.005 in CIE 1976 u'10 v'10 (10° observer)
    assert _duv_prime(colour, _xy(colour, sd, 10), D50_XY_10DEG) <= 0.005
    assert _duv_prime(colour, _xy(colour, sd, 2), D50_XY_2DEG) <= 0.005
    spec = colour.colour_rendering_index(sd, additional_data=True)
    assert spec.Q_a >= 90, "CIE Ra >= 90"
    # ISO 3664:2009 also asks for special indices R9-R14 >= 80
    assert min(spec.Q_as[i].Q_a for i in range(9, 15)) >= 80


def _lambertian_panel_illuminance_lx(flux_lm, length_mm, width_mm, height_mm, px_mm=0.0, py_mm=0.0):
    """Illuminance under a uniform Lambertian rectangle parallel to the receiver
    (closed-form configuration factor of a differential area to a rectangle,
    summed over the four rectangles meeting at the foot of the receiver)."""
    def f(a, b):
        ra, rb = np.sqrt(1 + a * a), np.sqrt(1 + b * b)
        return (a / ra * np.arctan(b / ra) + b / rb * np.arctan(a / rb)) / (2 * np.pi)

    exitance = flux_lm / (length_mm * width_mm * 1e-6)  # lm/m², Lambertian: E = M · F
    F = sum(f(w / height_mm, d / height_mm)
            for w in (length_mm / 2 + px_mm, length_mm / 2 - px_mm)
            for d in (width_mm / 2 + py_mm, width_mm / 2 - py_mm))
    return exitance * F


def test_iso_panel_illuminance_closed_form():
    """Sanity of the closed form: a small panel far away is a point source, E = I/h²."""
    flux, h = 100.0, 5000.0
    e = _lambertian_panel_illuminance_lx(flux, 10.0, 10.0, h)
    assert e == pytest.approx((flux / np.pi) / (h * 1e-3) ** 2, rel=1e-4)


def test_iso_p1_and_p2_illuminance_at_the_viewing_plane():
    """ISO 3664:2009: P1 2000 lx ± 500 lx, P2 500 lx ± 125 lx (direct light of the panel)."""
    booth = _booth(ISO)
    for name, (lo, hi) in {"P1": (1500, 2500), "P2": (375, 625)}.items():
        cfg = booth.lighting[name]
        total = 0.0
        for lid in cfg.lamps:
            lp = _lamp(booth, lid)
            # a panel is a Lambertian rectangle by its type: no profile on top
            assert lp.type == "panel" and lp.profile.type == "isotropic"
            assert lp.output.type == "luminous_flux_lm"
            h = lp.position_mm[2] - booth.sample_position_mm[2]
            total += cfg.dimming.get(lid, 1.0) * _lambertian_panel_illuminance_lx(
                lp.output.value_lm, lp.length_mm, lp.width_mm, h)
        assert lo <= total <= hi, f"{name}: {total:.0f} lx"
        assert cfg.nominal_illuminance_lx is not None and lo <= cfg.nominal_illuminance_lx <= hi


def test_iso_surround_is_neutral_matte_grey_below_60_percent(colour):
    booth = _booth(ISO)
    for role in ("floor", "left_wall", "right_wall", "rear_wall"):
        mat = booth.materials[getattr(booth.surfaces, role)]
        assert mat.type == "diffuse"
        Y, lab = _Y_and_lab(colour, _sd(colour, ISO / mat.reflectance.path))
        assert 0.50 <= Y < 0.60, f"{role}: ~N8, below 60 % (ISO 3664)"
        assert np.hypot(lab[1], lab[2]) <= 2.0, f"{role}: neutral"
    assert booth.platform.size_mm == (900, 600)
