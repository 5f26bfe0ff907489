// slices.js - the CT beside the surfaces (issue 46): a stored volume's or series' samples (GET
// /models/{id}/volume, /series/{uid}/volume: one NRRD) in three slice views, axial, coronal and
// sagittal, drawn on 2D canvases in the radiological convention (the patient's right on the
// left, anterior and superior up), with window and level (presets, drag, or the two numbers), the
// cut lines of the models in the 3D view (their triangles cut by the slice's plane, here in the
// page), and the three planes for view.js to draw in the 3D view. Bundled into view.js.
//
// Patient coordinates are DICOM's (LPS: +x left, +y posterior, +z superior). A grid whose axes
// are turned off the patient's is sliced along the grid axis nearest each patient axis.

const TYPES = { uint8: Uint8Array, uchar: Uint8Array, "unsigned char": Uint8Array, int16: Int16Array, short: Int16Array,
  uint16: Uint16Array, ushort: Uint16Array, "unsigned short": Uint16Array, float: Float32Array };

// An attached, raw NRRD (as the daemon writes it): dims, samples, space directions and origin.
export function parseNrrd(buf) {
  const bytes = new Uint8Array(buf);
  let end = -1;
  for (let i = 0; i + 1 < Math.min(bytes.length, 8192); i++) if (bytes[i] === 10 && bytes[i + 1] === 10) { end = i; break; }
  if (end < 0) throw new Error("not a NRRD (no header)");
  const head = new TextDecoder().decode(bytes.subarray(0, end));
  if (!head.startsWith("NRRD")) throw new Error("not a NRRD");
  const f = {};
  for (const line of head.split("\n").slice(1)) {
    const m = /^([^#:][^:]*):=?\s*(.*)$/.exec(line);
    if (m) f[m[1].trim()] = m[2].trim();
  }
  const dims = (f.sizes || "").split(/\s+/).map(Number);
  const T = TYPES[f.type];
  if (dims.length !== 3 || !T || (f.encoding || "raw") !== "raw") throw new Error("a NRRD of 3 dimensions and raw samples expected");
  if (f.endian === "big" && T.BYTES_PER_ELEMENT > 1) throw new Error("big-endian samples are not read");
  const vecs = (s) => (s.match(/\(([^)]*)\)/g) || []).map((v) => v.slice(1, -1).split(",").map(Number));
  const dirs = vecs(f["space directions"] || ""), origin = vecs(f["space origin"] || "(0,0,0)")[0];
  if (dirs.length !== 3) throw new Error("the NRRD gives no space directions");
  const n = dims[0] * dims[1] * dims[2], off = end + 2;
  if (buf.byteLength - off < n * T.BYTES_PER_ELEMENT) throw new Error("the NRRD's samples are short");
  const data = new T(buf.slice(off, off + n * T.BYTES_PER_ELEMENT)); // (copied: aligned)
  const spacing = dirs.map((d) => Math.hypot(...d)), unit = dirs.map((d, a) => d.map((x) => x / spacing[a]));
  let lo = Infinity, hi = -Infinity;
  for (let i = 0; i < n; i += Math.max(1, Math.floor(n / 200000))) { const v = data[i]; if (v < lo) lo = v; if (v > hi) hi = v; }
  return { dims, type: f.type, data, dirs, origin, spacing, unit, range: [lo, hi] };
}

// The three views: the patient axis each looks along, its screen's right and down (axis, sign).
export const VIEWS = [
  { name: "axial", label: "Axial", normal: 2, u: [0, 1], v: [1, 1], colour: "#e0443e" },
  { name: "coronal", label: "Coronal", normal: 1, u: [0, 1], v: [2, -1], colour: "#3fae49" },
  { name: "sagittal", label: "Sagittal", normal: 0, u: [1, 1], v: [2, -1], colour: "#e8c21c" },
];
// Window and level presets (Hounsfield units for CT).
export const PRESETS = { soft: [400, 40], bone: [1800, 400], lung: [1500, -600] };

// The grid axis nearest patient axis p, and whether it runs the same way.
function gridAxis(vol, p) {
  let best = 0;
  for (let a = 1; a < 3; a++) if (Math.abs(vol.unit[a][p]) > Math.abs(vol.unit[best][p])) best = a;
  return { a: best, s: vol.unit[best][p] >= 0 ? 1 : -1 };
}

// A view's layout on the grid: the sliced axis n, the screen's axes a (columns) and b (rows), and
// whether each is flipped.
function layout(vol, view) {
  const n = gridAxis(vol, view.normal).a, u = gridAxis(vol, view.u[0]), v = gridAxis(vol, view.v[0]);
  return { n, a: u.a, b: v.a, flipA: u.s * view.u[1] < 0, flipB: v.s * view.v[1] < 0, w: vol.dims[u.a], h: vol.dims[v.a] };
}

export class SliceViews {
  // els: {canvases: [3], ranges: [3], preset, window, level, caption}; meshes(): [{colour (css), position, count}];
  // changed(): the planes moved (view.js redraws the 3D view's).
  constructor(els, meshes, changed) {
    this.els = els, this.meshes = meshes, this.changed = changed;
    this.vol = null, this.k = [0, 0, 0], this.win = 400, this.lev = 40, this.lines = [0, 0, 0];
    this.images = VIEWS.map(() => document.createElement("canvas"));
    VIEWS.forEach((view, i) => this.wire(i));
    els.preset.addEventListener("change", () => this.preset(els.preset.value));
    for (const el of [els.window, els.level]) el.addEventListener("change", () => {
      const w = +els.window.value, l = +els.level.value;
      if (w > 0 && Number.isFinite(l)) this.setWL(w, l, "custom");
    });
    new ResizeObserver(() => this.draw()).observe(els.canvases[0].parentElement.parentElement);
  }

  wire(i) {
    const c = this.els.canvases[i], r = this.els.ranges[i];
    r.addEventListener("input", () => this.setSlice(i, +r.value));
    c.addEventListener("keydown", (ev) => {
      const step = { ArrowUp: 1, ArrowRight: 1, PageUp: 10, ArrowDown: -1, ArrowLeft: -1, PageDown: -10 }[ev.key];
      if (step === undefined || !this.vol) return;
      ev.preventDefault();
      this.setSlice(i, this.k[i] + step);
    });
    c.addEventListener("wheel", (ev) => {
      if (!this.vol) return;
      ev.preventDefault();
      this.setSlice(i, this.k[i] + (ev.deltaY < 0 ? 1 : -1));
    }, { passive: false });
    // drag: window (right is wider) and level (down is higher); a click without a drag moves the
    // other two views' slices to the point
    let drag = null;
    c.addEventListener("pointerdown", (ev) => {
      if (!this.vol) return;
      c.setPointerCapture(ev.pointerId);
      drag = { x: ev.clientX, y: ev.clientY, w: this.win, l: this.lev, moved: false };
    });
    c.addEventListener("pointermove", (ev) => {
      if (!drag) return;
      const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
      if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
      if (!drag.moved) return;
      const k = Math.max(1, (this.vol.range[1] - this.vol.range[0]) / 500);
      this.setWL(Math.max(1, drag.w + dx * 2 * k), drag.l + dy * k, "custom");
    });
    c.addEventListener("pointerup", (ev) => {
      if (drag && !drag.moved) this.pointAt(i, ev);
      drag = null;
    });
  }

  // Opens a volume (parseNrrd's): every view at its middle slice, CT in soft tissue, others at
  // the samples' range.
  open(vol, name) {
    this.vol = vol;
    VIEWS.forEach((view, i) => {
      const L = layout(vol, view), r = this.els.ranges[i];
      r.min = "0", r.max = String(vol.dims[L.n] - 1), r.value = String((this.k[i] = Math.floor(vol.dims[L.n] / 2)));
      r.disabled = false;
    });
    const ct = vol.type === "int16" && vol.range[0] < -500;
    this.preset(ct ? "soft" : "auto");
    this.els.caption.textContent = name + ": " + vol.dims.join(" × ") + " samples (" + vol.type + "), " +
      vol.spacing.map((s) => +s.toFixed(3)).join(" × ") + " mm";
  }

  // The samples changed in place (a brush stroke, its undo): the images painted again.
  repaint() {
    if (!this.vol) return;
    this.images.forEach((c, i) => this.paint(i));
    this.draw();
  }

  // Another copy of the same grid (read again): shown where the views are.
  replace(vol) {
    this.vol = vol;
    this.repaint();
  }

  close() {
    this.vol = null;
    this.draw();
    this.changed();
  }

  preset(name) {
    this.els.preset.value = name;
    if (name === "auto") {
      const [lo, hi] = this.vol ? this.vol.range : [0, 1];
      this.setWL(Math.max(1, hi - lo), (hi + lo) / 2, "auto");
    } else if (PRESETS[name]) this.setWL(PRESETS[name][0], PRESETS[name][1], name);
  }

  setWL(w, l, preset) {
    this.win = Math.round(w), this.lev = Math.round(l);
    this.els.window.value = String(this.win), this.els.level.value = String(this.lev);
    if (preset && this.els.preset.value !== preset) this.els.preset.value = preset === "custom" ? "custom" : preset;
    this.images.forEach((c, i) => this.paint(i));
    this.draw();
  }

  setSlice(i, k) {
    if (!this.vol) return;
    const L = layout(this.vol, VIEWS[i]);
    k = Math.max(0, Math.min(this.vol.dims[L.n] - 1, Math.round(k)));
    if (k === this.k[i] && this.images[i].width) return;
    this.k[i] = k;
    this.els.ranges[i].value = String(k);
    this.paint(i);
    this.draw(i);
    this.changed();
  }

  // A click on view i: the other views' slices through that point.
  pointAt(i, ev) {
    const c = this.els.canvases[i], box = c.getBoundingClientRect(), g = this.geometry(i, box.width, box.height);
    const col = (ev.clientX - box.left - g.dx) / g.sa - 0.5, row = (ev.clientY - box.top - g.dy) / g.sb - 0.5;
    if (col < -0.5 || row < -0.5 || col > g.L.w - 0.5 || row > g.L.h - 0.5) return;
    const idx = [0, 0, 0];
    idx[g.L.n] = this.k[i];
    idx[g.L.a] = g.L.flipA ? g.L.w - 1 - col : col;
    idx[g.L.b] = g.L.flipB ? g.L.h - 1 - row : row;
    VIEWS.forEach((view, j) => { if (j !== i) this.setSlice(j, idx[layout(this.vol, view).n]); });
  }

  // The slice's samples into its image (one pixel a sample) at the window and level.
  paint(i) {
    const img = this.images[i], vol = this.vol;
    if (!vol) return;
    const L = layout(vol, VIEWS[i]), d = vol.data, stride = [1, vol.dims[0], vol.dims[0] * vol.dims[1]];
    img.width = L.w, img.height = L.h;
    const g = img.getContext("2d"), out = g.createImageData(L.w, L.h), px = out.data;
    const lo = this.lev - this.win / 2, k = 255 / this.win, base = this.k[i] * stride[L.n];
    for (let r = 0; r < L.h; r++) {
      const ib = L.flipB ? L.h - 1 - r : r, row = base + ib * stride[L.b];
      for (let c = 0; c < L.w; c++) {
        const ia = L.flipA ? L.w - 1 - c : c;
        let v = (d[row + ia * stride[L.a]] - lo) * k;
        v = v < 0 ? 0 : v > 255 ? 255 : v;
        const o = 4 * (r * L.w + c);
        px[o] = px[o + 1] = px[o + 2] = v;
        px[o + 3] = 255;
      }
    }
    g.putImageData(out, 0, 0);
  }

  // Where view i's image lies on a canvas of w x h CSS pixels (its aspect the samples' in mm).
  geometry(i, w, h) {
    const vol = this.vol, L = layout(vol, VIEWS[i]);
    const mmW = L.w * vol.spacing[L.a], mmH = L.h * vol.spacing[L.b], s = Math.min(w / mmW, h / mmH);
    return { L, s, dx: (w - mmW * s) / 2, dy: (h - mmH * s) / 2, sa: vol.spacing[L.a] * s, sb: vol.spacing[L.b] * s };
  }

  // The plane of view i's slice: a point on it and its unit normal (patient coordinates).
  plane(i) {
    const vol = this.vol, L = layout(vol, VIEWS[i]);
    return { q: vol.origin.map((o, p) => o + this.k[i] * vol.dirs[L.n][p]), n: vol.unit[L.n] };
  }

  // The slice's rectangle in patient coordinates (4 corners), for the 3D view.
  corners(i) {
    const vol = this.vol, L = layout(vol, VIEWS[i]), { q } = this.plane(i);
    const ea = vol.dirs[L.a].map((x) => x * (vol.dims[L.a] - 1)), eb = vol.dirs[L.b].map((x) => x * (vol.dims[L.b] - 1));
    return [[0, 0], [1, 0], [1, 1], [0, 1]].map(([s, t]) => q.map((x, p) => x + s * ea[p] + t * eb[p]));
  }

  // The volume's box (min and max corners, patient coordinates), for framing the 3D view.
  box() {
    const vol = this.vol, lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let c = 0; c < 8; c++) {
      const p = vol.origin.map((o, q) => o + [0, 1, 2].reduce((s, a) => s + ((c >> a) & 1) * (vol.dims[a] - 1) * vol.dirs[a][q], 0));
      p.forEach((x, q) => { lo[q] = Math.min(lo[q], x); hi[q] = Math.max(hi[q], x); });
    }
    return [lo, hi];
  }

  // Draws view i (every view when undefined): the image, then the models' cut lines.
  draw(which) {
    VIEWS.forEach((view, i) => {
      if (which !== undefined && which !== i) return;
      const c = this.els.canvases[i], w = c.clientWidth, h = c.clientHeight, dpr = Math.min(window.devicePixelRatio || 1, 2);
      if (!w || !h) return;
      c.width = Math.round(w * dpr), c.height = Math.round(h * dpr);
      const g = c.getContext("2d");
      g.setTransform(dpr, 0, 0, dpr, 0, 0);
      g.fillStyle = "#000";
      g.fillRect(0, 0, w, h);
      if (!this.vol) { this.lines[i] = 0; return; }
      const geo = this.geometry(i, w, h);
      g.imageSmoothingEnabled = true;
      g.drawImage(this.images[i], geo.dx, geo.dy, geo.L.w * geo.sa, geo.L.h * geo.sb);
      this.lines[i] = this.cut(i, g, geo);
      g.fillStyle = view.colour;
      g.font = "12px system-ui, sans-serif";
      g.fillText(view.label + " " + (this.k[i] + 1) + "/" + this.vol.dims[geo.L.n], 6, 16);
      c.dataset.slice = this.k[i];
      c.dataset.lines = this.lines[i];
    });
  }

  // The models' triangles cut by view i's plane, drawn as segments in their colours: how many.
  cut(i, g, geo) {
    const vol = this.vol, { q, n } = this.plane(i), L = geo.L;
    const ua = vol.unit[L.a], ub = vol.unit[L.b], o = vol.origin;
    const toX = (p) => { let t = ((p[0] - o[0]) * ua[0] + (p[1] - o[1]) * ua[1] + (p[2] - o[2]) * ua[2]) / vol.spacing[L.a];
      if (L.flipA) t = L.w - 1 - t; return geo.dx + (t + 0.5) * geo.sa; };
    const toY = (p) => { let t = ((p[0] - o[0]) * ub[0] + (p[1] - o[1]) * ub[1] + (p[2] - o[2]) * ub[2]) / vol.spacing[L.b];
      if (L.flipB) t = L.h - 1 - t; return geo.dy + (t + 0.5) * geo.sb; };
    const dq = n[0] * q[0] + n[1] * q[1] + n[2] * q[2];
    let segments = 0;
    g.lineWidth = 1.5;
    for (const m of this.meshes()) {
      const P = m.position, d = [0, 0, 0], pts = [];
      g.strokeStyle = m.colour;
      g.beginPath();
      for (let t = 0; t < m.count; t++) {
        const o9 = 9 * t;
        for (let k = 0; k < 3; k++) d[k] = n[0] * P[o9 + 3 * k] + n[1] * P[o9 + 3 * k + 1] + n[2] * P[o9 + 3 * k + 2] - dq;
        const s0 = d[0] >= 0, s1 = d[1] >= 0, s2 = d[2] >= 0;
        if (s0 === s1 && s1 === s2) continue;
        pts.length = 0;
        for (const [a, b] of [[0, 1], [1, 2], [2, 0]]) {
          if ((d[a] >= 0) === (d[b] >= 0)) continue;
          const f = d[a] / (d[a] - d[b]), A = o9 + 3 * a, B = o9 + 3 * b;
          pts.push([P[A] + f * (P[B] - P[A]), P[A + 1] + f * (P[B + 1] - P[A + 1]), P[A + 2] + f * (P[B + 2] - P[A + 2])]);
        }
        g.moveTo(toX(pts[0]), toY(pts[0]));
        g.lineTo(toX(pts[1]), toY(pts[1]));
        segments++;
      }
      g.stroke();
    }
    return segments;
  }

  stats() {
    return this.vol ? { dims: this.vol.dims, type: this.vol.type, slices: this.k.slice(), window: this.win, level: this.lev,
      lines: this.lines.slice(), preset: this.els.preset.value } : null;
  }
}
