// lbscene web viewer: UI, camera and test mode around LbsceneGraph.GraphExecutor.
//
// Everything it draws comes from window.LBSCENE_DATA (lbscene-data.js): one render graph per
// lighting, the shader files, and per lighting × view × sample × display the meshes, data
// textures and binding values that `lbscene render` computes in Python.  Per frame it only
// computes the camera (the rule of runtimes/scene.py: look_at + OpenGL perspective) and the
// sample's tilt (binding `sample.model`).
//
// The page is a full-screen app: the canvas fills the viewport at any size and follows it when
// the window turns or resizes (render size = viewport × device pixel ratio, at most 2, and at most
// the export's pixel count); the controls float over it and fold away (remembered for the browser
// session); a horizontal drag on the view (finger, pen or mouse: pointer events) tilts the sample,
// a double tap levels it.
//
// URL parameters (all optional): lighting, view, sample, display (names or indices), tilt
// (degrees), size (WxH: a fixed render size instead of the viewport's), scale (render size as a
// fraction of the viewport's CSS size), shot=1 (canvas only, at the page origin), bench=N
// (render N frames and report their times), report=PATH (POST a JSON report there: frame times
// and the canvas's pixels), test=1 (start the session's test mode).
(function () {
  'use strict';
  const D = window.LBSCENE_DATA;
  const params = new URLSearchParams(location.search);
  const $ = (id) => document.getElementById(id);

  // ------------------------------------------------------------------ data
  const blobCache = {};
  function blob(ref) {
    if (!blobCache[ref.blob]) {
      const bin = atob(D.blobs[ref.blob]);
      const bytes = new Uint8Array(bin.length);
      for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
      blobCache[ref.blob] = bytes.buffer;
    }
    const buf = blobCache[ref.blob];
    return ref.dtype === 'uint32' ? new Uint32Array(buf) : new Float32Array(buf);
  }
  function texture(ex, name, ref) {   // (H, W, 4) float32
    ex.setTexture(name, blob(ref), ref.shape[1], ref.shape[0]);
  }

  // ------------------------------------------------------------------ small linear algebra
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]); return [a[0] / l, a[1] / l, a[2] / l]; };
  function matmul(a, b) {   // 4×4 row-major arrays of rows
    const m = [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]];
    for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) for (let k = 0; k < 4; k++) m[i][j] += a[i][k] * b[k][j];
    return m;
  }
  function lookAt(eye, target, up) {
    const f = norm(sub(target, eye));
    if (Math.abs(dot(f, up)) > 0.999) up = [0, 1, 0];
    const s = norm(cross(f, up));
    const u = cross(s, f);
    const m = [[s[0], s[1], s[2], 0], [u[0], u[1], u[2], 0], [-f[0], -f[1], -f[2], 0], [0, 0, 0, 1]];
    for (let i = 0; i < 3; i++) m[i][3] = -(m[i][0] * eye[0] + m[i][1] * eye[1] + m[i][2] * eye[2]);
    return m;
  }
  function perspective(fovyDeg, aspect, near, far) {
    const f = 1 / Math.tan(fovyDeg * Math.PI / 360);
    return [[f / aspect, 0, 0, 0], [0, f, 0, 0],
      [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]];
  }
  function rotation(axis, deg) {   // right-handed, Rodrigues (engine.light.geometry.rotation_matrix)
    const a = norm(axis), t = deg * Math.PI / 180, s = Math.sin(t), c = 1 - Math.cos(t);
    const k = [[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]];
    const r = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) {
      let kk = 0;
      for (let l = 0; l < 3; l++) kk += k[i][l] * k[l][j];
      r[i][j] += s * k[i][j] + c * kk;
    }
    return r;
  }
  const columnMajor = (m) => { const o = new Float32Array(16); for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) o[c * 4 + r] = m[r][c]; return o; };

  // ------------------------------------------------------------------ formatting
  // an angle as people write it: whole degrees when it is one, else one decimal (45°, 22.5°)
  const fmtDeg = (x) => (Number.isFinite(Number(x)) ? `${Number(Number(x).toFixed(1))}°` : '—');
  const TILT_MAX_DEG = 30;
  function clampTilt(t) { return Math.max(-TILT_MAX_DEG, Math.min(TILT_MAX_DEG, Math.round(t * 2) / 2)); }

  // ------------------------------------------------------------------ state
  const state = { lighting: 0, view: 0, sample: 0, display: 0, tilt: 0, size: (D.size_px || [1024, 768]).slice() };
  function pick(list, key, fallback) {
    const v = params.get(key);
    if (v === null) return fallback;
    const i = list.findIndex((x) => x.name === v);
    if (i >= 0) return i;
    const n = parseInt(v, 10);
    return Number.isInteger(n) && n >= 0 && n < list.length ? n : fallback;
  }
  const init = D.initial || {};
  state.lighting = pick(D.lightings, 'lighting', Math.max(0, D.lightings.findIndex((l) => l.name === init.lighting)));
  const views0 = D.lightings[state.lighting].views;
  state.view = pick(views0, 'view', Math.max(0, views0.findIndex((v) => v.name === init.view)));
  state.sample = pick(D.samples, 'sample', 0);
  state.display = pick(D.displays, 'display', 0);
  if (params.get('tilt')) state.tilt = clampTilt(parseFloat(params.get('tilt')) || 0);
  let fixedSize = null;
  if (params.get('size')) {
    const m = /^(\d+)x(\d+)$/.exec(params.get('size'));
    if (m) fixedSize = [parseInt(m[1], 10), parseInt(m[2], 10)];
  }
  const scaleParam = parseFloat(params.get('scale') || '');
  const maxPixels = state.size[0] * state.size[1];
  // the render size: fixed by ?size, else the viewport's (CSS px × ?scale, or × the device pixel
  // ratio up to 2, no more pixels than the export was made for), so the view keeps its aspect
  function viewportSize() {
    if (fixedSize) return fixedSize.slice();
    const w = Math.max(1, window.innerWidth), h = Math.max(1, window.innerHeight);
    let k = scaleParam > 0 ? scaleParam : Math.min(window.devicePixelRatio || 1, 2);
    if (!(scaleParam > 0)) k = Math.min(k, Math.sqrt(maxPixels / (w * h)));
    return [Math.max(16, Math.round(w * k)), Math.max(16, Math.round(h * k))];
  }
  state.size = viewportSize();
  const shot = params.get('shot') === '1';
  if (shot) document.body.classList.add('shot');

  // ------------------------------------------------------------------ GL
  const canvas = $('view');
  const gl = canvas.getContext('webgl2', { antialias: false, alpha: false, depth: false, preserveDrawingBuffer: true });
  if (!gl) { $('status').textContent = 'WebGL2 is not available in this browser.'; throw new Error('no WebGL2'); }
  const timer = gl.getExtension('EXT_disjoint_timer_query_webgl2');
  const dbg = gl.getExtension('WEBGL_debug_renderer_info');
  const glRenderer = dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  const executors = {};
  let uploaded = {};
  function executor() {
    const L = D.lightings[state.lighting];
    if (!executors[L.name]) {
      const ex = new LbsceneGraph.GraphExecutor(gl, L.graph, D.shaders, state.size);
      for (const [name, ref] of Object.entries(D.static_textures)) texture(ex, name, ref);
      texture(ex, 'materials', L.textures.materials);
      executors[L.name] = ex;
      uploaded[L.name] = {};
    }
    return executors[L.name];
  }

  function caseData() {
    const L = D.lightings[state.lighting];
    const V = L.views[state.view];
    return { L, V, S: V.samples[state.sample], disp: V.samples[state.sample].displays[state.display] };
  }

  function prepare() {
    const ex = executor();
    const { L, V, S, disp } = caseData();
    ex.resize(state.size);
    const up = uploaded[L.name];
    const meshKey = `${state.view}/${state.sample}`;
    if (up.mesh !== meshKey) {
      for (const [name, m] of Object.entries(S.meshes)) ex.setMesh(name, blob(m.vertices), blob(m.indices));
      for (const [name, ref] of Object.entries(S.textures)) texture(ex, name, ref);
      up.mesh = meshKey;
    }
    if (up.display !== state.display) {
      texture(ex, 'tone_lut', D.displays[state.display].textures.tone_lut);
      up.display = state.display;
    }
    Object.assign(ex.values, disp.values);
    const cam = V.camera;
    const [w, h] = state.size;
    const vp = matmul(perspective(cam.vertical_fov_deg, w / h, cam.near_mm, cam.far_mm), lookAt(cam.eye_mm, cam.target_mm, cam.up));
    ex.values['view.view_proj'] = columnMajor(vp);
    ex.values['view.eye_mm'] = new Float32Array(cam.eye_mm);
    // tilt: a rotation of the sample about its centre, about the platform's axis
    const c = cam.sample_centre_mm;
    const r = rotation(L.graph.scene.platform.axis, state.tilt);
    const m = [[r[0][0], r[0][1], r[0][2], 0], [r[1][0], r[1][1], r[1][2], 0], [r[2][0], r[2][1], r[2][2], 0], [0, 0, 0, 1]];
    for (let i = 0; i < 3; i++) m[i][3] = c[i] - (r[i][0] * c[0] + r[i][1] * c[1] + r[i][2] * c[2]);
    ex.values['sample.model'] = columnMajor(m);
    return ex;
  }

  // ------------------------------------------------------------------ frames
  const frameMs = [];
  let gpuMs = null;
  function render() {
    if (canvas.width !== state.size[0] || canvas.height !== state.size[1]) {
      canvas.width = state.size[0];
      canvas.height = state.size[1];
    }
    const ex = prepare();
    let q = null;
    if (timer) { q = gl.createQuery(); gl.beginQuery(timer.TIME_ELAPSED_EXT, q); }
    const t0 = performance.now();
    ex.run('realtime');
    if (q) gl.endQuery(timer.TIME_ELAPSED_EXT);
    ex.present('display_rgba8');
    ex.sync('display_rgba8');
    const dt = performance.now() - t0;
    frameMs.push(dt);
    if (frameMs.length > 60) frameMs.shift();
    if (q) pollQuery(q);
    showStatus();
    return dt;
  }
  function pollQuery(q) {
    const check = () => {
      if (!gl.getQueryParameter(q, gl.QUERY_RESULT_AVAILABLE)) { requestAnimationFrame(check); return; }
      if (!gl.getParameter(timer.GPU_DISJOINT_EXT)) gpuMs = gl.getQueryParameter(q, gl.QUERY_RESULT) / 1e6;
      gl.deleteQuery(q);
    };
    requestAnimationFrame(check);
  }
  function median(a) { const s = a.slice().sort((x, y) => x - y); return s.length ? s[(s.length - 1) >> 1] : NaN; }
  function showStatus() {
    const { L, V, S, disp } = caseData();
    const r = V.realised || {};
    $('frame').textContent = `frame ${frameMs[frameMs.length - 1].toFixed(1)} ms (median of ${frameMs.length}: ${median(frameMs).toFixed(1)} ms` +
      (gpuMs !== null ? `, GPU ${gpuMs.toFixed(1)} ms` : '') + `) · ${state.size[0]}×${state.size[1]} · ${glRenderer}`;
    $('status').textContent = `${D.booth} · ${L.name} (${L.diffuse} diffuse) · ${V.name}: illumination ${fmtDeg(r.illumination_deg)}, ` +
      `viewing ${fmtDeg(r.viewing_deg)}, aspecular ${fmtDeg(r.aspecular_deg)}` +
      (state.tilt ? `, tilt ${fmtDeg(state.tilt)}` : '') + ` · sample ${D.samples[state.sample].name} · ` +
      `${disp.sample_illuminance_lx.toFixed(0)} lx · display ${D.displays[state.display].name}`;
  }

  // ------------------------------------------------------------------ controls
  function fill(sel, items, selected) {
    sel.innerHTML = '';
    items.forEach((it, i) => { const o = document.createElement('option'); o.value = i; o.textContent = it.name; sel.appendChild(o); });
    sel.value = selected;
  }
  function syncControls() {
    fill($('lighting'), D.lightings, state.lighting);
    fill($('viewsel'), D.lightings[state.lighting].views, state.view);
    fill($('sample'), D.samples, state.sample);
    fill($('display'), D.displays, state.display);
    $('tilt').value = state.tilt;
    $('tiltval').textContent = fmtDeg(state.tilt);
  }
  function onChange(key, el, parse) {
    el.addEventListener('input', () => { state[key] = parse(el.value); if (key === 'lighting') state.view = Math.min(state.view, D.lightings[state.lighting].views.length - 1); syncControls(); render(); });
  }
  onChange('lighting', $('lighting'), Number);
  onChange('view', $('viewsel'), Number);
  onChange('sample', $('sample'), Number);
  onChange('display', $('display'), Number);
  onChange('tilt', $('tilt'), (v) => clampTilt(parseFloat(v)));
  $('prev').addEventListener('click', () => { const n = D.lightings[state.lighting].views.length; state.view = (state.view + n - 1) % n; syncControls(); render(); });
  $('next').addEventListener('click', () => { const n = D.lightings[state.lighting].views.length; state.view = (state.view + 1) % n; syncControls(); render(); });
  let running = false;
  // fold the controls away (the view alone); remembered for this browser session
  const FOLD_KEY = 'lbscene.viewer.folded';
  function setFolded(folded) {
    document.body.classList.toggle('folded', folded);
    $('fold').textContent = folded ? 'Controls' : 'Hide controls';
    $('fold').setAttribute('aria-expanded', String(!folded));
    try { sessionStorage.setItem(FOLD_KEY, folded ? '1' : '0'); } catch (e) { /* storage refused: not remembered */ }
  }
  let folded0 = false;
  try { folded0 = sessionStorage.getItem(FOLD_KEY) === '1'; } catch (e) { /* storage refused */ }
  setFolded(folded0);
  $('fold').addEventListener('click', () => setFolded(!document.body.classList.contains('folded')));

  // touch, pen and mouse on the view: a horizontal drag tilts the sample (the width of the view
  // is the whole tilt range), a double tap levels it; the page itself never pans (touch-action)
  const drag = { id: null, x0: 0, tilt0: 0, moved: false, lastTap: 0 };
  let pending = false;
  function renderSoon() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; render(); });
  }
  canvas.addEventListener('pointerdown', (e) => {
    if (T.on || drag.id !== null) return;
    drag.id = e.pointerId; drag.x0 = e.clientX; drag.tilt0 = state.tilt; drag.moved = false;
    try { canvas.setPointerCapture(e.pointerId); } catch (err) { /* synthetic pointer */ }
    e.preventDefault();
  });
  canvas.addEventListener('pointermove', (e) => {
    if (e.pointerId !== drag.id) return;
    const dx = e.clientX - drag.x0;
    if (Math.abs(dx) < 4 && !drag.moved) return;
    drag.moved = true;
    const t = clampTilt(drag.tilt0 + dx / Math.max(1, canvas.clientWidth) * 2 * TILT_MAX_DEG);
    if (t !== state.tilt) { state.tilt = t; syncControls(); renderSoon(); }
  });
  const endDrag = (e) => {
    if (e.pointerId !== drag.id) return;
    drag.id = null;
    if (drag.moved || e.type === 'pointercancel') return;
    const now = performance.now();
    if (now - drag.lastTap < 350) { drag.lastTap = 0; state.tilt = 0; syncControls(); renderSoon(); } else drag.lastTap = now;
  };
  canvas.addEventListener('pointerup', endDrag);
  canvas.addEventListener('pointercancel', endDrag);

  // the viewport turned or resized: render at its new size
  window.addEventListener('resize', () => {
    const s = viewportSize();
    if (s[0] !== state.size[0] || s[1] !== state.size[1]) { state.size = s; renderSoon(); }
  });

  $('animate').addEventListener('change', (e) => {
    running = e.target.checked;
    const loop = () => { if (!running) return; render(); requestAnimationFrame(loop); };
    if (running) requestAnimationFrame(loop);
  });

  // ------------------------------------------------------------------ test mode (visual session)
  const T = { on: false, observer: null, trials: [], i: 0, shownAt: 0, responses: [] };
  function startTest() {
    const ses = D.session;
    T.observer = $('observer').value;
    T.trials = ses.trials.filter((t) => t.observer === T.observer);
    T.i = 0;
    T.responses = [];
    T.on = true;
    document.body.classList.add('testing');
    present();
  }
  function present() {
    if (T.i >= T.trials.length) { finishTest(); return; }
    const t = T.trials[T.i];
    state.lighting = D.lightings.findIndex((l) => l.name === t.lighting);
    state.view = D.lightings[state.lighting].views.findIndex((v) => v.name === t.geometry);
    state.sample = D.samples.findIndex((s) => s.name === t.sample);
    state.tilt = 0;
    syncControls();
    render();
    const what = { colour: 'the colour', sparkle: 'the sparkle (glints under the lamp)',
      graininess: 'the graininess (light/dark pattern)' }[t.attribute || 'colour'];
    $('trial').textContent = `${T.observer}: case ${T.i + 1} of ${T.trials.length} (repeat ${t.repeat}): judge ${what}`;
    T.shownAt = performance.now();
  }
  function answer(score) {
    const t = T.trials[T.i];
    T.responses.push(Object.assign({}, t, { score, response_time_ms: Math.round(performance.now() - T.shownAt),
      display: D.displays[state.display].name }));
    T.i += 1;
    present();
  }
  const CSV_COLUMNS = ['session', 'observer', 'repeat', 'order', 'lighting', 'geometry', 'sample', 'display', 'score', 'response_time_ms', 'attribute'];
  function resultsCsv(rows) {
    const q = (v) => { const s = String(v); return /[",\n]/.test(s) ? `"${s.replace(/"/g, '""')}"` : s; };
    return CSV_COLUMNS.join(',') + '\n' + rows.map((r) => CSV_COLUMNS.map((c) => q(c === 'session' ? D.session.name : r[c])).join(',')).join('\n') + '\n';
  }
  function download(name, text, type) {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([text], { type }));
    a.download = name;
    a.textContent = name;
    $('downloads').appendChild(a);
    $('downloads').appendChild(document.createTextNode(' '));
  }
  function finishTest() {
    T.on = false;
    document.body.classList.remove('testing');
    const ses = D.session;
    const json = JSON.stringify({ format: 'lbscene.visual_results', version: 1, session: ses.name, session_hash: ses.hash,
      response: ses.response, observer: T.observer, responses: T.responses }, null, 1);
    const stem = `${ses.name.replace(/[^A-Za-z0-9_-]+/g, '_')}-${T.observer}`;
    download(`${stem}.csv`, resultsCsv(T.responses), 'text/csv');
    download(`${stem}.json`, json, 'application/json');
    $('trial').textContent = `${T.observer}: done, ${T.responses.length} answers: download the results below`;
    if (params.get('report')) post({ kind: 'visual_results', results: JSON.parse(json), csv: resultsCsv(T.responses) });
  }
  function setupTest() {
    const ses = D.session;
    if (!ses) { $('testpanel').hidden = true; return; }
    fill($('observer'), ses.observers.map((o) => ({ name: o.id })), 0);
    $('observer').querySelectorAll('option').forEach((o) => { o.value = o.textContent; });
    $('observer').value = ses.observers[0].id;   // after the options carry the ids as values
    $('starttest').addEventListener('click', startTest);
    const box = $('scores');
    box.innerHTML = '';
    const r = ses.response;
    if (r.type === 'grey_scale') {
      for (let v = r.min; v <= r.max + 1e-9; v += r.step) {
        const b = document.createElement('button');
        b.textContent = Number(v.toFixed(2)).toString();
        b.type = 'button';
        b.dataset.score = v;
        b.addEventListener('click', () => T.on && answer(Number(v.toFixed(2))));
        box.appendChild(b);
      }
    } else {
      const inp = document.createElement('input');
      inp.type = 'number'; inp.min = 0; inp.step = 0.1; inp.id = 'deinput';
      const b = document.createElement('button');
      b.textContent = 'ΔE estimate';
      b.addEventListener('click', () => { if (T.on && inp.value !== '') { answer(parseFloat(inp.value)); inp.value = ''; } });
      box.appendChild(inp); box.appendChild(b);
    }
    $('scale').textContent = r.type === 'grey_scale' ? `grey scale ${r.min}–${r.max} (5: no visible difference)` : 'estimated ΔE';
  }

  // ------------------------------------------------------------------ automation (tests, benchmarks)
  function post(obj) {
    return fetch(params.get('report'), { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(obj) });
  }
  function b64(bytes) {
    let s = '';
    for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    return btoa(s);
  }
  async function automate() {
    const n = parseInt(params.get('bench') || '0', 10);
    const times = [];
    for (let i = 0; i < n; i++) { times.push(render()); await new Promise((r) => setTimeout(r, 0)); }
    if (params.get('test') === '1' && D.session) {
      // scripted observer for the browser test: answers each case with the score given in ?answers
      const ans = (params.get('answers') || '').split(',').filter((x) => x !== '').map(Number);
      $('observer').value = params.get('observer') || D.session.observers[0].id;
      startTest();
      let k = 0;
      while (T.on) { answer(ans.length ? ans[k % ans.length] : 3); k += 1; }
      return;
    }
    if (!params.get('report')) return;
    const ex = executors[D.lightings[state.lighting].name];
    const px = ex.readRGBA8('display_rgba8');
    await post({ kind: 'frame', width: state.size[0], height: state.size[1], rgba8_base64: b64(px),
      frame_ms: times, first_frame_ms: firstMs, gl_renderer: glRenderer, timer_query: !!timer, gpu_ms: gpuMs,
      lighting: D.lightings[state.lighting].name, view: D.lightings[state.lighting].views[state.view].name,
      sample: D.samples[state.sample].name, display: D.displays[state.display].name, user_agent: navigator.userAgent });
  }

  syncControls();
  setupTest();
  let firstMs = null;
  try {
    firstMs = render();   // includes shader compilation and uploads
    document.body.dataset.ready = '1';
    automate().catch((e) => { $('status').textContent = String(e); if (params.get('report')) post({ kind: 'error', error: String(e) }); });
  } catch (e) {
    $('status').textContent = `error: ${e.message}`;
    if (params.get('report')) post({ kind: 'error', error: String(e && e.stack || e) });
    throw e;
  }
})();
