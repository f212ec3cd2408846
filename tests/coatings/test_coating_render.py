"""Effect coatings in the realtime runtime (moderngl, GLSL ES 3.00; the WebGL2 viewer runs the same
shader files).

* the flop path: the sample's centre pixel against an independent quadrature of the fitted BRDF
  over the tube lamp's surface (numpy; the lamp's radiance and position from the render graph);
* the texture preserves the flop's mean (sparkle and graininess are fluctuations around it);
* stable at rest (a stable hash of sample-space cells: two frames are identical), and the glints
  follow the sample when it tilts (they change with the half vector, the cells do not);
* the display's highlight roll-off: identity below its knee, monotone, the chosen maximum at
  white, a coloured glint less bleached than by clipping.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.gl

REPO = Path(__file__).resolve().parents[2]
TUBE = REPO / "tests" / "runtimes" / "data" / "tube-booth"
COARSE = REPO / "examples" / "render" / "sample-coating-coarse-silver.yaml"
SIZE = (256, 192)
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


@pytest.fixture(scope="module")
def ctx():
    from lbscene.runtimes.executor import GLUnavailableError, create_context

    try:
        c = create_context()
    except GLUnavailableError as exc:
        pytest.skip(str(exc))
    yield c
    c.release()


@pytest.fixture(scope="module")
def setup():
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.files.load import load_document
    from lbscene.runtimes.graph import build_render_graph
    from lbscene.runtimes.scene import SampleSpec
    from lbscene.schemas.sample import Sample

    ir = compile_booth(TUBE)
    sp = SampleSpec.from_document(load_document(COARSE, Sample))
    return ir, build_render_graph(ir, "D65"), sp


def _renderer(setup, ctx, sample):
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.render import Renderer

    ir, graph, _ = setup
    return Renderer(ir, graph, sample, srgb_display(), ctx=ctx)


def _no_texture(sample, gloss=None):
    upd = {"coating": sample.coating.model_copy(update={"texture": None})}
    if gloss is not None:
        upd["gloss_GU"] = gloss
    return dataclasses.replace(sample, **upd)


def _quadrature_Y(r, view, sample):
    """Y of the sample centre by a dense quadrature of the flop BRDF over the tube's lateral surface
    (a Lambertian cylinder of radiance I_ref / 2rℓ), in the view's XYZ weights."""
    from lbscene.engine.coatings.flop import MeasuredGeometry
    from lbscene.engine.coatings.model import _angles
    from lbscene.runtimes.colour_bridge import project_reflectance
    from lbscene.runtimes.graph import rotation_matrix

    ir, g = r.scene.ir, r.scene.graph
    vi = r.scene.view(view)
    vs = r.scene._view_spec(view)
    R = rotation_matrix(vs["rotation"]["axis"], vs["rotation"]["angle_deg"])
    o = np.asarray(vs["rotation"]["origin_mm"], float)
    P = vi.sample_centre_mm
    N = vi.sample_normal / np.linalg.norm(vi.sample_normal)
    eye = np.asarray(vs["camera"]["position_mm"], float)
    V = (eye - P) / np.linalg.norm(eye - P)
    u = np.array([1.0, 0.0, 0.0]) @ R.T
    u = (u - N * (u @ N)) / np.linalg.norm(u - N * (u @ N))
    frame = np.stack([u, np.cross(N, u), N])
    meas = [MeasuredGeometry(*_angles(lbl, a), project_reflectance(r1, vi.sample_irradiance_1nm, ir.grid))
            for a, lbl, r1 in sample.geometries]
    flop = r.scene.coating_appearance().flop.refit_linear(meas)
    e = g["scene"]["emitters"][0]
    c = (np.asarray(e["centre_mm"]) - o) @ R.T + o
    ax = np.asarray(e["axis"], float) @ R.T
    hl, rad = e["half_length_mm"], e["half_width_mm"]
    L = np.asarray(e["intensity_bands_W_sr_nm"]) / (4 * hl * rad * 1e-6)
    na, nr = 800, 180
    t = ((np.arange(na) + 0.5) / na - 0.5) * 2 * hl
    a = (np.arange(nr) + 0.5) / nr * 2 * np.pi
    b1 = np.cross(ax, [0.0, 0.0, 1.0])
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(ax, b1)
    T, A = np.meshgrid(t, a, indexing="ij")
    ns = np.cos(A)[..., None] * b1 + np.sin(A)[..., None] * b2
    pts = c + T[..., None] * ax + rad * ns
    d = P - pts
    dist = np.linalg.norm(d, axis=-1)
    ldir = -d / dist[..., None]
    domega = (2 * hl / na) * (2 * np.pi * rad / nr) * np.clip((d * ns).sum(-1) / dist, 0, None) / dist ** 2
    w = (np.clip(ldir @ N, 0, None) * domega).reshape(-1)
    lo = (ldir @ frame.T).reshape(-1, 3)
    fr = flop.brdf(lo, np.broadcast_to(frame @ V, lo.shape))
    out = (fr * w[:, None]).sum(0) * L
    W = np.asarray(vi.values["view.xyz_weights"]).reshape(16, 3)[:ir.grid.count]
    return float(out @ W[:, 1])


@pytest.mark.parametrize("view", ["45as-15", "45as15", "45as45"])
def test_flop_against_a_quadrature_over_the_tube(setup, ctx, view):
    sample = _no_texture(setup[2], gloss=0.0)
    r = _renderer(setup, ctx, sample)
    f = r.render(view, SIZE, want_xyz=True)
    x, y = (int(v) for v in r.sample_pixel(view, SIZE))
    Y = float(f.xyz[y - 2:y + 3, x - 2:x + 3, 1].mean())
    # measured: within 2.5 % (8 points along the tube in the shader)
    assert Y == pytest.approx(_quadrature_Y(r, view, sample), rel=0.04)


def test_texture_keeps_the_mean_and_is_stable(setup, ctx):
    sp = setup[2]
    textured = _renderer(setup, ctx, sp)
    flop = _renderer(setup, ctx, _no_texture(sp))
    for view in ("45as15", "45as45"):
        a = textured.render(view, SIZE, want_xyz=True)
        b = flop.render(view, SIZE, want_xyz=True)
        x, y = (int(v) for v in textured.sample_pixel(view, SIZE))
        pa = a.xyz[y - 20:y + 20, x - 30:x + 30, 1]
        pb = b.xyz[y - 20:y + 20, x - 30:x + 30, 1]
        assert pa.mean() == pytest.approx(pb.mean(), rel=0.05)
        assert (pa - pb).std() > 0.05 * pb.mean()      # there is a texture
    one = textured.render("45as45", SIZE)
    two = textured.render("45as45", SIZE)
    assert np.array_equal(one.rgba8, two.rgba8)       # no shimmer at rest


def test_glints_stay_on_the_sample_when_it_tilts(setup, ctx):
    """A tilt of 0.05° moves no cell and barely moves the half vector: the glint pattern is the
    same; 3° changes which flakes glint (the half vector crosses slope bins)."""
    from lbscene.runtimes.scene import _gl

    r = _renderer(setup, ctx, setup[2])

    def frame(tilt_deg):
        r.prepare("45as45", SIZE)
        c = r.scene.view("45as45").sample_centre_mm
        t = np.radians(tilt_deg)
        m = np.eye(4)
        m[:3, :3] = [[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]]
        m[:3, 3] = c - m[:3, :3] @ c
        r.executor.values["sample.model"] = _gl(m)
        r.executor.run(None, "analysis")
        return r.executor.read("xyz")[..., 1]

    base, small, large = frame(0.0), frame(0.05), frame(3.0)
    x, y = (int(v) for v in r.sample_pixel("45as45", SIZE))
    win = (slice(y - 15, y + 15), slice(x - 25, x + 25))

    def corr(a, b):
        a, b = a[win].ravel(), b[win].ravel()
        return float(np.corrcoef(a, b)[0, 1])

    assert corr(base, small) > 0.9
    assert corr(base, large) < 0.5


def _rolloff_drive(ctx, xyz, rolloff):
    from lbscene.engine.colour.display_model import load_display
    from lbscene.runtimes.coating import HIGHLIGHT_KNEE, HIGHLIGHT_MAX
    from lbscene.runtimes.graph import LIB_DISPLAY, compose_shader

    model = load_display(REPO / "displays" / "srgb-reference.yaml")
    u = model.glsl_uniforms()
    vert = ("#version 300 es\nprecision highp float;\nconst vec2 P[3] = vec2[3](vec2(-1.0, -1.0), "
            "vec2(3.0, -1.0), vec2(-1.0, 3.0));\nvoid main() { gl_Position = vec4(P[gl_VertexID], 0.0, 1.0); }\n")
    frag = ("#version 300 es\nprecision highp float;\nuniform sampler2D u_xyz;\nlayout(location = 0) out vec4 o;\n"
            "void main() { o = display_drive(texelFetch(u_xyz, ivec2(gl_FragCoord.xy), 0).xyz); }\n")
    defines = [("TONE_KIND", u["tone_kind"]), ("GAMUT_MAPPING", u["gamut_mapping"]),
               ("HIGHLIGHT_ROLLOFF", int(rolloff))]
    prog = ctx.program(vertex_shader=vert, fragment_shader=compose_shader(frag, defines, [LIB_DISPLAY]))
    n = len(xyz)
    tex = ctx.texture((n, 1), 4, np.c_[xyz, np.ones(n)].astype("f4").tobytes(), dtype="f4")
    tex.filter = (ctx.NEAREST, ctx.NEAREST)
    tex.use(0)
    from lbscene.runtimes.scene import _gl, display_linear_matrix

    linear = display_linear_matrix(1.0, np.eye(3), u["xyz_offset"], u["xyz_to_rgb"], u["inv_y_span"])
    vals = {"u_xyz": 0, "u_display_linear": tuple(_gl(linear)),
            "u_tone_params": [tuple(p) for p in u["tone_params"]], "u_tone_lut_size": 2,
            "u_highlight_knee": HIGHLIGHT_KNEE, "u_highlight_max": HIGHLIGHT_MAX}
    for k, v in vals.items():
        if k in prog:
            prog[k].value = v
    fbo = ctx.simple_framebuffer((n, 1), components=4, dtype="f4")
    fbo.use()
    ctx.vertex_array(prog, []).render(mode=ctx.TRIANGLES, vertices=3)
    out = np.frombuffer(fbo.read(components=4, dtype="f4"), "f4").reshape(n, 4)[:, :3].astype(float)
    for o in (fbo, tex, prog):
        o.release()
    return model, out


def test_highlight_rolloff(ctx):
    from lbscene.runtimes.coating import HIGHLIGHT_KNEE, HIGHLIGHT_MAX

    from lbscene.engine.colour.display_model import load_display

    model = load_display(REPO / "displays" / "srgb-reference.yaml")
    y = np.linspace(0.05, 12.0, 240)
    grey = model.xyz_white_seen[None, :] * y[:, None]
    _, on = _rolloff_drive(ctx, grey, True)
    _, off = _rolloff_drive(ctx, grey, False)
    below = y < HIGHLIGHT_KNEE * 0.98
    np.testing.assert_allclose(on[below], off[below], atol=2e-4)            # identity below the knee
    g = on[:, 1]
    assert np.all(np.diff(g[y <= 0.8 * HIGHLIGHT_MAX]) > 0)                   # brighter glints stay brighter
    assert np.all(np.diff(g) >= -1e-6)
    assert g[np.argmin(np.abs(y - HIGHLIGHT_MAX))] == pytest.approx(1.0, abs=2e-3)   # y_max → white
    assert np.all(off[y > 1.05, 1] >= 0.999)                                 # without it: all white
    # a coloured glint keeps its hue: drive ratios of a bright orange as for the same colour dimmer
    orange = model.drive_to_xyz(np.array([[0.9, 0.5, 0.2]]))[0]
    _, d = _rolloff_drive(ctx, np.stack([orange * 3.0]), True)
    _, d_off = _rolloff_drive(ctx, np.stack([orange * 3.0]), False)
    # (near white luminance the gamut has no room for saturation: the roll-off keeps what it can)
    assert d_off[0, 2] > 0.99               # without the roll-off: the display's white
    assert d[0, 2] < d_off[0, 2] - 0.03 and d[0, 0] > d[0, 1] > d[0, 2]
