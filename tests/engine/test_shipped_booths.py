"""Every booth folder under booths/ validates clean and builds for every lighting configuration.

Adding a booth is adding a folder: this test picks it up with no code change.
"""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BOOTH_DIRS = sorted(p.parent for p in (REPO / "booths").glob("*/booth.yaml"))


def test_the_three_seed_booths_are_shipped():
    names = {p.name for p in BOOTH_DIRS}
    assert {"xrite-spectralight-qc", "byk-byko-spectra-effect", "iso3664-p1-d50"} <= names


@pytest.mark.parametrize("booth", BOOTH_DIRS, ids=[p.name for p in BOOTH_DIRS])
def test_booth_validates_clean(booth):
    from lbscene.engine.files.diagnostics import Severity
    from lbscene.engine.conformance.validate import validate_paths

    report = validate_paths([booth])
    problems = [d.format() for d in report.diagnostics if d.severity is not Severity.INFO]
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("booth", BOOTH_DIRS, ids=[p.name for p in BOOTH_DIRS])
def test_booth_builds_every_lighting(booth, tmp_path):
    from pxr import Usd, UsdLux

    from lbscene.engine.scene.build import build_booth
    from lbscene.engine.scene.usd_stage import register_schema

    res = build_booth(booth, tmp_path / "out")
    assert res.lightings
    register_schema()
    for name in res.lightings:
        stage = Usd.Stage.Open(str(tmp_path / "out" / "lighting" / name / "scene.usda"))
        lights = [p for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI) or p.IsA(UsdLux.BoundableLightBase)]
        assert lights, f"{name}: no UsdLux lights"
        visible = [p for p in lights if p.GetAttribute("visibility").Get() != "invisible"]
        assert visible, f"{name}: no lamp on"
        for p in lights:
            assert p.HasAPI("LbsceneSpectralAPI") and len(p.GetAttribute("lbscene:spectral:bandValues").Get()) == 16
