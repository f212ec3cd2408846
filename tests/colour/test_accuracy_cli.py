"""``lbscene accuracy``: rows, exit codes, plot written atomically, located user errors."""

import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MINIMAL = REPO / "tests" / "data" / "minimal-booth"
SRGB = REPO / "displays" / "srgb-reference.yaml"


def test_json_rows_for_cie_lightings_and_a_booth(run_cli, tmp_path):
    plot = tmp_path / "out" / "acc.png"
    code, out, err = run_cli("accuracy", "--booth", MINIMAL, "--display", SRGB,
                             "--format", "json", "--plot", plot)
    assert code == 0, err
    rows = json.loads(out)
    labels = [r["lighting"] for r in rows]
    for name in ("CIE D65", "CIE A", "CIE F2", "CIE F7", "CIE F11", "TL84 (Philips TL-84, measured)"):
        assert name in labels
    assert any(lab.endswith(": A") for lab in labels)          # the booth's configuration
    for r in rows:
        assert r["band_mean_dE00"] <= 0.1 and r["band_max_dE00"] <= 0.3
        assert r["box_max_dE00"] > r["band_max_dE00"]
        assert r["display"].startswith("sRGB")
        assert r["roundtrip_max_dE00"] < 1e-6
        assert r["roundtrip_dithered_max_dE00"] < r["roundtrip_8bit_max_dE00"]
        assert isinstance(r["out_of_gamut_count"], int)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # no temporary left behind; the ledger records that lbscene wrote the plot
    assert sorted(p.name for p in plot.parent.iterdir()) == [".lbscene-outputs.json", "acc.png"]


def test_text_report(run_cli):
    code, out, err = run_cli("accuracy", "--no-cie", "--booth", MINIMAL, "--display", SRGB)
    assert code == 0, err
    assert "Band weighting vs 1 nm reference" in out and "Display round trip" in out
    assert "ColorChecker N Ohta" in out


def test_missing_display_is_a_located_user_error(run_cli, tmp_path):
    code, out, err = run_cli("accuracy", "--no-cie", "--booth", MINIMAL,
                             "--display", tmp_path / "none.yaml")
    assert code == 2
    assert "LB010" in err


def test_plot_must_be_png(run_cli, tmp_path):
    code, out, err = run_cli("accuracy", "--no-cie", "--booth", MINIMAL, "--plot", tmp_path / "a.jpg")
    assert code == 2 and "LB500" in err


def test_bad_display_file_exits_2(run_cli, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(SRGB.read_text().replace("white_luminance_cd_m2: 80", "white_luminance_cd_m2: -1"))
    code, out, err = run_cli("accuracy", "--no-cie", "--booth", MINIMAL, "--display", bad)
    assert code == 2 and "LB103" in err and "bad.yaml:" in err
