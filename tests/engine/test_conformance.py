"""``lbscene conformance``: colorimetry, uniformity and the ISO 3664 checks, against outside truth.

Expected values come from outside the code under test:

* CIE 15:2004 Table T.3 (CCT of D65 6504 K, of A 2856 K) and the chromaticities of the CIE
  illuminants; D65 lies 0.0032 above the Planckian locus (Ohno 2014);
* CIE 15:2004 Table T.8: CIE 13.3 general colour rendering index of FL2 (64), FL7 (90), FL11 (83);
* ANSI/IES TM-30-18 (and CIE 224:2017) for FL2: Rf 70, Rg 86 (the IES calculator's figures, as
  colour-science's own tests pin them);
* the closed form of a point source over a plane, E = I·cos³θ / h²;
* ISO 3664:2009 P1 requirements (2000 lx ± 500 lx, D50 within 0.005 in u'10 v'10, Ra ≥ 90,
  surround below 60 %) applied by hand to booths whose light is a CIE illuminant.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning",
                                        "ignore::colour.utilities.ColourWarning")


def _colorimetry_of(name):
    import colour

    from lbscene.engine.conformance.colorimetry import colorimetry_1nm
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    sd = colour.SDS_ILLUMINANTS[name]
    return colorimetry_1nm(np.interp(WL, sd.wavelengths, sd.values, left=0.0, right=0.0))


@pytest.mark.parametrize("name, x, y, cct_K, duv", [
    ("D65", 0.31272, 0.32903, 6504.0, 0.0032),
    ("A", 0.44757, 0.40745, 2856.0, 0.0),
])
def test_chromaticity_cct_and_duv_of_cie_illuminants(name, x, y, cct_K, duv):
    c = _colorimetry_of(name)
    assert c.xy == pytest.approx((x, y), abs=2e-5)
    assert c.cct_K == pytest.approx(cct_K, abs=2.0)
    assert c.duv == pytest.approx(duv, abs=1e-4)
    assert c.cri_ra == pytest.approx(100.0, abs=0.05)      # a reference illuminant renders itself


@pytest.mark.parametrize("name, ra", [("FL2", 64), ("FL7", 90), ("FL11", 83)])
def test_cri_of_cie_fluorescent_illuminants(name, ra):
    c = _colorimetry_of(name)
    assert c.cri_ra == pytest.approx(ra, abs=0.6)
    assert len(c.cri_r) == 14
    # Ra is the mean of R1..R8 (CIE 13.3)
    assert np.mean(c.cri_r[:8]) == pytest.approx(c.cri_ra, abs=1e-6)


def test_fidelity_and_gamut_of_fl2():
    c = _colorimetry_of("FL2")
    assert c.cie2017_rf == pytest.approx(70, abs=0.3)
    assert c.tm30_rf == pytest.approx(70, abs=0.3)
    assert c.tm30_rg == pytest.approx(86, abs=0.6)


def test_no_light_and_far_from_the_locus():
    from lbscene.engine.conformance.colorimetry import colorimetry_1nm

    assert colorimetry_1nm(np.zeros(471)).xy is None
    mono = np.zeros(471)
    mono[170] = 1.0                                         # 530 nm: a green line
    c = colorimetry_1nm(mono)
    assert c.xy is not None and c.cri_ra is None and c.cct_K is None and c.duv is None
    assert "Planckian" in c.notes[0]


# --------------------------------------------------------------------------- booths

BOOTH = """version: 1
kind: booth
name: {name}
provenance: {{status: synthetic}}
interior: {{type: box, width_mm: 1400, depth_mm: 1000, height_mm: 2200}}
materials:
  grey: {{type: diffuse, reflectance: {{type: constant, value: {rho}}}}}
surfaces: {{floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}}
lamps:
  - id: bulb
    type: point
    position_mm: [0, 0, {h_mm}]
    spd: {{type: cie_illuminant, name: {spd}}}
    output: {{type: peak_intensity_cd, value_cd: {cd}}}
lighting:
  P1: {{lamps: [bulb], standard: ISO_3664_P1}}
platform: {{centre_mm: [0, 0, 0], size_mm: [600, 400], rotation_axis: [1, 0, 0]}}
observer: {{type: eye_point, position_mm: [0, -900, 500]}}
"""


def _booth(tmp_path, *, name="point booth", rho=0.3, h_mm=2000.0, spd="D50", lx=2000.0):
    d = tmp_path / f"b-{spd}-{rho}-{lx}"
    d.mkdir()
    cd = lx * (h_mm / 1000.0) ** 2
    (d / "booth.yaml").write_text(BOOTH.format(name=json.dumps(name), rho=rho, h_mm=h_mm, spd=spd, cd=cd))
    return d


def _checks(lc, source="model"):
    return {c.id: c for c in lc.checks if c.source == source}


def test_uniformity_of_a_point_source_over_a_plane_is_the_cos3_law(tmp_path):
    from lbscene.engine.conformance import run_conformance

    h_mm, lx = 600.0, 1500.0
    d = _booth(tmp_path, rho=0.0, h_mm=h_mm, lx=lx)
    res = run_conformance(d, grid=(7, 5))
    m = res.lightings[0].model
    # the grid: 7 × 5 points spanning the 600 × 400 mm platform edge to edge
    X, Y = np.meshgrid(np.linspace(-300, 300, 7), np.linspace(-200, 200, 5))
    cos = h_mm / np.sqrt(h_mm ** 2 + X ** 2 + Y ** 2)
    E = lx * cos ** 3                                    # I/h² · cos³θ
    assert m.illuminance_at_sample_lx == pytest.approx(lx, rel=1e-6)
    np.testing.assert_allclose(np.sort(m.grid_lx), np.sort(E.ravel()), rtol=1e-6)
    assert m.uniformity == pytest.approx(E.min() / E.mean(), rel=1e-6)
    assert m.uniformity_min_to_max == pytest.approx(E.min() / E.max(), rel=1e-6)
    assert res.area.source == "platform" and res.area.size_mm == (600.0, 400.0)


def test_a_booth_that_meets_iso_3664_p1(tmp_path):
    from lbscene.engine.conformance import run_conformance

    lc = run_conformance(_booth(tmp_path)).lightings[0]
    ch = _checks(lc)
    assert lc.verdict == "pass"
    for k in ("illuminance", "uniformity", "chromaticity", "colour_rendering", "special_indices", "surround"):
        assert ch[k].verdict == "pass", (k, ch[k])
    assert ch["illuminance"].value == pytest.approx(2000.0, rel=1e-6)
    assert ch["chromaticity"].value == pytest.approx(0.0, abs=2e-4)      # the light is D50
    assert ch["surround"].value == pytest.approx(0.30, abs=1e-3)         # a flat 30 % grey: Y = 0.30
    for k in ("metamerism_visible", "metamerism_uv", "uv_content"):
        assert ch[k].verdict == "not_applicable" and ch[k].note
    # the light is D50 (colour-science's table covers 300-830 nm): its UV content is D50's
    assert ch["uv_content"].value == pytest.approx(1.0, abs=2e-3) and ch["uv_content"].unit == "× D50"


def test_a_booth_that_fails_iso_3664_p1(tmp_path):
    import colour

    from lbscene.engine.conformance import run_conformance

    lc = run_conformance(_booth(tmp_path, spd="A", rho=0.8, lx=1000.0)).lightings[0]
    ch = _checks(lc)
    assert lc.verdict == "fail"
    assert ch["illuminance"].verdict == "fail" and ch["illuminance"].value == pytest.approx(1000.0, rel=1e-6)
    assert ch["surround"].verdict == "fail" and ch["surround"].value == pytest.approx(0.80, abs=1e-3)
    # illuminant A against D50 in u'10 v'10, by colour-science directly
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmfs = colour.MSDS_CMFS["CIE 1964 10 Degree Standard Observer"]
        uv = [colour.xy_to_Luv_uv(colour.XYZ_to_xy(colour.sd_to_XYZ(colour.SDS_ILLUMINANTS[n], cmfs)))
              for n in ("A", "D50")]
    assert ch["chromaticity"].verdict == "fail"
    assert ch["chromaticity"].value == pytest.approx(float(np.hypot(*(uv[0] - uv[1]))), abs=5e-4)
    assert ch["colour_rendering"].verdict == "pass"        # A renders colours as a Planckian radiator


def _measurements(tmp_path, booth, h_mm=2000.0, lx=2000.0):
    import colour

    m = tmp_path / "meas"
    m.mkdir()
    pts = [(x, y) for x in (-300, -150, 0, 150, 300) for y in (-200, 0, 200)]
    E = [lx * (h_mm / np.sqrt(h_mm ** 2 + x * x + y * y)) ** 3 for x, y in pts]
    (m / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(f"{x},{y},{e:.4f}\n"
                                                                       for (x, y), e in zip(pts, E)))
    sd = colour.SDS_ILLUMINANTS["D50"]
    wl = np.arange(380, 781, 5)
    L = 0.99 * np.interp(wl, sd.wavelengths, sd.values) * 0.01 / np.pi
    (m / "tile.csv").write_text("wavelength_nm,radiance\n" + "".join(f"{w},{v:.6g}\n" for w, v in zip(wl, L)))
    (m / "set.yaml").write_text(f"version: 1\nkind: measurement_set\nname: by hand\nbooth: {booth}\nlighting: P1\n"
                                "illuminance:\n  - path: grid.csv\nwhite_tile:\n  radiance: {type: csv, path: tile.csv}\n"
                                "  reflectance: {type: constant, value: 0.99}\n")
    return m / "set.yaml", E


def test_measurements_are_judged_side_by_side(tmp_path):
    from lbscene.engine.conformance import run_conformance

    booth = _booth(tmp_path)
    mset, E = _measurements(tmp_path, booth)
    res = run_conformance(booth, measurements=mset)
    lc = res.lightings[0]
    meas = lc.measured
    assert meas is not None and res.measured_lighting == "P1"
    assert meas.illuminance_at_sample_lx == pytest.approx(2000.0, rel=1e-5)
    assert meas.uniformity == pytest.approx(min(E) / np.mean(E), rel=1e-5)
    assert meas.colorimetry.cct_K == pytest.approx(5003, abs=3)           # CIE D50
    mc = _checks(lc, "measured")
    assert mc["illuminance"].verdict == "pass" and mc["chromaticity"].verdict == "pass"
    j = res.to_json()["lightings"][0]
    assert j["measured"]["illuminance_at_sample_lx"] == pytest.approx(2000.0, rel=1e-5)
    assert {c["source"] for c in j["checks"]} == {"model", "measured"}


# --------------------------------------------------------------------------- command line

def test_cli_text_json_and_report(tmp_path, run_cli):
    booth = _booth(tmp_path, name="[red]T[/red] <b>&", spd="A", lx=1000.0)
    rep = tmp_path / "r.html"
    code, out, err = run_cli("conformance", booth, "--report", rep)
    assert code == 0, err                      # a failing check is a report, not an error
    assert "[red]T[/red] <b>&" in out          # the user's text is printed as written (escaped markup)
    assert "fail" in out
    html = rep.read_text()
    assert "&lt;b&gt;&amp;" in html and "<b>&" not in html
    assert "<script" not in html.lower() and "data:image/png;base64," in html
    assert "src='http" not in html and 'src="http' not in html
    code, out, err = run_cli("conformance", booth, "--format", "json", "--lighting", "P1")
    assert code == 0, err
    j = json.loads(out)
    lc = j["lightings"][0]
    assert lc["verdict"] == "fail" and lc["standard"] == "ISO_3664_P1"
    assert set(lc["model"]) >= {"illuminance_at_sample_lx", "uniformity", "uniformity_min_to_max", "colorimetry"}
    assert set(lc["model"]["colorimetry"]) >= {"xy", "uv_prime", "uv_prime_10deg", "cct_K", "duv", "cri_ra",
                                               "cri_r", "cie2017_rf", "tm30_rf", "tm30_rg"}
    assert {c["verdict"] for c in lc["checks"]} <= {"pass", "fail", "not_applicable"}
    assert set(lc["checks"][0]) == {"id", "title", "source", "verdict", "value", "unit", "requirement",
                                    "reference", "note"}


def test_cli_errors_are_located_and_pinned(tmp_path, run_cli):
    booth = _booth(tmp_path)
    code, _, err = run_cli("conformance", booth, "--lighting", "D65")
    assert code == 2
    assert (f"{booth}/booth.yaml: error LB202: --lighting: booth 'point booth' has no lighting configuration "
            "'D65' (got 'D65'; expected one of P1)") in err
    code, _, err = run_cli("conformance", booth, "--report", tmp_path / "r.txt")
    assert code == 2 and "error LB500: --report must name an .html file" in err
    mine = tmp_path / "mine.html"
    mine.write_text("my notes")
    code, _, err = run_cli("conformance", booth, "--report", mine)
    assert code == 2 and "LB611" in err and mine.read_text() == "my notes"


def test_api_arguments_are_checked(tmp_path):
    import lbscene

    booth = _booth(tmp_path)
    with pytest.raises(TypeError):
        lbscene.conformance(booth, lightings="P1")
    with pytest.raises(TypeError):
        lbscene.conformance(booth, grid="13x9")
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.conformance(booth, grid=(1, 9))
    assert ei.value.diagnostics[0].code == "LB500"
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.conformance(tmp_path / "nowhere")
    assert ei.value.diagnostics[0].code == "LB010"


@pytest.mark.slow
def test_the_shipped_iso_booth(run_cli):
    code, out, err = run_cli("conformance", "iso3664-p1-d50", "--format", "json")
    assert code == 0, err
    j = json.loads(out)
    p1 = {c["id"]: c for c in j["lightings"][0]["checks"]}
    assert p1["illuminance"]["verdict"] == "pass" and p1["chromaticity"]["verdict"] == "pass"
    assert p1["colour_rendering"]["verdict"] == "pass" and p1["surround"]["verdict"] == "pass"
