// brdfpipe material explorer: blends pre-rendered images of measured materials
// live on the GPU at any point of a GPLVM latent space (Soler et al. 2018).
// No framework; data come from data/*.js (see brdfpipe/explorer/export.py).
'use strict';
(function () {
  const $ = (id) => document.getElementById(id);
  // The page's only way to put data on screen: elements built with DOM calls, strings added as text nodes
  // (never innerHTML), so a material, path or database name shows literally whatever it holds.
  function el(tag, props = {}, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(props)) {
      if (k === 'class') e.className = v;
      else if (k === 'style') e.style.cssText = v;
      else if (k.startsWith('data-')) e.dataset[k.slice(5)] = String(v);
      else e[k] = v;
    }
    for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(String(c)));
    return e;
  }
  function options(select, items) {  // items: [value, label]
    select.replaceChildren(...items.map(([value, label]) => el('option', { value: String(value) }, label)));
  }
  const api = { ready: false, error: null };
  window.explorer = api;

  function fail(msg) {
    api.error = msg;
    const box = $('error');
    box.textContent = msg;
    box.hidden = false;
  }

  // ---------------------------------------------------------------- data
  // Every data/*.js file assigns {crc32, json}: its payload as JSON text and the CRC-32 of that text
  // (brdfpipe.core.integrity.text_crc32). A file that did not load (missing, or truncated: it does not
  // parse) or whose text does not match its CRC-32 is refused, naming it, before anything is drawn.
  const RERUN = 'write the explorer folder again (rerun its rule: snakemake --forcerun write_explorer)';
  // CRC-32 (zlib's), a byte at a time (slicing by 8 over TextEncoder.encodeInto's bytes was not measurably
  // faster in headless Chromium on the shared 2-core machine, benches/bench_integrity.py).
  const CRC_TABLE = (() => {
    const t = new Uint32Array(256);
    for (let n = 0; n < 256; n++) {
      let c = n;
      for (let k = 0; k < 8; k++) c = c & 1 ? 0xEDB88320 ^ (c >>> 1) : c >>> 1;
      t[n] = c >>> 0;
    }
    return t;
  })();
  function crc32(text) {  // of an ASCII string: its bytes are its char codes
    const T = CRC_TABLE;
    let c = 0xFFFFFFFF;
    for (let i = 0; i < text.length; i++) c = T[(c ^ text.charCodeAt(i)) & 0xFF] ^ (c >>> 8);
    return 'crc32:' + ((c ^ 0xFFFFFFFF) >>> 0).toString(16).padStart(8, '0');
  }
  let crcMs = 0;
  function loadData() {
    const raw = window.BRDF_EXPLORER_DATA || {}, out = {};
    for (const key of ['model', 'layers', 'basis', 'refs']) {
      const file = `data/${key}.js`, rec = raw[key];
      if (!rec || typeof rec.json !== 'string' || typeof rec.crc32 !== 'string') {
        return `${file} did not load (missing, truncated or not an explorer data file); ${RERUN}.`;
      }
      const t0 = performance.now(), crc = crc32(rec.json);
      crcMs += performance.now() - t0;
      if (crc !== rec.crc32) {
        return `${file}: its payload does not match its recorded digest (damaged or edited); ${RERUN}.`;
      }
      try {
        out[key] = JSON.parse(rec.json);
      } catch (e) {
        return `${file}: its payload is not JSON (${e.message}); ${RERUN}.`;
      }
      raw[key] = null;  // the text is no longer needed
    }
    return out;
  }
  const DATA = loadData();
  if (typeof DATA === 'string') {
    fail(DATA);
    for (const id of ['controls', 'slices', 'path-controls']) $(id).hidden = true;
    document.querySelector('main').hidden = true;  // no black canvas: only the message
    return;
  }
  api.verifyMs = crcMs;  // the CRC-32 checks of the four data files
  function bytes(b64) {
    const bin = atob(b64);
    const out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }
  const f64 = (b64) => new Float64Array(bytes(b64).buffer);
  const u32 = (b64) => new Uint32Array(bytes(b64).buffer);

  const M = DATA.model.manifest;
  const N = M.n, W = M.width, H = M.height, NAMES = M.materials;
  const ALBEDO = f64(DATA.model.albedo);
  const MODELS = DATA.model.models.map((m) => {
    const hull = m.hull;
    return {
      q: m.q, ell: m.ell, mu: m.mu, space: m.space, linear: m.linear,
      X: f64(m.X), L: f64(m.chol),
      hull: hull && {
        tol: hull.tol, interval: hull.interval || null, polygon: hull.polygon || null,
        eq: hull.equations ? f64(hull.equations) : null, facets: hull.facets || 0,
      },
    };
  });
  const PATHS = M.paths;
  const PATH_W = DATA.model.path_weights.map(f64);

  // ---------------------------------------------------------------- the GPLVM in the page
  // b = K^-1 k with K = L L^T (L: the model's saved Cholesky factor), k_j =
  // exp(-|x_j - x|^2 / 2 l^2) (+ mu where x equals x_j exactly); w = b + (1 - sum b)/N.
  function kernelVector(m, x) {
    const q = m.q, k = new Float64Array(N), s = 2 * m.ell * m.ell;
    for (let j = 0; j < N; j++) {
      let d2 = 0, same = true;
      for (let a = 0; a < q; a++) {
        const d = m.X[j * q + a] - x[a];
        d2 += d * d;
        if (d !== 0) same = false;
      }
      k[j] = Math.exp(-d2 / s) + (same ? m.mu : 0);
    }
    return k;
  }
  function solveB(m, k) {
    const L = m.L, y = new Float64Array(N), b = new Float64Array(N);
    for (let i = 0; i < N; i++) {
      let s = k[i];
      const row = i * N;
      for (let j = 0; j < i; j++) s -= L[row + j] * y[j];
      y[i] = s / L[row + i];
    }
    for (let i = N - 1; i >= 0; i--) {
      let s = y[i];
      for (let j = i + 1; j < N; j++) s -= L[j * N + i] * b[j];
      b[i] = s / L[i * N + i];
    }
    return b;
  }
  function blendWeights(b) {
    let sum = 0;
    for (let i = 0; i < N; i++) sum += b[i];
    const w = new Float64Array(N), c = (1 - sum) / N;
    for (let i = 0; i < N; i++) w[i] = b[i] + c;
    return w;
  }
  function weightsAt(m, x) {
    const b = solveB(m, kernelVector(m, x));
    return { b, w: blendWeights(b) };
  }
  function hullContains(m, x) {
    const h = m.hull;
    if (!h) return null;
    if (h.interval) return x[0] >= h.interval[0] - h.tol && x[0] <= h.interval[1] + h.tol;
    const q = m.q, stride = q + 1;
    for (let f = 0; f < h.facets; f++) {
      let s = h.eq[f * stride + q];
      for (let a = 0; a < q; a++) s += h.eq[f * stride + a] * x[a];
      if (s > h.tol) return false;
    }
    return true;
  }

  // ---------------------------------------------------------------- WebGL2
  const view = $('view');
  view.width = W; view.height = H;
  const scale = Math.max(1, Math.min(3, Math.floor(520 / W)));
  view.style.width = (W * scale) + 'px'; view.style.height = (H * scale) + 'px';
  const gl = view.getContext('webgl2', { preserveDrawingBuffer: true, antialias: false, alpha: false,
                                         premultipliedAlpha: false });
  if (!gl) {
    fail('This page needs WebGL2 (any current Chrome, Firefox or Safari; in headless Chromium start it with ' +
         '--use-angle=swiftshader --enable-unsafe-swiftshader).');
    return;
  }

  // Geometry: one triangle over the whole canvas, or the quads of the tiles that need the full blend
  // (export.blend_tiles; elsewhere every image has the same value and one fetch gives the blend).
  const VS = `#version 300 es
  layout(location = 0) in vec2 a_pos;
  void main() { gl_Position = vec4(a_pos, 0.0, 1.0); }`;
  const TONEMAP = `
  uniform float u_scale;
  uniform int u_linear;
  uniform int u_height;
  out vec4 o;
  vec3 srgb(vec3 x) {
    x = clamp(x * u_scale, 0.0, 1.0);
    return mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, vec3(greaterThan(x, vec3(0.0031308))));
  }
  void emit(vec3 acc) { o = u_linear == 1 ? vec4(acc, 1.0) : vec4(srgb(acc), 1.0); }
  ivec2 pixel() { return ivec2(int(gl_FragCoord.x), u_height - 1 - int(gl_FragCoord.y)); }
  `;
  // Packed: eight half floats per RGBA32UI texel (export.pack_halves); layer c*G + g.
  function packedFS(groups) {
    return `#version 300 es
    precision highp float; precision highp int; precision highp usampler2DArray;
    #define G ${groups}
    uniform usampler2DArray u_tex;
    uniform vec4 u_w[2 * G];
    ${TONEMAP}
    float channel(ivec2 p, int layer, vec4 w0, vec4 w1) {
      uvec4 t = texelFetch(u_tex, ivec3(p, layer), 0);
      return dot(vec4(unpackHalf2x16(t.x), unpackHalf2x16(t.y)), w0)
           + dot(vec4(unpackHalf2x16(t.z), unpackHalf2x16(t.w)), w1);
    }
    void main() {
      ivec2 p = pixel();
      vec3 acc = vec3(0.0);
      ${unrolled(groups, 'w0', 'w1')}
      emit(acc);
    }`;
  }
  // The loop over groups written out: constant texture layers and uniform indices (SwiftShader runs a
  // loop with a dynamic uniform index markedly slower).
  function unrolled(groups, a, b) {
    let src = '';
    for (let g = 0; g < groups; g++) {
      src += `{ vec4 ${a} = u_w[${2 * g}], ${b} = u_w[${2 * g + 1}];
        acc.r += channel(p, ${g}, ${a}, ${b}); acc.g += channel(p, ${groups + g}, ${a}, ${b});
        acc.b += channel(p, ${2 * groups + g}, ${a}, ${b}); }\n`;
    }
    return src;
  }
  // Packed, converted by bit operations: a half h is the float with bits ((h & 0x7fff) << 13 | sign << 31)
  // times 2^112 (exact for normal halves; halves below 6.1e-5 may be flushed to 0 by the GPU); the factor
  // 2^112 is folded into the weights, which come as (even images, odd images) of each group of eight.
  function bitsFS(groups) {
    return `#version 300 es
    precision highp float; precision highp int; precision highp usampler2DArray;
    #define G ${groups}
    uniform usampler2DArray u_tex;
    uniform vec4 u_w[2 * G];
    ${TONEMAP}
    float channel(ivec2 p, int layer, vec4 we, vec4 wo) {
      uvec4 t = texelFetch(u_tex, ivec3(p, layer), 0);
      vec4 lo = uintBitsToFloat(((t << 16u) & 0x80000000u) | ((t << 13u) & 0x0FFFE000u));
      vec4 hi = uintBitsToFloat((t & 0x80000000u) | ((t >> 3u) & 0x0FFFE000u));
      return dot(lo, we) + dot(hi, wo);
    }
    void main() {
      ivec2 p = pixel();
      vec3 acc = vec3(0.0);
      ${unrolled(groups, 'we', 'wo')}
      emit(acc);
    }`;
  }
  // Naive (the benchmark's baseline): one RGBA16F layer per image, one fetch per image.
  function naiveFS(n) {
    return `#version 300 es
    precision highp float; precision highp int; precision highp sampler2DArray;
    #define NL ${n}
    uniform sampler2DArray u_tex;
    uniform float u_wn[NL];
    ${TONEMAP}
    void main() {
      ivec2 p = pixel();
      vec3 acc = vec3(0.0);
      for (int i = 0; i < NL; ++i) acc += u_wn[i] * texelFetch(u_tex, ivec3(p, i), 0).rgb;
      emit(acc);
    }`;
  }
  // One fetch: where every image of a set is equal (exact) or every component after the mean is zero
  // (reduced), the blend is u_c0 times image 0 (u_c0 = the sum of the weights, or the mean's coefficient).
  function firstPackedFS(groups) {
    return `#version 300 es
    precision highp float; precision highp int; precision highp usampler2DArray;
    #define G ${groups}
    uniform usampler2DArray u_tex;
    uniform float u_c0;
    ${TONEMAP}
    void main() {
      ivec2 p = pixel();
      vec3 v = vec3(unpackHalf2x16(texelFetch(u_tex, ivec3(p, 0), 0).x).x,
                    unpackHalf2x16(texelFetch(u_tex, ivec3(p, G), 0).x).x,
                    unpackHalf2x16(texelFetch(u_tex, ivec3(p, 2 * G), 0).x).x);
      emit(u_c0 * v);
    }`;
  }
  const FIRST_NAIVE_FS = `#version 300 es
    precision highp float; precision highp int; precision highp sampler2DArray;
    uniform sampler2DArray u_tex;
    uniform float u_c0;
    ${TONEMAP}
    void main() { emit(u_c0 * texelFetch(u_tex, ivec3(pixel(), 0), 0).rgb); }`;
  function program(fs) {
    const mk = (type, src) => {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(s));
      return s;
    };
    const p = gl.createProgram();
    gl.attachShader(p, mk(gl.VERTEX_SHADER, VS));
    gl.attachShader(p, mk(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(p));
    const u = (name) => gl.getUniformLocation(p, name);
    return { p, u_tex: u('u_tex'), u_w: u('u_w'), u_wn: u('u_wn'), u_c0: u('u_c0'), u_scale: u('u_scale'),
             u_linear: u('u_linear'), u_height: u('u_height') };
  }
  function packedTexture(words, layers) {
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, t);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA32UI, W, H, layers, 0, gl.RGBA_INTEGER, gl.UNSIGNED_INT, words);
    return t;
  }
  // The halves of image i, channel c, from packed words (layout of export.pack_halves).
  function unpackToRGBA16(words, n) {
    const G = Math.ceil(n / 8), P = W * H, out = new Uint16Array(n * P * 4);
    for (let i = 0; i < n; i++) {
      const g = i >> 3, j = (i & 7) >> 1, shift = (i & 1) * 16;
      for (let c = 0; c < 3; c++) {
        const base = (c * G + g) * P * 4 + j;
        for (let px = 0; px < P; px++) out[(i * P + px) * 4 + c] = (words[base + px * 4] >>> shift) & 0xffff;
      }
      for (let px = 0; px < P; px++) out[(i * P + px) * 4 + 3] = 0x3c00;
    }
    return out;
  }

  function vertexArray(xy) {
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, xy, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
    return { vao, count: xy.length / 2 };
  }
  const FULL = vertexArray(new Float32Array([-1, -1, 3, -1, -1, 3]));
  // Two triangles per listed tile, in clip space; tile rows count from the image's top (row r is at
  // gl_FragCoord.y = H - 1 - r, as in pixel()).
  function tileGeometry(set) {
    const t = set.tile, tw = Math.ceil(W / t), th = Math.ceil(H / t), list = set.tiles;
    if (list.length === tw * th) return { all: true, geom: FULL };
    const xy = new Float32Array(list.length * 12);
    list.forEach((idx, i) => {
      const tx = idx % tw, ty = Math.floor(idx / tw);
      const x0 = tx * t / W * 2 - 1, x1 = Math.min(W, (tx + 1) * t) / W * 2 - 1;
      const y1 = (H - ty * t) / H * 2 - 1, y0 = (H - Math.min(H, (ty + 1) * t)) / H * 2 - 1;
      xy.set([x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1], i * 12);
    });
    return { all: false, geom: vertexArray(xy) };
  }

  const SETS = {};
  try {
    const exactWords = u32(DATA.layers.data), basisWords = u32(DATA.basis.data);
    SETS.exact = { n: N, layers: DATA.layers.layers, words: exactWords, tex: packedTexture(exactWords, DATA.layers.layers),
                   prog: program(packedFS(DATA.layers.layers / 3)), first: program(firstPackedFS(DATA.layers.layers / 3)),
                   tiles: tileGeometry({ tile: DATA.layers.tile, tiles: u32(DATA.layers.tiles) }) };
    SETS.reduced = { n: DATA.basis.n, layers: DATA.basis.layers, words: basisWords,
                     tex: packedTexture(basisWords, DATA.basis.layers), prog: program(packedFS(DATA.basis.layers / 3)),
                     first: program(firstPackedFS(DATA.basis.layers / 3)),
                     tiles: tileGeometry({ tile: DATA.basis.tile, tiles: u32(DATA.basis.tiles) }),
                     coef: f64(DATA.basis.coef) };
  } catch (e) {
    fail('WebGL set-up failed: ' + e.message);
    return;
  }
  function bitsProg(name) {
    const s = SETS[name];
    if (!s.bits) s.bits = program(bitsFS(s.layers / 3));
    return s.bits;
  }
  function naiveSet(name) {
    const s = SETS[name];
    if (!s.naive) {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, t);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA16F, W, H, s.n, 0, gl.RGBA, gl.HALF_FLOAT, unpackToRGBA16(s.words, s.n));
      s.naive = { tex: t, prog: program(naiveFS(s.n)), first: program(FIRST_NAIVE_FS) };
    }
    return s.naive;
  }

  // Image weights (per image of a set) from material weights w.
  function setWeights(name, w) {
    if (name === 'exact') return w;
    const s = SETS.reduced, k = s.n, c = new Float64Array(k);
    for (let i = 0; i < N; i++) {
      const wi = w[i];
      if (wi === 0) continue;
      for (let j = 0; j < k; j++) c[j] += wi * s.coef[i * k + j];
    }
    return c;
  }

  let fbo = null, fboTex = null;
  // The blend Σ wᵢ Iᵢ of a set, tone mapped (or linear into `target`): the one-fetch shader over the whole
  // canvas, then the full blend over the tiles that need it (`tiles: false`: the full blend everywhere).
  function draw(name, imageWeights, { linear = false, shader = 'packed', target = null, tiles = true } = {}) {
    const s = SETS[name];
    const prog = shader === 'naive' ? naiveSet(name).prog : shader === 'bits' ? bitsProg(name) : s.prog;
    const tex = shader === 'naive' ? naiveSet(name).tex : s.tex;
    const settings = (p) => {
      gl.uniform1f(p.u_scale, Math.pow(2, state.exposure));
      gl.uniform1i(p.u_linear, linear ? 1 : 0);
      gl.uniform1i(p.u_height, H);
    };
    gl.bindFramebuffer(gl.FRAMEBUFFER, target);
    gl.viewport(0, 0, W, H);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    const geom = tiles && !s.tiles.all ? s.tiles.geom : FULL;
    if (geom !== FULL) {
      const first = shader === 'naive' ? naiveSet(name).first : s.first;
      let c0 = 0;
      if (name === 'exact') for (let i = 0; i < s.n; i++) c0 += imageWeights[i];
      else c0 = imageWeights[0];
      gl.useProgram(first.p);
      gl.uniform1i(first.u_tex, 0);
      gl.uniform1f(first.u_c0, c0);
      settings(first);
      gl.bindVertexArray(FULL.vao);
      gl.drawArrays(gl.TRIANGLES, 0, FULL.count);
    }
    gl.useProgram(prog.p);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    gl.uniform1i(prog.u_tex, 0);
    if (shader === 'naive') {
      gl.uniform1fv(prog.u_wn, Float32Array.from(imageWeights));
    } else if (shader === 'bits') {
      const padded = new Float32Array(Math.ceil(s.n / 8) * 8), f = Math.pow(2, 112);
      for (let i = 0; i < s.n; i++) padded[(i & ~7) + ((i & 1) << 2) + ((i & 7) >> 1)] = imageWeights[i] * f;
      gl.uniform4fv(prog.u_w, padded);
    } else {
      const padded = new Float32Array(Math.ceil(s.n / 8) * 8);
      padded.set(imageWeights);
      gl.uniform4fv(prog.u_w, padded);
    }
    settings(prog);
    gl.bindVertexArray(geom.vao);
    gl.drawArrays(gl.TRIANGLES, 0, geom.count);
    gl.bindVertexArray(null);
  }
  function floatTarget() {
    if (!fbo) {
      if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('EXT_color_buffer_float is not available');
      fboTex = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, fboTex);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, W, H);
      fbo = gl.createFramebuffer();
      gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, fboTex, 0);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    }
    return fbo;
  }

  // ---------------------------------------------------------------- state and UI
  const state = {
    mode: 'map', q: M.default_q, dims: [0, 1], point: null, exposure: 0, basis: 'exact', labels: true,
    pathA: null, pathB: null, t: 0.5, w: null, b: null, frameMs: null,
  };
  const model = () => MODELS.find((m) => m.q === state.q);
  function centre(m) {
    const c = new Array(m.q).fill(0);
    for (let j = 0; j < N; j++) for (let a = 0; a < m.q; a++) c[a] += m.X[j * m.q + a] / N;
    return c;
  }
  function extent(m, a) {
    let lo = Infinity, hi = -Infinity;
    for (let j = 0; j < N; j++) { const v = m.X[j * m.q + a]; lo = Math.min(lo, v); hi = Math.max(hi, v); }
    const pad = 0.15 * (hi - lo || 1);
    return [lo - pad, hi + pad];
  }

  const mapCanvas = $('map'), mctx = mapCanvas.getContext('2d');
  const MW = mapCanvas.width, MH = mapCanvas.height, MARGIN = 28, MAX_ZOOM = 64;
  // zoom and pan of the map: a factor on the fitted scale and the latent offset of the map's centre
  const mapView = { zoom: 1, dx: 0, dy: 0 };
  function resetView() { mapView.zoom = 1; mapView.dx = 0; mapView.dy = 0; }
  function frame() {
    const m = model(), [dx, dy] = state.dims;
    const ex = extent(m, dx), ey = dy === null ? [-1, 1] : extent(m, dy);
    // equal scale on both axes
    const sx = (MW - 2 * MARGIN) / (ex[1] - ex[0]), sy = (MH - 2 * MARGIN) / (ey[1] - ey[0]);
    const s = Math.min(sx, sy) * mapView.zoom;
    const cx = (ex[0] + ex[1]) / 2 + mapView.dx, cy = (ey[0] + ey[1]) / 2 + mapView.dy;
    return {
      scale: s,
      toPx: (x, y) => [MW / 2 + (x - cx) * s, MH / 2 - (y - cy) * s],
      fromPx: (px, py) => [cx + (px - MW / 2) / s, cy - (py - MH / 2) / s],
    };
  }
  // zoom by `factor` about the map pixel (px, py): the latent point under it stays under it
  function zoomAt(px, py, factor) {
    const before = frame().fromPx(px, py);
    mapView.zoom = Math.min(MAX_ZOOM, Math.max(1, mapView.zoom * factor));
    if (mapView.zoom === 1) { resetView(); } else {
      const after = frame().fromPx(px, py);
      mapView.dx += before[0] - after[0];
      if (state.dims[1] !== null) mapView.dy += before[1] - after[1];
    }
    drawMap();
  }
  // pan by a drag of (dpx, dpy) map pixels
  function panBy(dpx, dpy) {
    const s = frame().scale;
    mapView.dx -= dpx / s;
    if (state.dims[1] !== null) mapView.dy += dpy / s;
    drawMap();
  }

  // Labels that do not collide: in order of priority (nearest the pointer first), each label tries four
  // places around its point (right, left, above, below) and is drawn at the first one that stays on the
  // map and overlaps no label already placed and no other point; a label that fits nowhere is left out
  // (zoom in to see it; the nearest materials are listed under the map).
  const LABEL_H = 10, MARKER = 5;
  function placeLabels(points, measure) {
    const boxes = [], placed = [];
    const overlaps = (a, b) => a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
    const markers = points.map((p) => ({ x: p.px - MARKER, y: p.py - MARKER, w: 2 * MARKER, h: 2 * MARKER }));
    points.forEach((p, i) => {
      const w = measure(p.name), h = LABEL_H;
      const spots = [[p.px + 7, p.py - h / 2], [p.px - 7 - w, p.py - h / 2],
                     [p.px - w / 2, p.py - 7 - h], [p.px - w / 2, p.py + 7]];
      for (const [x, y] of spots) {
        const box = { x, y, w, h };
        if (x < 0 || y < 0 || x + w > MW || y + h > MH) continue;
        if (boxes.some((b) => overlaps(box, b))) continue;
        if (markers.some((mk, k) => k !== i && overlaps(box, mk))) continue;
        boxes.push(box);
        placed.push({ name: p.name, j: p.j, x, y, w, h });
        break;
      }
    });
    return placed;
  }
  let drawnLabels = [];

  // the materials nearest a latent point (all q coordinates), nearest first
  function nearestTo(m, x, k = 5) {
    const d = [];
    for (let j = 0; j < N; j++) {
      let s = 0;
      for (let a = 0; a < m.q; a++) s += (m.X[j * m.q + a] - x[a]) ** 2;
      d.push([Math.sqrt(s), j]);
    }
    d.sort((a, b) => a[0] - b[0] || a[1] - b[1]);
    return d.slice(0, k).map(([dist, j]) => ({ j, name: NAMES[j], d: dist }));
  }
  function updateNearest() {
    const m = model(), near = nearestTo(m, state.point);
    const buttons = near.map((n) => el('button', { type: 'button', 'data-j': String(n.j),
      title: `latent distance ${n.d.toFixed(3)}` }, `${n.name} (${n.d.toFixed(2)})`));
    $('nearest').replaceChildren('nearest: ', ...buttons.flatMap((b, i) => (i ? [' ', b] : [b])));
  }
  function project(m, j) {
    const [dx, dy] = state.dims;
    return [m.X[j * m.q + dx], dy === null ? 0 : m.X[j * m.q + dy]];
  }
  function srgb8(v) {
    const x = Math.min(1, Math.max(0, v));
    return Math.round(255 * (x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055));
  }
  let hullCache = { key: null, img: null };
  function hullShade(m, f) {
    // outside the hull (in this slice) in grey, on a grid of 4-pixel cells
    const key = [state.q, state.dims.join(','), state.point && m.q > 2 ? state.point.filter((_, a) => !state.dims.includes(a)).join(',') : '',
                 mapView.zoom, mapView.dx, mapView.dy].join('|');
    if (hullCache.key === key) return hullCache.img;
    const img = mctx.createImageData(MW, MH), cell = 4, x = state.point ? state.point.slice() : centre(m);
    for (let py = 0; py < MH; py += cell) {
      for (let px = 0; px < MW; px += cell) {
        const [u, v] = f.fromPx(px + cell / 2, py + cell / 2);
        x[state.dims[0]] = u;
        if (state.dims[1] !== null) x[state.dims[1]] = v;
        const inside = hullContains(m, x);
        const g = inside === false ? 228 : 255;
        for (let yy = py; yy < Math.min(py + cell, MH); yy++) {
          for (let xx = px; xx < Math.min(px + cell, MW); xx++) {
            const o = (yy * MW + xx) * 4;
            img.data[o] = img.data[o + 1] = img.data[o + 2] = g; img.data[o + 3] = 255;
          }
        }
      }
    }
    hullCache = { key, img };
    return img;
  }
  function drawMap() {
    const m = model(), f = frame();
    mctx.putImageData(hullShade(m, f), 0, 0);
    if (m.hull && m.hull.polygon) {
      mctx.beginPath();
      m.hull.polygon.forEach((j, i) => { const [px, py] = f.toPx(...project(m, j)); i ? mctx.lineTo(px, py) : mctx.moveTo(px, py); });
      mctx.closePath();
      mctx.strokeStyle = '#888'; mctx.setLineDash([4, 3]); mctx.stroke(); mctx.setLineDash([]);
    }
    if (state.dims[1] === null) {
      mctx.strokeStyle = '#999'; mctx.beginPath(); mctx.moveTo(0, MH / 2); mctx.lineTo(MW, MH / 2); mctx.stroke();
    }
    // distance from the slice (other dimensions) fades the points
    const others = [];
    for (let a = 0; a < m.q; a++) if (!state.dims.includes(a)) others.push(a);
    const x = state.point || centre(m);
    mctx.font = '9px system-ui, sans-serif';
    const alphas = new Float64Array(N), onMap = [];
    for (let j = 0; j < N; j++) {
      const [px, py] = f.toPx(...project(m, j));
      let d2 = 0;
      for (const a of others) { const d = m.X[j * m.q + a] - x[a]; d2 += d * d; }
      const alpha = others.length ? Math.max(0.2, Math.exp(-d2 / (2 * m.ell * m.ell))) : 1;
      alphas[j] = alpha;
      mctx.globalAlpha = alpha;
      mctx.fillStyle = `rgb(${srgb8(ALBEDO[3 * j])},${srgb8(ALBEDO[3 * j + 1])},${srgb8(ALBEDO[3 * j + 2])})`;
      mctx.beginPath(); mctx.arc(px, py, 4.5, 0, 2 * Math.PI); mctx.fill();
      mctx.strokeStyle = '#333'; mctx.lineWidth = 0.8; mctx.stroke();
      mctx.globalAlpha = 1;
      if (px >= -MARKER && px <= MW + MARKER && py >= -MARKER && py <= MH + MARKER) onMap.push({ j, name: NAMES[j], px, py });
    }
    drawnLabels = [];
    if (state.labels) {
      // nearest the pointer first (its pixel), then the rest
      const [ppx, ppy] = f.toPx(x[state.dims[0]], state.dims[1] === null ? 0 : x[state.dims[1]]);
      onMap.sort((a, b) => Math.hypot(a.px - ppx, a.py - ppy) - Math.hypot(b.px - ppx, b.py - ppy) || a.j - b.j);
      drawnLabels = placeLabels(onMap, (name) => mctx.measureText(name).width);
      mctx.fillStyle = '#333'; mctx.textBaseline = 'top';
      for (const l of drawnLabels) { mctx.globalAlpha = alphas[l.j]; mctx.fillText(l.name, l.x, l.y); }
      mctx.globalAlpha = 1; mctx.textBaseline = 'alphabetic';
    }
    $('zoom-out').textContent = mapView.zoom === 1 ? '' : `zoom ×${mapView.zoom.toFixed(1)}`;
    $('reset-view').hidden = mapView.zoom === 1 && mapView.dx === 0 && mapView.dy === 0;
    if (state.mode === 'path' && state.pathA !== null) {
      const [ax, ay] = f.toPx(...project(m, state.pathA)), [bx, by] = f.toPx(...project(m, state.pathB));
      mctx.strokeStyle = '#d07a00'; mctx.lineWidth = 2;
      mctx.beginPath(); mctx.moveTo(ax, ay); mctx.lineTo(bx, by); mctx.stroke(); mctx.lineWidth = 1;
    }
    if (state.point) {
      const [px, py] = f.toPx(state.point[state.dims[0]], state.dims[1] === null ? 0 : state.point[state.dims[1]]);
      mctx.strokeStyle = '#c00'; mctx.lineWidth = 1.5;
      mctx.beginPath(); mctx.arc(px, py, 7, 0, 2 * Math.PI);
      mctx.moveTo(px - 11, py); mctx.lineTo(px + 11, py); mctx.moveTo(px, py - 11); mctx.lineTo(px, py + 11);
      mctx.stroke(); mctx.lineWidth = 1;
    }
  }

  function fmt(v, d = 3) { return (v >= 0 ? '+' : '') + v.toFixed(d); }
  function updatePanel(inside) {
    const w = state.w, m = model();
    $('where').textContent = `q = ${m.q}, x = (${state.point.map((v) => v.toFixed(3)).join(', ')})`;
    const alb = [0, 0, 0];
    let sabs = 0;
    for (let i = 0; i < N; i++) {
      for (let c = 0; c < 3; c++) alb[c] += w[i] * ALBEDO[3 * i + c];
      sabs += Math.abs(w[i]);
    }
    const warnings = [];
    if (inside === false) warnings.push('Outside the convex hull of the materials: the interpolant is not backed by data here.');
    if (alb.some((v) => v < 0 || v > 1)) warnings.push('Interpolated albedo outside [0, 1]: not a physically plausible material.');
    if (!m.linear) warnings.push(`Data space "${m.space}" is not linear in the BRDF: blending images with its weights is an approximation.`);
    $('warning').hidden = !warnings.length;
    $('warning').textContent = warnings.join(' ');
    $('albedo-swatch').style.background = `rgb(${alb.map(srgb8).join(',')})`;
    $('albedo').textContent = `albedo Σwᵢaᵢ = (${alb.map((v) => v.toFixed(3)).join(', ')})`;
    $('sums').textContent = `Σ|wᵢ| = ${sabs.toFixed(3)}`;
    const order = Array.from(w.keys()).sort((a, b) => Math.abs(w[b]) - Math.abs(w[a])).slice(0, 8);
    const big = Math.max(...order.map((i) => Math.abs(w[i])), 1e-12);
    $('weights').tBodies[0].replaceChildren(...order.map((i) => el('tr', {},
      el('td', {}, NAMES[i]), el('td', { class: 'v' }, fmt(w[i])),
      el('td', {}, el('span', { class: 'bar' + (w[i] < 0 ? ' neg' : ''),
                                style: `width:${Math.round(90 * Math.abs(w[i]) / big)}px` })))));
    api.last = { albedo: alb, inside, sumAbs: sabs, warning: warnings.join(' ') };
  }

  let pending = false;
  function render() {
    pending = false;
    const t0 = performance.now();
    draw(state.basis, setWeights(state.basis, state.w));
    gl.finish();
    state.frameMs = performance.now() - t0;
    const s = SETS[state.basis];
    $('timing').textContent = `blend of ${s.n} images (${state.basis}) on the GPU: ${state.frameMs.toFixed(1)} ms ` +
      `(${W} × ${H}, exposure ${fmt(state.exposure, 1)})`;
    drawRef();
  }
  function schedule() { if (!pending) { pending = true; requestAnimationFrame(render); } }

  function setPoint(x) {
    const m = model();
    state.point = Array.from(x, Number);
    const r = weightsAt(m, state.point);
    state.b = r.b; state.w = r.w;
    updatePanel(hullContains(m, state.point));
    updateNearest();
    drawMap();
    schedule();
  }

  // ---------------------------------------------------------------- path mode
  function pathEntries(a, b) { return PATHS.map((p, i) => ({ p, i })).filter(({ p }) => p.a === NAMES[a] && p.b === NAMES[b]); }
  const refCanvas = $('ref'), rctx = refCanvas.getContext('2d');
  refCanvas.width = W; refCanvas.height = H;
  refCanvas.style.width = view.style.width; refCanvas.style.height = view.style.height;
  const REFS = DATA.refs.n ? new Uint16Array(bytes(DATA.refs.data).buffer) : null;
  function half(h) {
    const s = (h & 0x8000) ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
    if (e === 0) return s * Math.pow(2, -14) * (f / 1024);
    if (e === 31) return f ? NaN : s * Infinity;
    return s * Math.pow(2, e - 15) * (1 + f / 1024);
  }
  function drawRef() {
    const fig = $('ref-fig');
    if (state.mode !== 'path') { fig.hidden = true; return; }
    fig.hidden = false;
    const hit = pathEntries(state.pathA, state.pathB).find(({ p }) => Math.abs(p.t - state.t) < 1e-9);
    if (!hit || !REFS) {
      rctx.fillStyle = '#333'; rctx.fillRect(0, 0, W, H);
      rctx.fillStyle = '#ccc'; rctx.font = '11px system-ui'; rctx.fillText('no render at this t', 6, 16);
      $('ref-caption').textContent = 'rendered reference: none at t = ' + state.t.toFixed(2);
      return;
    }
    const img = rctx.createImageData(W, H), off = hit.p.ref * W * H * 3, sc = Math.pow(2, state.exposure);
    for (let px = 0; px < W * H; px++) {
      for (let c = 0; c < 3; c++) img.data[px * 4 + c] = srgb8(half(REFS[off + px * 3 + c]) * sc);
      img.data[px * 4 + 3] = 255;
    }
    rctx.putImageData(img, 0, 0);
    const p = hit.p;
    $('ref-caption').textContent = `rendered reference at t = ${p.t}` + (p.rmse_blend_seed2 !== undefined ?
      ` — blend vs 2nd-seed render ${(100 * p.rmse_blend_seed2).toFixed(1)} %, two seeds ${(100 * p.rmse_noise).toFixed(1)} %` : '');
  }
  function setPath(a, b, t) {
    state.pathA = a; state.pathB = b; state.t = t;
    const entries = pathEntries(a, b);
    if (entries.length && MODELS.some((m) => m.q === entries[0].p.q) && state.q !== entries[0].p.q) selectModel(entries[0].p.q, false);
    $('path-a').value = a; $('path-b').value = b; $('path-t').value = t; $('path-t-out').textContent = t.toFixed(2);
    $('path-refs').replaceChildren(...(entries.length ?
      ['references: ', ...entries.map(({ p }) => el('button', { 'data-t': Number(p.t) }, `t = ${Number(p.t)}`))] :
      ['no rendered reference on this path']));
    const m = model(), x = new Array(m.q);
    for (let d = 0; d < m.q; d++) x[d] = (1 - t) * m.X[a * m.q + d] + t * m.X[b * m.q + d];
    setPoint(x);
    buildSlices();  // the sliders of the other coordinates follow the path's point
  }

  // ---------------------------------------------------------------- controls
  function buildSlices() {
    const m = model(), box = $('slices');
    box.replaceChildren();
    $('dims-box').hidden = m.q < 3;
    for (let a = 0; a < m.q; a++) {
      if (state.dims.includes(a)) continue;
      const [lo, hi] = extent(m, a);
      const input = el('input', { type: 'range', min: String(lo), max: String(hi), step: String((hi - lo) / 400) });
      input.value = String(state.point[a]);
      const lab = el('label', {}, `x${a + 1} `, input, ' ', el('output', {}, state.point[a].toFixed(2)));
      input.addEventListener('input', () => {
        const x = state.point.slice(); x[a] = Number(input.value);
        lab.querySelector('output').textContent = x[a].toFixed(2);
        setPoint(x);
      });
      box.appendChild(lab);
    }
  }
  function selectModel(q, keepPoint = true) {
    state.q = q;
    const m = model();
    state.dims = m.q === 1 ? [0, null] : [0, 1];
    $('model').value = String(q);
    const axes = Array.from({ length: m.q }, (_, a) => [a, `x${a + 1}`]);
    options($('dim-x'), axes); options($('dim-y'), axes);
    $('dim-x').value = '0'; $('dim-y').value = '1';
    hullCache.key = null;
    resetView();
    state.point = centre(m);
    buildSlices();
    if (keepPoint) setPoint(state.point);
    $('map-note').textContent = m.q === 1 ? 'q = 1: the latent space is a line.' :
      m.q === 2 ? 'The q = 2 latent map; grey: outside the convex hull of the materials (dashed).' :
      `A 2-D slice of the q = ${m.q} space through the other coordinates set below; points fade with their distance from the slice; grey: outside the hull in this slice.`;
  }
  function setDims(i, j) {
    const m = model();
    if (m.q < 2 || i === j) return;
    state.dims = [i, j];
    $('dim-x').value = String(i); $('dim-y').value = String(j);
    hullCache.key = null;
    resetView();
    buildSlices();
    setPoint(state.point);
  }
  function setMode(mode) {
    state.mode = mode;
    document.querySelector(`input[name=mode][value=${mode}]`).checked = true;
    $('path-controls').hidden = mode !== 'path';
    // side by side in path mode: two images in the width of one
    const cw = mode === 'path' ? Math.min(W * scale, 340) : W * scale;
    for (const c of [view, refCanvas]) { c.style.width = cw + 'px'; c.style.height = Math.round(cw * H / W) + 'px'; }
    if (mode === 'path') {
      const first = PATHS.length ? PATHS[0] : null;
      const a = state.pathA !== null ? state.pathA : first ? NAMES.indexOf(first.a) : 0;
      const b = state.pathB !== null ? state.pathB : first ? NAMES.indexOf(first.b) : Math.min(1, N - 1);
      setPath(a, b, first && state.pathA === null ? first.t : state.t);
    } else {
      drawMap(); schedule();
    }
  }

  function init() {
    $('subtitle').textContent = `${N} materials (${M.database} database), GPLVM ${M.space} μ = ${M.mu}, ` +
      `pre-renders ${W} × ${H}`;
    options($('model'), MODELS.map((m) => [m.q, `q = ${m.q}`]));
    const b = M.basis;
    options($('basis'), [['exact', `exact: ${N} pre-renders`],
      ['reduced', `reduced: mean + ${b.k} components` +
        (b.below_floor === false ? ' (approximate: worst blend above the noise floor)' : '')]]);
    $('basis').title = `reduced basis: largest relative RMSE ${b.error_prerenders_max.toPrecision(3)} over the pre-renders, ` +
      `${b.error_blends_max.toPrecision(3)} over ${b.blend_samples} blends in the hulls; target ${b.target.toPrecision(3)}` +
      (b.floor === null ? ' (no noise floor known)' : ' (the Monte Carlo noise of one pre-render)');
    const names = NAMES.map((n, i) => [i, n]);
    options($('path-a'), names); options($('path-b'), names);
    $('footer').textContent = `brdfpipe ${M.brdfpipe_version}. Weights b = K⁻¹k from the exported model; ` +
      `blend Σ wᵢ Iᵢ of half-float pre-renders in a WebGL2 shader, tone mapped there (×2^exposure, sRGB). ` +
      `Reduced mode: ${b.k} SVD components + mean, largest error ${(100 * Math.max(b.error_prerenders_max, b.error_blends_max)).toFixed(2)} % ` +
      (b.floor === null ? '' : `(noise floor of one pre-render ${(100 * b.floor).toFixed(1)} %)`);

    document.querySelectorAll('input[name=mode]').forEach((r) => r.addEventListener('change', () => setMode(r.value)));
    $('model').addEventListener('change', () => selectModel(Number($('model').value)));
    $('dim-x').addEventListener('change', () => setDims(Number($('dim-x').value), state.dims[1]));
    $('dim-y').addEventListener('change', () => setDims(state.dims[0], Number($('dim-y').value)));
    $('basis').addEventListener('change', () => { state.basis = $('basis').value; schedule(); });
    $('exposure').addEventListener('input', () => {
      state.exposure = Number($('exposure').value);
      $('exposure-out').textContent = fmt(state.exposure, 1);
      schedule();
    });
    $('labels').addEventListener('change', () => { state.labels = $('labels').checked; drawMap(); });
    $('path-a').addEventListener('change', () => setPath(Number($('path-a').value), state.pathB, state.t));
    $('path-b').addEventListener('change', () => setPath(state.pathA, Number($('path-b').value), state.t));
    $('path-t').addEventListener('input', () => setPath(state.pathA, state.pathB, Number($('path-t').value)));
    $('path-refs').addEventListener('click', (e) => {
      if (e.target.dataset && e.target.dataset.t) setPath(state.pathA, state.pathB, Number(e.target.dataset.t));
    });
    const mapPixel = (e) => {
      const r = mapCanvas.getBoundingClientRect();
      return [(e.clientX - r.left) * MW / r.width, (e.clientY - r.top) * MH / r.height];
    };
    let drag = null;  // a press on the map: dragging it pans (the point stays where the press put it)
    const pointer = (e) => {
      const [px, py] = mapPixel(e);
      if (e.type === 'pointermove' && drag && (e.buttons & 1)) {
        if (drag.moved || Math.hypot(px - drag.px, py - drag.py) > 3) {
          drag.moved = true;
          panBy(px - drag.last[0], py - drag.last[1]);
          drag.last = [px, py];
        }
        return;
      }
      if (e.type === 'pointerdown') drag = { px, py, last: [px, py], moved: false };
      if (state.mode !== 'map') return;
      const f = frame(), m = model(), [u, v] = f.fromPx(px, py), x = state.point.slice();
      x[state.dims[0]] = u;
      if (state.dims[1] !== null) x[state.dims[1]] = v;
      if (e.type === 'pointerdown') {  // a click on a material: exactly its latent point (w = e_i)
        for (let j = 0; j < N; j++) {
          const [qx, qy] = f.toPx(...project(m, j));
          if (Math.hypot(qx - px, qy - py) <= 6) { setPoint(Array.from(m.X.subarray(j * m.q, (j + 1) * m.q))); return; }
        }
      }
      setPoint(x);
    };
    mapCanvas.addEventListener('pointermove', pointer);
    mapCanvas.addEventListener('pointerdown', pointer);
    window.addEventListener('pointerup', () => { drag = null; });
    mapCanvas.addEventListener('wheel', (e) => {
      e.preventDefault();
      const [px, py] = mapPixel(e);
      zoomAt(px, py, Math.pow(1.2, -e.deltaY / 100));
    }, { passive: false });
    mapCanvas.addEventListener('dblclick', () => { resetView(); drawMap(); });
    $('reset-view').addEventListener('click', () => { resetView(); drawMap(); });
    $('nearest').addEventListener('click', (e) => {
      const j = e.target.dataset && e.target.dataset.j;
      if (j !== undefined) setPoint(Array.from(model().X.subarray(Number(j) * model().q, (Number(j) + 1) * model().q)));
    });

    selectModel(state.q, false);
    // start at the material nearest the centre of the map
    const m = model(), c = centre(m);
    let best = 0, bd = Infinity;
    for (let j = 0; j < N; j++) {
      let d = 0;
      for (let a = 0; a < m.q; a++) d += (m.X[j * m.q + a] - c[a]) ** 2;
      if (d < bd) { bd = d; best = j; }
    }
    const start = c.map((v, a) => 0.5 * v + 0.5 * m.X[best * m.q + a]);
    setPoint(start);
    render();
  }

  // ---------------------------------------------------------------- API for tests, benches and tools
  function readLinear(name, imageWeights, { shader = 'packed', tiles = true } = {}) {
    const target = floatTarget();
    draw(name, imageWeights, { linear: true, target, shader, tiles });
    const px = new Float32Array(W * H * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, target);
    gl.readPixels(0, 0, W, H, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const rgb = new Float32Array(W * H * 3);  // top row first
    for (let y = 0; y < H; y++) {
      for (let x = 0; x < W; x++) {
        const s = ((H - 1 - y) * W + x) * 4, d = (y * W + x) * 3;
        rgb[d] = px[s]; rgb[d + 1] = px[s + 1]; rgb[d + 2] = px[s + 2];
      }
    }
    return rgb;
  }
  function b64f32(a) {
    const u = new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
    let s = '';
    for (let i = 0; i < u.length; i += 0x8000) s += String.fromCharCode.apply(null, u.subarray(i, i + 0x8000));
    return btoa(s);
  }
  Object.assign(api, {
    manifest: M,
    state: () => ({ mode: state.mode, q: state.q, dims: state.dims.slice(), point: state.point.slice(),
                    exposure: state.exposure, basis: state.basis, pathA: state.pathA, pathB: state.pathB, t: state.t,
                    w: Array.from(state.w), frameMs: state.frameMs }),
    weightsAt: (q, x) => { const r = weightsAt(MODELS.find((m) => m.q === q), x); return { b: Array.from(r.b), w: Array.from(r.w) }; },
    hullContains: (q, x) => hullContains(MODELS.find((m) => m.q === q), x),
    setPoint: (x) => { setPoint(x); render(); return api.state(); },
    setModel: (q) => { selectModel(q); render(); return api.state(); },
    setDims: (i, j) => { setDims(i, j); render(); return api.state(); },
    setMode: (mode) => { setMode(mode); render(); return api.state(); },
    setPath: (a, b, t) => { setMode('path'); setPath(NAMES.indexOf(a), NAMES.indexOf(b), t); render(); return api.state(); },
    setExposure: (e) => { state.exposure = e; $('exposure').value = e; $('exposure-out').textContent = fmt(e, 1); render(); return e; },
    setBasis: (name) => { state.basis = name; $('basis').value = name; render(); return name; },
    // the map's view (zoom, latent offset of its centre), the labels drawn (map pixels) and the nearest materials
    view: () => ({ zoom: mapView.zoom, dx: mapView.dx, dy: mapView.dy }),
    labels: () => drawnLabels.map((l) => ({ name: l.name, x: l.x, y: l.y, w: l.w, h: l.h })),
    nearest: (k = 5) => nearestTo(model(), state.point, k).map((n) => ({ name: n.name, d: n.d })),
    // the label placement alone, on given points ([{name, px, py}], map pixels) with the map's font
    placeLabels: (points) => {
      mctx.font = '9px system-ui, sans-serif';
      return placeLabels(points.map((p, j) => ({ ...p, j })), (name) => mctx.measureText(name).width);
    },
    mapSize: () => [MW, MH],
    // the map's pixel (page coordinates) of a latent point, for pointer events
    mapToPage: (x) => {
      const f = frame(), r = mapCanvas.getBoundingClientRect();
      const [px, py] = f.toPx(x[state.dims[0]], state.dims[1] === null ? 0 : x[state.dims[1]]);
      return [r.left + px * r.width / MW, r.top + py * r.height / MH];
    },
    // the linear blend (before tone mapping) of the current weights, read back as float32 RGB (base64, top row first)
    debugBlend: (opts = {}) => {
      const name = opts.basis || state.basis, w = opts.weights ? Float64Array.from(opts.weights) : state.w;
      const iw = setWeights(name, w);
      const rgb = readLinear(name, iw, { shader: opts.shader || 'packed', tiles: opts.tiles !== false });
      render();
      return { width: W, height: H, basis: name, weights: Array.from(w), imageWeights: Array.from(iw), rgb: b64f32(rgb),
               blendedTiles: SETS[name].tiles.all ? 'all' : SETS[name].tiles.geom.count / 6 };
    },
    // the tone-mapped canvas as 8-bit RGBA (base64, top row first)
    canvasPixels: () => {
      render();
      const px = new Uint8Array(W * H * 4);
      gl.readPixels(0, 0, W, H, gl.RGBA, gl.UNSIGNED_BYTE, px);
      const out = new Uint8Array(W * H * 4);
      for (let y = 0; y < H; y++) out.set(px.subarray((H - 1 - y) * W * 4, (H - y) * W * 4), y * W * 4);
      return b64f32(out);
    },
    // frame time of the blend: `frames` draws with changing weights, each finished (gl.finish + a 1-pixel read)
    bench: (opts = {}) => {
      const name = opts.basis || 'exact', shader = opts.shader || 'packed', frames = opts.frames || 30;
      const tiles = opts.tiles !== false;
      const n = SETS[name].n, base = setWeights(name, state.w), px = new Uint8Array(4);
      if (shader === 'naive') naiveSet(name);
      const one = (i) => {
        const iw = new Float64Array(n);
        for (let j = 0; j < n; j++) iw[j] = base[j] * (1 + 0.01 * Math.sin(i + j));
        draw(name, iw, { shader, tiles });
        gl.finish();
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
      };
      for (let i = 0; i < 3; i++) one(i);  // warm-up: shader compilation, texture residency
      const t0 = performance.now();
      for (let i = 0; i < frames; i++) one(i + 3);
      const ms = (performance.now() - t0) / frames;
      render();
      return { basis: name, shader, tiles, blended_tiles: SETS[name].tiles.all ? 'all' : SETS[name].tiles.geom.count / 6,
               images: n, width: W, height: H, frames, ms, fps: 1000 / ms };
    },
  });

  try {
    init();
    api.ready = true;
  } catch (e) {
    fail('explorer: ' + e.message);
    throw e;
  }
})();
