// lbscene render-graph executor for WebGL2: the browser twin of runtimes/executor.py.
//
// It runs a render graph (the JSON that runtimes/graph.py writes) with the graph's own
// GLSL ES 3.00 sources, composed exactly like graph.compose_shader: the stage file's
// #version line, one "#define NAME value" line per define (sorted by name), the include
// chunks, then the rest of the file.  Like the Python executor it knows nothing about
// booths: bindings are resolved from a flat `values` object, data textures and meshes
// are handed to it.  Float textures are read with texelFetch only; rendering to RGBA32F
// targets (analysis and deferred schedules) needs EXT_color_buffer_float, the realtime
// schedule does not.
(function (global) {
  'use strict';

  const VERTEX_FLOATS = 25;

  function composeShader(source, defines, include, read) {
    const head = defines.map(([k, v]) => `#define ${k} ${v}\n`).join('');
    const libs = include.map((name) =>
      `// ---- include ${name}\n${read(name).replace(/\s+$/, '')}\n// ---- end ${name}\n`).join('');
    if (!head && !libs) return source;
    const i = source.indexOf('\n');
    const first = i < 0 ? source : source.slice(0, i);
    const rest = i < 0 ? '' : source.slice(i + 1);
    return `${first}\n${head}${libs}${rest}`;
  }

  const DEPTH_FUNCS = { '<': 'LESS', '<=': 'LEQUAL', '>': 'GREATER', '>=': 'GEQUAL', '==': 'EQUAL', always: 'ALWAYS' };

  class GraphExecutor {
    // gl: a WebGL2 context; graph: the render graph; shaders: file name -> source.
    constructor(gl, graph, shaders, size) {
      this.gl = gl;
      this.graph = graph;
      this.shaders = shaders;
      this.values = {};
      this.data = {};        // name -> WebGLTexture (data textures)
      this.targets = {};     // name -> {tex, format}
      this.fbos = {};
      this.meshes = {};      // name -> {vbo, ibo, count}
      this.vaos = {};
      this.programs = {};
      this.emptyVao = gl.createVertexArray();
      this.floatTargets = !!gl.getExtension('EXT_color_buffer_float');
      this.size = [0, 0];
      this.resize(size);
    }

    source(name) {
      const s = this.shaders[name];
      if (s === undefined) throw new Error(`shader ${name} missing from the export`);
      return s;
    }

    _compile(type, src, label) {
      const gl = this.gl;
      const sh = gl.createShader(type);
      gl.shaderSource(sh, src);
      gl.compileShader(sh);
      if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
        throw new Error(`${label}: ${gl.getShaderInfoLog(sh)}`);
      }
      return sh;
    }

    _value(binding) {
      if (binding !== null && typeof binding === 'object') return binding.value;
      if (!(binding in this.values)) throw new Error(`render graph binding ${binding} has no value`);
      return this.values[binding];
    }

    programFor(item) {
      const defines = Object.entries(item.defines || {}).map(([k, b]) =>
        [k, (b !== null && typeof b === 'object') ? b.value : Math.trunc(Number(this._value(b)))]);
      defines.sort((a, b) => (a[0] < b[0] ? -1 : a[0] > b[0] ? 1 : 0));
      const p = item.program;
      const inc = p.include || [], vinc = p.vertex_include || [];
      const key = JSON.stringify([p.vertex, p.fragment, defines, inc, vinc]);
      if (!this.programs[key]) {
        const gl = this.gl;
        const read = (n) => this.source(n);
        const vs = composeShader(this.source(p.vertex), defines, vinc, read);
        const fs = composeShader(this.source(p.fragment), defines, inc, read);
        const prog = gl.createProgram();
        gl.attachShader(prog, this._compile(gl.VERTEX_SHADER, vs, p.vertex));
        gl.attachShader(prog, this._compile(gl.FRAGMENT_SHADER, fs, p.fragment));
        gl.linkProgram(prog);
        if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
          throw new Error(`link ${p.vertex}+${p.fragment}: ${gl.getProgramInfoLog(prog)}`);
        }
        const uniforms = {};
        const n = gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS);
        for (let i = 0; i < n; i++) {
          const info = gl.getActiveUniform(prog, i);
          const name = info.name.replace(/\[0\]$/, '');
          uniforms[name] = { type: info.type, size: info.size, loc: gl.getUniformLocation(prog, info.name) };
        }
        this.programs[key] = { key, prog, uniforms };
      }
      return this.programs[key];
    }

    resize(size) {
      const gl = this.gl;
      const w = size[0] | 0, h = size[1] | 0;
      if (w === this.size[0] && h === this.size[1]) return;
      for (const t of Object.values(this.targets)) gl.deleteTexture(t.tex);
      for (const f of Object.values(this.fbos)) gl.deleteFramebuffer(f);
      this.targets = {};
      this.fbos = {};
      for (const [name, spec] of Object.entries(this.graph.resources.textures)) {
        if (spec.size !== 'viewport') continue;
        const tex = gl.createTexture();
        gl.bindTexture(gl.TEXTURE_2D, tex);
        if (spec.format === 'depth24') {
          gl.texStorage2D(gl.TEXTURE_2D, 1, gl.DEPTH_COMPONENT24, w, h);
        } else if (spec.format === 'rgba8') {
          gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA8, w, h);
        } else if (spec.format === 'rgba16f') {
          gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA16F, w, h);
        } else {
          gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, w, h);
        }
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
        this.targets[name] = { tex, format: spec.format };
      }
      this.size = [w, h];
    }

    // The framebuffer of a pass (made on first use, so that a schedule that needs no float
    // targets runs without EXT_color_buffer_float).
    _fbo(pass) {
      const gl = this.gl;
      if (!this.fbos[pass.name]) {
        const fb = gl.createFramebuffer();
        gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
        const colour = pass.outputs.color;
        colour.forEach((n, i) => gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i,
          gl.TEXTURE_2D, this.targets[n].tex, 0));
        if (pass.outputs.depth) {
          gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.TEXTURE_2D,
            this.targets[pass.outputs.depth].tex, 0);
        }
        gl.drawBuffers(colour.map((_, i) => gl.COLOR_ATTACHMENT0 + i));
        const st = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
        if (st !== gl.FRAMEBUFFER_COMPLETE) {
          throw new Error(`pass ${pass.name}: framebuffer incomplete (0x${st.toString(16)})` +
            (this.floatTargets ? '' : '; float render targets need EXT_color_buffer_float'));
        }
        this.fbos[pass.name] = fb;
      }
      return this.fbos[pass.name];
    }

    // A data texture from a Float32Array laid out (H, W, 4), row y = texelFetch(…, ivec2(x, y)).
    setTexture(name, array, width, height) {
      const gl = this.gl;
      let t = this.data[name];
      if (!t) {
        t = this.data[name] = gl.createTexture();
      }
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, height, 0, gl.RGBA, gl.FLOAT, array);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    }

    // Interleaved vertices (n × 25 float32, the graph's attribute order) and uint32 triangles.
    setMesh(name, vertices, indices) {
      const gl = this.gl;
      const old = this.meshes[name];
      if (old) {
        if (old.vbo) gl.deleteBuffer(old.vbo);
        if (old.ibo) gl.deleteBuffer(old.ibo);
        for (const k of Object.keys(this.vaos)) {
          if (k.startsWith(name + '|')) { gl.deleteVertexArray(this.vaos[k]); delete this.vaos[k]; }
        }
      }
      if (!indices.length) { this.meshes[name] = { vbo: null, ibo: null, count: 0 }; return; }
      const vbo = gl.createBuffer();
      gl.bindVertexArray(null);
      gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
      gl.bufferData(gl.ARRAY_BUFFER, vertices, gl.STATIC_DRAW);
      const ibo = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
      this.meshes[name] = { vbo, ibo, count: indices.length };
    }

    _vao(mesh, p) {
      const key = mesh + '|' + p.key;
      if (!this.vaos[key]) {
        const gl = this.gl;
        const m = this.meshes[mesh];
        const vao = gl.createVertexArray();
        gl.bindVertexArray(vao);
        gl.bindBuffer(gl.ARRAY_BUFFER, m.vbo);
        let offset = 0;
        for (const a of this.graph.resources.meshes[mesh].attributes) {
          const loc = gl.getAttribLocation(p.prog, a.name);
          if (loc >= 0) {
            gl.enableVertexAttribArray(loc);
            gl.vertexAttribPointer(loc, a.components, gl.FLOAT, false, VERTEX_FLOATS * 4, offset);
          }
          offset += 4 * a.components;
        }
        gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, m.ibo);
        gl.bindVertexArray(null);
        this.vaos[key] = vao;
      }
      return this.vaos[key];
    }

    _bind(p, uniforms, textures) {
      const gl = this.gl;
      gl.useProgram(p.prog);
      for (const [uname, binding] of Object.entries(uniforms || {})) {
        const u = p.uniforms[uname];
        if (!u) continue;
        const v = this._value(binding);
        const arr = Array.isArray(v) || ArrayBuffer.isView(v);
        switch (u.type) {
          case gl.FLOAT: arr ? gl.uniform1fv(u.loc, v) : gl.uniform1f(u.loc, v); break;
          case gl.FLOAT_VEC2: gl.uniform2fv(u.loc, v); break;
          case gl.FLOAT_VEC3: gl.uniform3fv(u.loc, v); break;
          case gl.FLOAT_VEC4: gl.uniform4fv(u.loc, v); break;
          case gl.FLOAT_MAT3: gl.uniformMatrix3fv(u.loc, false, v); break;
          case gl.FLOAT_MAT4: gl.uniformMatrix4fv(u.loc, false, v); break;
          case gl.FLOAT_MAT4x3: gl.uniformMatrix4x3fv(u.loc, false, v); break;
          case gl.FLOAT_MAT3x4: gl.uniformMatrix3x4fv(u.loc, false, v); break;
          case gl.INT: case gl.BOOL: arr ? gl.uniform1iv(u.loc, v) : gl.uniform1i(u.loc, Math.trunc(v)); break;
          default: throw new Error(`uniform ${uname}: unsupported type 0x${u.type.toString(16)}`);
        }
      }
      // texture units in the order the graph lists the samplers (as the Python executor)
      let unit = -1;
      for (const [uname, tex] of Object.entries(textures || {})) {
        unit += 1;
        const u = p.uniforms[uname];
        if (!u) continue;
        const t = this.data[tex] || (this.targets[tex] && this.targets[tex].tex);
        if (!t) throw new Error(`texture ${tex} has no data`);
        gl.activeTexture(gl.TEXTURE0 + unit);
        gl.bindTexture(gl.TEXTURE_2D, t);
        gl.uniform1i(u.loc, unit);
      }
    }

    schedule(name) {
      const byName = {};
      for (const p of this.graph.passes) byName[p.name] = p;
      const scheds = this.graph.schedules || { all: Object.keys(byName) };
      name = name || this.graph.default_schedule || Object.keys(scheds)[0];
      if (!scheds[name]) throw new Error(`render graph has no schedule ${name}`);
      return scheds[name].map((n) => byName[n]);
    }

    run(scheduleName) {
      const gl = this.gl;
      const [w, h] = this.size;
      for (const p of this.schedule(scheduleName)) {
        gl.bindFramebuffer(gl.FRAMEBUFFER, this._fbo(p));
        gl.viewport(0, 0, w, h);
        if (p.kind === 'raster') {
          const c = p.clear || {};
          const col = c.color || [0, 0, 0, 0];
          gl.depthMask(true);
          p.outputs.color.forEach((_, i) => gl.clearBufferfv(gl.COLOR, i, col));
          if (p.outputs.depth) gl.clearBufferfv(gl.DEPTH, 0, [c.depth === undefined ? 1.0 : c.depth]);
          gl.enable(gl.DEPTH_TEST);
          gl.frontFace(gl.CCW);
          for (const d of p.draws) {
            let mesh = null;
            if (!d.fullscreen) {
              mesh = this.meshes[d.mesh];
              if (!mesh || mesh.count === 0) continue;
            }
            const prog = this.programFor(d);
            if (d.cull_back_faces) { gl.enable(gl.CULL_FACE); gl.cullFace(gl.BACK); } else gl.disable(gl.CULL_FACE);
            gl.depthFunc(gl[DEPTH_FUNCS[d.depth_func || '<']]);
            gl.depthMask(d.depth_write === undefined ? true : !!d.depth_write);
            this._bind(prog, d.uniforms, d.textures);
            if (mesh === null) {
              gl.bindVertexArray(this.emptyVao);
              gl.drawArrays(gl.TRIANGLES, 0, 3);
            } else {
              gl.bindVertexArray(this._vao(d.mesh, prog));
              gl.drawElements(gl.TRIANGLES, mesh.count, gl.UNSIGNED_INT, 0);
            }
          }
          gl.bindVertexArray(null);
          gl.depthFunc(gl.LESS);
          gl.depthMask(true);
          gl.disable(gl.DEPTH_TEST);
          gl.disable(gl.CULL_FACE);
        } else {
          const prog = this.programFor(p);
          gl.disable(gl.DEPTH_TEST);
          gl.disable(gl.CULL_FACE);
          this._bind(prog, p.uniforms, p.textures);
          gl.bindVertexArray(this.emptyVao);
          gl.drawArrays(gl.TRIANGLES, 0, 3);
          gl.bindVertexArray(null);
        }
      }
    }

    // Copy an RGBA8 target to the canvas (same pixels: no filtering, no scaling).
    present(name) {
      const gl = this.gl;
      const [w, h] = this.size;
      const fb = this._readFbo(name);
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fb);
      gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, null);
      gl.blitFramebuffer(0, 0, w, h, 0, 0, w, h, gl.COLOR_BUFFER_BIT, gl.NEAREST);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    }

    _readFbo(name) {
      const gl = this.gl;
      const key = '#read:' + name;
      if (!this.fbos[key]) {
        const fb = gl.createFramebuffer();
        gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
        gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.targets[name].tex, 0);
        this.fbos[key] = fb;
      }
      return this.fbos[key];
    }

    // An RGBA8 target as bytes, top row first (like GraphExecutor.read in Python).
    readRGBA8(name) {
      const gl = this.gl;
      const [w, h] = this.size;
      gl.bindFramebuffer(gl.FRAMEBUFFER, this._readFbo(name));
      const raw = new Uint8Array(w * h * 4);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, raw);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      const out = new Uint8Array(w * h * 4);
      for (let y = 0; y < h; y++) out.set(raw.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
      return out;
    }

    // Wait for the GPU: a one-pixel read-back (gl.finish alone may return early).
    sync(name) {
      const gl = this.gl;
      gl.bindFramebuffer(gl.FRAMEBUFFER, this._readFbo(name));
      const px = new Uint8Array(4);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    }
  }

  global.LbsceneGraph = { GraphExecutor, composeShader, VERTEX_FLOATS };
})(typeof window !== 'undefined' ? window : globalThis);
