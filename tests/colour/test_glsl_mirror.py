"""The runtime's GLSL ES 3.00 display library (``runtimes/shaders/lib_display.glsl``, composed as
the runtime composes it) and the exported uniforms reproduce ``DisplayModel.xyz_to_drive``
(Mesa llvmpipe through moderngl's EGL backend)."""

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.gl

REPO = Path(__file__).resolve().parents[2]

VERT = """#version 300 es
precision highp float;
const vec2 P[3] = vec2[3](vec2(-1.0, -1.0), vec2(3.0, -1.0), vec2(-1.0, 3.0));
void main() { gl_Position = vec4(P[gl_VertexID], 0.0, 1.0); }
"""

FRAG = """#version 300 es
precision highp float;
uniform sampler2D u_xyz;
layout(location = 0) out vec4 o_drive;
void main() {
    o_drive = display_drive(texelFetch(u_xyz, ivec2(gl_FragCoord.xy), 0).xyz);
}
"""


@pytest.fixture(scope="module")
def ctx():
    moderngl = pytest.importorskip("moderngl")
    try:
        c = moderngl.create_standalone_context(backend="egl")
    except Exception as exc:  # no EGL on this machine
        pytest.skip(f"no OpenGL context: {exc}")
    yield c
    c.release()


def _run(ctx, model, xyz):
    from lbscene.runtimes.graph import LIB_DISPLAY, compose_shader

    u = model.glsl_uniforms()
    defines = [("TONE_KIND", u["tone_kind"]), ("GAMUT_MAPPING", u["gamut_mapping"])]
    prog = ctx.program(vertex_shader=VERT, fragment_shader=compose_shader(FRAG, defines, [LIB_DISPLAY]))
    n = len(xyz)
    tex = ctx.texture((n, 1), 4, np.c_[xyz, np.ones(n)].astype("f4").tobytes(), dtype="f4")
    tex.filter = (ctx.NEAREST, ctx.NEAREST)
    lut = np.array(u["tone_lut"] or [[0.0] * 3, [1.0] * 3], "f4")
    lut_tex = ctx.texture((len(lut), 1), 4, np.c_[lut, np.zeros(len(lut))].astype("f4").tobytes(),
                          dtype="f4")
    lut_tex.filter = (ctx.NEAREST, ctx.NEAREST)
    tex.use(0)
    lut_tex.use(1)
    from lbscene.runtimes.scene import _gl, display_linear_matrix

    # exposure 1, adaptation: identity
    linear = display_linear_matrix(1.0, np.eye(3), u["xyz_offset"], u["xyz_to_rgb"], u["inv_y_span"])
    values = {"u_xyz": 0, "u_tone_lut": 1, "u_display_linear": tuple(_gl(linear)),
              "u_tone_params": [tuple(p) for p in u["tone_params"]],
              "u_tone_lut_size": max(u["tone_lut_size"], 2)}
    for k, v in values.items():
        if k in prog:
            prog[k].value = v
    fbo = ctx.simple_framebuffer((n, 1), components=4, dtype="f4")
    fbo.use()
    ctx.vertex_array(prog, []).render(mode=ctx.TRIANGLES, vertices=3)
    out = np.frombuffer(fbo.read(components=4, dtype="f4"), "f4").reshape(n, 4)
    for o in (fbo, tex, lut_tex, prog):
        o.release()
    return out[:, :3].astype(float), out[:, 3].astype(float)


def _models():
    from lbscene.engine.colour.display_model import DisplayModel, load_display
    from lbscene.schemas.display import Display

    x = np.linspace(0, 1, 33)
    lut_doc = Display.model_validate({
        "version": 1, "kind": "display", "name": "lut", "provenance": {"status": "synthetic"},
        "primaries_xy": {"red": [0.68, 0.32], "green": [0.265, 0.69], "blue": [0.15, 0.06]},
        "white_xy": [0.3127, 0.3290], "white_luminance_cd_m2": 300, "black_luminance_cd_m2": 0.3,
        "tone_response": {c: {"type": "lut", "drive": x.tolist(), "output": (x ** g).tolist()}
                          for c, g in (("red", 2.1), ("green", 2.2), ("blue", 2.3))}})
    return [load_display(REPO / "displays/srgb-reference.yaml"),
            load_display(REPO / "displays/tablet-wide-gamut.yaml"),
            load_display(REPO / "displays/srgb-reference.yaml", mapping="clip"),
            DisplayModel(lut_doc)]


@pytest.mark.parametrize("index", range(4), ids=["srgb", "tablet-gog", "srgb-clip", "lut"])
def test_shader_mirrors_python(ctx, index):
    model = _models()[index]
    rng = np.random.default_rng(index)
    inside = model.drive_to_xyz(rng.uniform(0.1, 1.0, (200, 3)))
    # out of gamut: push colours away from the white, some below the floor or above white
    outside = model.xyz_white_seen * 0.4 + (inside - model.xyz_white_seen * 0.4) * 2.5
    xyz = np.vstack([inside, outside])
    drive, rep = model.xyz_to_drive(xyz, report=True)
    assert 0 < rep.count < len(xyz)
    gl_drive, gl_excess = _run(ctx, model, xyz)
    tol = 2e-3 if index == 3 else 2e-4     # LUT: the shader's 4096-entry resampled inverse
    np.testing.assert_allclose(gl_drive, drive, atol=tol)
    np.testing.assert_allclose(gl_excess, rep.excess, atol=1e-4 * max(1.0, rep.max_excess))
    # what is seen from the shader's drive values agrees with the model's own
    from lbscene.engine.colour.accuracy import delta_e00, xyz_to_lab

    white = model.xyz_white_seen
    de = delta_e00(xyz_to_lab(model.drive_to_xyz(gl_drive), white),
                   xyz_to_lab(model.drive_to_xyz(drive), white))
    assert de.max() < (0.05 if index == 3 else 0.01)
