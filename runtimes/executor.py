"""
The moderngl executor of render graphs (headless EGL by default).

:class:`GraphExecutor` creates the graph's render targets, compiles its
programs from the GLSL ES 3.00 files in ``runtimes/shaders`` (composed with
their ``#define`` lines and ``include`` chunks by
:func:`~lbscene.runtimes.graph.compose_shader`), keeps the data textures and
meshes it is given, and runs the passes of a schedule in order.  It knows
nothing about booths: bindings are resolved from a flat ``values`` dict.
Raster draws may be ``fullscreen`` (one triangle, no vertex buffer) and set
``depth_func`` / ``depth_write`` (the realtime schedule's background).

Desktop/ES differences are handled here, never by editing shaders: a driver
that refuses ``#version 300 es`` in a desktop core context gets the same
source with the version line rewritten to ``#version 330 core`` (GLSL 3.30
accepts every construct the shaders use, precision qualifiers included).
Mesa llvmpipe (the CI and this machine) compiles ES 3.00 as it is.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .graph import SHADER_DIR, compose_shader

__all__ = ["GLUnavailableError", "create_context", "compile_program", "GraphExecutor", "PassTiming"]

ES_HEADER = "#version 300 es"
DESKTOP_HEADER = "#version 330 core"


class GLUnavailableError(RuntimeError):
    """No OpenGL context could be created (no EGL, no driver)."""


def create_context(device_index: int | None = None, backend: str = "egl"):
    """A standalone (headless) OpenGL 3.3+ context; ``device_index`` picks the EGL device."""
    import moderngl

    kw: dict[str, Any] = {"require": 330}
    if backend:
        kw["backend"] = backend
    if device_index is not None:
        kw["device_index"] = int(device_index)
    try:
        return moderngl.create_standalone_context(**kw)
    except Exception as exc:  # glcontext raises plain Exceptions
        raise GLUnavailableError(f"cannot create an OpenGL context ({backend or 'default'} backend"
                                 f"{'' if device_index is None else f', device {device_index}'}): {exc}")


def _desktop(src: str) -> str:
    return src.replace(ES_HEADER, DESKTOP_HEADER, 1)


def compile_program(ctx, vertex_src: str, fragment_src: str):
    """Compile a program as written (GLSL ES 3.00), falling back to desktop GLSL 3.30."""
    import moderngl

    try:
        return ctx.program(vertex_shader=vertex_src, fragment_shader=fragment_src)
    except moderngl.Error as exc:
        msg = str(exc).lower()
        if "version" not in msg and "300" not in msg:
            raise
        return ctx.program(vertex_shader=_desktop(vertex_src), fragment_shader=_desktop(fragment_src))


@dataclass
class PassTiming:
    name: str
    seconds: float


_FORMATS = {"rgba32f": (4, "f4"), "rgba16f": (4, "f2"), "rgba8": (4, "f1")}


class GraphExecutor:
    """Runs a render graph with moderngl.

    Parameters
    ----------
    ctx
        A moderngl context (see :func:`create_context`).
    graph
        The render graph dict.
    size
        Viewport ``(width, height)`` in pixels.
    """

    def __init__(self, ctx, graph: dict, size: tuple[int, int], shader_dir: Path = SHADER_DIR):
        import moderngl

        self.ctx = ctx
        self.graph = graph
        self.shader_dir = Path(shader_dir)
        self.size = (0, 0)
        self._programs: dict[tuple, Any] = {}
        self._sources: dict[str, str] = {}
        self.targets: dict[str, Any] = {}
        self.data: dict[str, Any] = {}
        self._meshes: dict[str, tuple[Any, Any, int]] = {}
        self._vaos: dict[tuple, Any] = {}
        self._fbos: dict[str, Any] = {}
        self.values: dict[str, Any] = {}
        self._empty_vao: dict[tuple, Any] = {}
        self._mgl = moderngl
        max_side = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 8192))
        self.max_size = min(max_side, int(ctx.info.get("GL_MAX_RENDERBUFFER_SIZE", max_side)))
        self.resize(size)

    # ------------------------------------------------------------------ resources
    def _read_shader(self, name: str) -> str:
        text = self._sources.get(name)
        if text is None:
            text = self._sources[name] = (self.shader_dir / name).read_text()
        return text

    def program(self, vert: str, frag: str, defines: tuple = (), include: tuple = (),
                vertex_include: tuple = ()):
        """The program of two shader files, composed by :func:`~lbscene.runtimes.graph.compose_shader`:
        ``#define`` lines after ``#version`` (both stages), then the ``include`` chunks (fragment
        stage) or ``vertex_include`` chunks (vertex stage)."""
        key = (vert, frag, defines, include, vertex_include)
        if key not in self._programs:
            vs = compose_shader(self._read_shader(vert), defines, vertex_include, self._read_shader)
            fs = compose_shader(self._read_shader(frag), defines, include, self._read_shader)
            self._programs[key] = compile_program(self.ctx, vs, fs)
        return self._programs[key]

    def _program_for(self, item: dict):
        defines = tuple(sorted((k, int(self._value(b)) if not isinstance(b, dict) else b["value"])
                               for k, b in item.get("defines", {}).items()))
        prog = item["program"]
        key = (prog["vertex"], prog["fragment"], defines, tuple(prog.get("include", ())),
               tuple(prog.get("vertex_include", ())))
        return key, self.program(*key)

    def resize(self, size: tuple[int, int]) -> None:
        size = (int(size[0]), int(size[1]))
        if size == self.size:
            return
        if max(size) > self.max_size:
            raise ValueError(f"viewport {size} exceeds the GL limit {self.max_size}")
        for t in self.targets.values():
            t.release()
        for f in self._fbos.values():
            f.release()
        self.targets, self._fbos = {}, {}
        for name, spec in self.graph["resources"]["textures"].items():
            if spec.get("size") != "viewport":
                continue
            if spec["format"] == "depth24":
                self.targets[name] = self.ctx.depth_texture(size)
            else:
                comps, dtype = _FORMATS[spec["format"]]
                t = self.ctx.texture(size, comps, dtype=dtype)
                t.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
                self.targets[name] = t
        for p in self.graph["passes"]:
            out = p["outputs"]
            colour = [self.targets[n] for n in out["color"]]
            depth = self.targets[out["depth"]] if out.get("depth") else None
            self._fbos[p["name"]] = self.ctx.framebuffer(color_attachments=colour,
                                                         depth_attachment=depth)
        self.size = size

    def set_texture(self, name: str, array: np.ndarray) -> None:
        """Upload a data texture (H, W, 4) float32; row y is fetched as texelFetch(…, ivec2(x, y))."""
        a = np.ascontiguousarray(array, dtype=np.float32)
        h, w, c = a.shape
        t = self.data.get(name)
        if t is None or t.size != (w, h) or t.components != c:
            if t is not None:
                t.release()
            t = self.ctx.texture((w, h), c, a.tobytes(), dtype="f4")
            t.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
            t.repeat_x = t.repeat_y = False
            self.data[name] = t
        else:
            t.write(a.tobytes())

    def set_mesh(self, name: str, vertices: np.ndarray, indices: np.ndarray) -> None:
        """Interleaved vertices (n, 25) float32 in the graph's attribute order; triangle indices."""
        old = self._meshes.pop(name, None)
        if old is not None:
            for b in old[:2]:
                if b is not None:
                    b.release()
            for k in [k for k in self._vaos if k[0] == name]:
                self._vaos.pop(k).release()
        if len(indices) == 0:
            self._meshes[name] = (None, None, 0)
            return
        vbo = self.ctx.buffer(np.ascontiguousarray(vertices, dtype=np.float32).tobytes())
        ibo = self.ctx.buffer(np.ascontiguousarray(indices, dtype=np.uint32).tobytes())
        self._meshes[name] = (vbo, ibo, len(indices))

    def _vao(self, mesh: str, prog_key: tuple):
        key = (mesh,) + prog_key
        if key not in self._vaos:
            vbo, ibo, _ = self._meshes[mesh]
            prog = self._programs[prog_key]
            attrs = self.graph["resources"]["meshes"][mesh]["attributes"]
            fmt, names = [], []
            for a in attrs:
                if a["name"] in prog:
                    fmt.append(f"{a['components']}f")
                    names.append(a["name"])
                else:
                    fmt.append(f"{4 * a['components']}x")
            self._vaos[key] = self.ctx.vertex_array(prog, [(vbo, " ".join(fmt), *names)],
                                                    index_buffer=ibo, index_element_size=4)
        return self._vaos[key]

    def _fullscreen_vao(self, key: tuple, prog):
        """A vertex array without buffers (fullscreen.vert builds its triangle from gl_VertexID)."""
        if key not in self._empty_vao:
            self._empty_vao[key] = self.ctx.vertex_array(prog, [])
        return self._empty_vao[key]

    # ------------------------------------------------------------------ bindings
    def _value(self, binding):
        if isinstance(binding, dict):
            return binding["value"]
        if binding not in self.values:
            raise KeyError(f"render graph binding {binding!r} has no value")
        return self.values[binding]

    def _bind(self, prog, uniforms: dict, textures: dict) -> None:
        for uname, binding in uniforms.items():
            if uname not in prog:
                continue
            v = self._value(binding)
            u = prog[uname]
            if isinstance(v, np.ndarray):
                dtype = np.int32 if np.issubdtype(v.dtype, np.integer) else np.float32
                u.write(np.ascontiguousarray(v, dtype=dtype).tobytes())
            elif isinstance(v, (bool, int, np.integer)):
                u.value = int(v)
            else:
                u.value = float(v)
        for unit, (uname, tex) in enumerate(textures.items()):
            if uname not in prog:
                continue
            t = self.data.get(tex)
            if t is None:
                t = self.targets.get(tex)
            if t is None:
                raise KeyError(f"texture {tex!r} has no data")
            t.use(unit)
            prog[uname].value = unit

    # ------------------------------------------------------------------ execution
    def schedule(self, name: str | None = None) -> list[dict]:
        """The passes of a schedule (default: the graph's default schedule), in order."""
        by_name = {p["name"]: p for p in self.graph["passes"]}
        scheds = self.graph.get("schedules") or {"all": list(by_name)}
        name = name or self.graph.get("default_schedule") or next(iter(scheds))
        if name not in scheds:
            raise KeyError(f"render graph has no schedule {name!r} (has {', '.join(scheds)})")
        return [by_name[n] for n in scheds[name]]

    def run(self, timings: list[PassTiming] | None = None, schedule: str | None = None) -> None:
        """Execute a schedule's passes; with ``timings``, finish after each pass and record its time."""
        ctx, mgl = self.ctx, self._mgl
        for p in self.schedule(schedule):
            t0 = time.perf_counter()
            fbo = self._fbos[p["name"]]
            fbo.use()
            if p["kind"] == "raster":
                c = p.get("clear", {})
                fbo.clear(*c.get("color", (0.0, 0.0, 0.0, 0.0)), depth=c.get("depth", 1.0))
                ctx.enable(mgl.DEPTH_TEST)
                ctx.front_face = "ccw"
                for d in p["draws"]:
                    if d.get("fullscreen"):
                        mesh = None
                    else:
                        mesh = self._meshes.get(d["mesh"])
                        if mesh is None or mesh[2] == 0:
                            continue
                    key, prog = self._program_for(d)
                    if d.get("cull_back_faces"):
                        ctx.enable(mgl.CULL_FACE)
                    else:
                        ctx.disable(mgl.CULL_FACE)
                    ctx.depth_func = d.get("depth_func", "<")
                    fbo.depth_mask = bool(d.get("depth_write", True))
                    self._bind(prog, d.get("uniforms", {}), d.get("textures", {}))
                    if mesh is None:
                        self._fullscreen_vao(key, prog).render(mgl.TRIANGLES, vertices=3)
                    else:
                        self._vao(d["mesh"], key).render(mgl.TRIANGLES)
                ctx.depth_func = "<"
                fbo.depth_mask = True
                ctx.disable(mgl.DEPTH_TEST | mgl.CULL_FACE)
            else:
                key, prog = self._program_for(p)
                ctx.disable(mgl.DEPTH_TEST | mgl.CULL_FACE)
                self._bind(prog, p.get("uniforms", {}), p.get("textures", {}))
                self._fullscreen_vao(key, prog).render(mgl.TRIANGLES, vertices=3)
            if timings is not None:
                ctx.finish()
                timings.append(PassTiming(p["name"], time.perf_counter() - t0))
        if timings is None:
            ctx.finish()

    def read(self, name: str) -> np.ndarray:
        """A render target as (H, W, C), top row first (uint8 for rgba8, float32 otherwise)."""
        t = self.targets[name]
        dtype = np.uint8 if t.dtype == "f1" else np.float32
        a = np.frombuffer(t.read(), dtype=dtype).reshape(self.size[1], self.size[0], t.components)
        return a[::-1].copy()

    def release(self) -> None:
        for group in (self._vaos, self._empty_vao):
            for v in group.values():
                v.release()
        for vbo, ibo, _ in self._meshes.values():
            for b in (vbo, ibo):
                if b is not None:
                    b.release()
        for group in (self._fbos, self.targets, self.data):
            for v in group.values():
                v.release()
        for p in self._programs.values():
            p.release()
        self._vaos, self._empty_vao, self._meshes, self._fbos = {}, {}, {}, {}
        self.targets, self.data, self._programs = {}, {}, {}
