"""The declarative render graph: structure, determinism, build integration, views."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
TUBE_BOOTH = HERE / "data" / "tube-booth"


@pytest.fixture(scope="module")
def tube_ir():
    from lbscene.engine.scene.compile import compile_booth

    return compile_booth(TUBE_BOOTH)


@pytest.fixture(scope="module")
def graph(tube_ir):
    from lbscene.runtimes.graph import build_render_graph

    return build_render_graph(tube_ir, "D65")


def test_graph_is_plain_json_and_deterministic(tube_ir, graph):
    from lbscene.runtimes.graph import GRAPH_FORMAT, GRAPH_VERSION, build_render_graph

    assert graph["format"] == GRAPH_FORMAT and graph["version"] == GRAPH_VERSION
    assert graph["ir_hash"] == tube_ir.content_hash and graph["lighting"] == "D65"
    assert json.loads(json.dumps(graph)) == graph
    assert json.dumps(build_render_graph(tube_ir, "D65"), sort_keys=True) == json.dumps(graph, sort_keys=True)


def test_every_reference_in_the_graph_resolves(graph):
    from lbscene.runtimes.graph import SHADER_DIR

    textures = graph["resources"]["textures"]
    meshes = graph["resources"]["meshes"]
    names = {p["name"] for p in graph["passes"]}
    for sched in graph["schedules"].values():
        assert set(sched) <= names
    assert graph["default_schedule"] in graph["schedules"]
    for p in graph["passes"]:
        for target in p["outputs"]["color"]:
            assert textures[target]["size"] == "viewport"
        assert len(p["outputs"]["color"]) <= graph["requires"]["max_draw_buffers"] <= 4
        for item in p.get("draws", [p]):
            for stage in ("vertex", "fragment"):
                assert (SHADER_DIR / item["program"][stage]).is_file()
            for tex in item.get("textures", {}).values():
                assert tex in textures, tex
            for binding in list(item.get("uniforms", {}).values()) + list(item.get("defines", {}).values()):
                assert isinstance(binding, dict) or binding in graph["values"], binding
            if "mesh" in item:
                assert item["mesh"] in meshes


def test_spectral_blocks_cover_the_bands(graph):
    bands = [b for k in range(4) for b in graph["resources"]["textures"][f"spectral_radiance_{k}"]["bands"]]
    assert bands == list(range(16)) and graph["bands"]["blocks"] == 4
    assert graph["bands"]["labels"][0] == "390-410nm" and graph["bands"]["labels"][-1] == "690-710nm"
    assert graph["resources"]["textures"]["spectral_radiance_0"]["format"] == "rgba32f"


def test_views_realise_the_declared_geometries(graph):
    # independent expectation from the booth's construction: viewing angle = 60° − rotation
    views = {v["name"]: v for v in graph["views"]}
    assert list(views) == ["45as-15", "45as0", "45as15", "45as45"]
    for name, v in views.items():
        ill, asp = 45.0, float(name.split("as")[1])
        assert v["platform_rotation_deg"] == pytest.approx(60.0 - (ill - asp))
        r = v["realised"]
        assert r["illumination_deg"] == pytest.approx(45.0, abs=1e-3)
        assert r["aspecular_deg"] == pytest.approx(asp, abs=1e-3)


def test_rotation_is_solved_when_not_declared(tube_ir):
    from lbscene.runtimes.graph import build_render_graph

    geoms = tuple(g.model_copy(update={"platform_rotation_deg": None}) for g in tube_ir.geometries)
    solved = build_render_graph(tube_ir.model_copy(update={"geometries": geoms}), "D65")
    for v in solved["views"]:
        asp = float(v["name"].split("as")[1])
        assert v["rotation_source"] == "solved"
        assert v["platform_rotation_deg"] == pytest.approx(60.0 - (45.0 - asp), abs=1e-3)


def test_emitters_carry_absolute_band_intensity(tube_ir, graph):
    (e,) = graph["scene"]["emitters"]
    lamp = tube_ir.lamps[0]
    assert e["kind"] == "tube" and e["rotates_with_platform"] is True
    np.testing.assert_allclose(e["intensity_bands_W_sr_nm"], tube_ir.grid.integrate(lamp.peak_intensity_1nm),
                               rtol=1e-9)
    assert e["half_length_mm"] == pytest.approx(150.0) and e["half_width_mm"] == pytest.approx(10.0)
    assert e["profile"] == [1.0] * 64           # no angular_profile effect: isotropic


def test_materials_use_the_lighting_projection(tube_ir, graph):
    rows = {m["id"]: m for m in graph["scene"]["materials"]}
    for mid, m in tube_ir.materials.items():
        expected = m.reflectance_bands_by_lighting.get("D65") or m.reflectance.bands
        np.testing.assert_allclose(rows[mid]["reflectance_bands"], expected, rtol=1e-9)


def test_build_writes_a_render_graph_per_lighting(tmp_path):
    from lbscene.engine.scene.build import build_booth
    from lbscene.runtimes.graph import load_render_graph

    res = build_booth(REPO / "tests" / "data" / "minimal-booth", tmp_path / "b")
    assert "lbscene.runtimes.graph" not in res.skipped_writers
    path = tmp_path / "b" / "lighting" / "A" / "render_graph.json"
    g = load_render_graph(path)
    assert g["ir_hash"] == res.ir_hash and g["ir"] == "../../scene.ir.json"
    assert (path.parent / g["ir"]).resolve() == (tmp_path / "b" / "scene.ir.json").resolve()
    assert "lighting/A/render_graph.json" in res.files
    first = path.read_bytes()
    build_booth(REPO / "tests" / "data" / "minimal-booth", tmp_path / "b")
    assert path.read_bytes() == first             # byte-identical rebuild


def test_load_render_graph_rejects_other_files(tmp_path):
    from lbscene.runtimes.graph import load_render_graph

    p = tmp_path / "x.json"
    p.write_text(json.dumps({"format": "something else", "version": 1}))
    with pytest.raises(ValueError, match="lbscene.render_graph"):
        load_render_graph(p)


def test_shader_files_are_glsl_es_300():
    from lbscene.runtimes.graph import shader_sources

    sources = shader_sources()
    assert {"surface.vert", "fullscreen.vert", "booth.frag", "sample.frag", "spectral_to_xyz.frag",
            "display.frag", "dither.frag", "resolve.frag", "background.frag", "lib_spectral.glsl",
            "lib_display.glsl", "lib_dither.glsl"} <= set(sources)
    for name, src in sources.items():
        if name.endswith(".glsl"):
            # chunks go after the stage file's version line
            assert not any(line.lstrip().startswith("#version") for line in src.splitlines()), name
        else:
            assert src.startswith("#version 300 es\n"), name
        # desktop-only or GLSL ES 1.00 constructs that WebGL2 would reject
        for bad in ("gl_FragColor", "texture2D(", "#version 330", "#extension", "layout(binding"):
            assert bad not in src, (name, bad)


def test_every_program_names_existing_chunks(graph):
    from lbscene.runtimes.graph import SHADER_DIR, compose_shader

    for p in graph["passes"]:
        for item in p.get("draws", [p]):
            prog = item["program"]
            for chunk in prog.get("include", []) + prog.get("vertex_include", []):
                assert chunk.endswith(".glsl") and (SHADER_DIR / chunk).is_file(), chunk
            src = compose_shader((SHADER_DIR / prog["fragment"]).read_text(), [("A", 1)],
                                 prog.get("include", []))
            assert src.startswith("#version 300 es\n#define A 1\n")
            assert sum(line.lstrip().startswith("#version") for line in src.splitlines()) == 1


def test_schedules():
    from lbscene.runtimes.graph import SCHEDULES

    assert SCHEDULES["analysis"] == ["surfaces", "spectral_to_xyz", "display", "dither"]
    assert SCHEDULES["deferred"] == ["surfaces", "resolve"]
    assert SCHEDULES["realtime"] == ["shade_display"]


@pytest.mark.parametrize("projection", ["equirect", "cube"])
def test_environment_irradiance_of_a_uniform_sky(projection):
    """Uniform radiance L from every direction gives the irradiance π·L on any plane."""
    from lbscene.bakers.products import cube_directions, equirect_directions
    from lbscene.runtimes.bake import environment_irradiance

    shape = (64, 128) if projection == "equirect" else (32, 6 * 32)
    data = np.ones(shape + (2,)) * np.array([0.5, 2.0])
    for normal in ([0, 0, 1], [0, -1, 1], [1, 2, -3]):
        e = environment_irradiance(data, projection, (0, 1, 0), (0, 0, 1), normal)
        np.testing.assert_allclose(e, np.pi * np.array([0.5, 2.0]), rtol=0.01)
    # only the upper hemisphere lit: a horizontal plane facing up sees all of it, one facing
    # down none of it
    dirs = (equirect_directions(128) if projection == "equirect" else cube_directions(32))
    upper = np.where(dirs[..., 2:3] > 0, data, 0.0)
    np.testing.assert_allclose(environment_irradiance(upper, projection, (0, 1, 0), (0, 0, 1), [0, 0, 1]),
                               np.pi * np.array([0.5, 2.0]), rtol=0.01)
    np.testing.assert_allclose(environment_irradiance(upper, projection, (0, 1, 0), (0, 0, 1), [0, 0, -1]),
                               0.0, atol=1e-9)
