// live.js - live isosurfaces (issue 46): an isosurface model's iso moved by a slider, its samples
// painted or erased by a spherical brush, the last changes undone; the surface follows each change
// by its mesh delta (GET /models/{id}/mesh?format=delta&since=V, the whole mesh again only on 410),
// never by downloading the mesh again. It keeps the page's copy of the model's samples (GET
// /models/{id}/volume) in step with every edit it sends, so that a stroke and its undo are the
// samples of their block. No three.js: view.js hands it the model's slots, the picking and the
// frame; the DOM it touches is the #live fieldset's controls. Bundled into view.js.
//
// Every change of the model (an iso, a stroke, an undo) and the delta after it run one at a time
// in the order they were asked (run()): at most one request in flight, and the version the view
// holds is the one the next delta starts from. Iso values coalesce: while one is in flight only
// the last value asked waits, the ones between are never sent.

const UNDO_MAX = 50;             // the changes that can be undone (strokes and iso changes)
const UNDO_BYTES = 64 << 20;     // the old samples they keep at most: the oldest let go first
const BRUSH_MIN_MM = 0.1, BRUSH_MAX_MM = 200; // the brush's radius bounds
const REGION_MAX = 1 << 24;      // samples one stroke writes at most (32 MB of int16): a larger one is refused here

const TYPED = { uint8: Uint8Array, int16: Int16Array, uint16: Uint16Array, float: Float32Array, float32: Float32Array };

// The 3x3 inverse of rows (a grid's space directions: patient = origin + index . rows).
function inverse3(m) {
  const [a, b, c] = m, det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
  if (!det) throw new Error("the grid's space directions are singular");
  const r = [[b[1] * c[2] - b[2] * c[1], a[2] * c[1] - a[1] * c[2], a[1] * b[2] - a[2] * b[1]],
    [b[2] * c[0] - b[0] * c[2], a[0] * c[2] - a[2] * c[0], a[2] * b[0] - a[0] * b[2]],
    [b[0] * c[1] - b[1] * c[0], a[1] * c[0] - a[0] * c[1], a[0] * b[1] - a[1] * b[0]]];
  return r.map((row) => row.map((x) => x / det));
}

// The exact least and greatest sample (the iso route's bounds: a value outside them is a 422).
export function sampleRange(data) {
  let lo = Infinity, hi = -Infinity;
  for (let i = 0; i < data.length; i++) { const v = data[i]; if (v < lo) lo = v; if (v > hi) hi = v; }
  return [lo, hi];
}

// A brush stroke's block of samples: the spheres of radius r (mm) around centres (patient
// coordinates) painted ("paint": samples raised, the surface grows to the spheres) or erased
// ("erase": lowered, it shrinks away from them), as a ramp of slope (range) / (finest spacing)
// through the iso at distance r, so that the new surface lies on the spheres to within the
// extraction's interpolation, not on voxel steps. Samples only ever move the stroke's way
// (max/min with what they were), stay within [lo, hi] and are rounded for integer types.
// -> {region: [x0,y0,z0,nx,ny,nz], old, next (typed arrays of the block, x fastest)}, or null
// when the spheres miss the grid.
export function strokeBlock(vol, centres, r, mode, iso, [lo, hi]) {
  const { dims, dirs, origin, data } = vol, inv = inverse3(dirs);
  // index = (p - origin) . inv: a sphere's half-extent along index a is r times column a's length
  const half = [0, 1, 2].map((a) => r * Math.hypot(inv[0][a], inv[1][a], inv[2][a]));
  const from = [Infinity, Infinity, Infinity], to = [-Infinity, -Infinity, -Infinity];
  const h = Math.min(...vol.spacing), pad = 1; // (the ramp reaches one finest spacing past r)
  for (const c of centres) {
    const d = [0, 1, 2].map((q) => c[q] - origin[q]);
    for (let a = 0; a < 3; a++) {
      const t = d[0] * inv[0][a] + d[1] * inv[1][a] + d[2] * inv[2][a];
      from[a] = Math.min(from[a], Math.floor(t - half[a]) - pad), to[a] = Math.max(to[a], Math.ceil(t + half[a]) + pad);
    }
  }
  for (let a = 0; a < 3; a++) from[a] = Math.max(0, from[a]), to[a] = Math.min(dims[a] - 1, to[a]);
  if (from.some((x, a) => x > to[a])) return null;
  const n = [0, 1, 2].map((a) => to[a] - from[a] + 1), count = n[0] * n[1] * n[2];
  if (count > REGION_MAX) throw new Error("a stroke of " + count + " samples: more than " + REGION_MAX + "; a smaller radius");
  const T = data.constructor, old = new T(count), next = new T(count), int = !(data instanceof Float32Array);
  const paint = mode === "paint", slope = (paint ? hi - iso : iso - lo) / h; // value per mm of the ramp
  const sx = dims[0], sxy = dims[0] * dims[1];
  let o = 0;
  for (let z = 0; z < n[2]; z++)
    for (let y = 0; y < n[1]; y++) {
      const base = (from[2] + z) * sxy + (from[1] + y) * sx + from[0];
      for (let x = 0; x < n[0]; x++, o++) {
        const s = data[base + x];
        old[o] = s;
        const i = from[0] + x, j = from[1] + y, k = from[2] + z;
        const px = origin[0] + i * dirs[0][0] + j * dirs[1][0] + k * dirs[2][0];
        const py = origin[1] + i * dirs[0][1] + j * dirs[1][1] + k * dirs[2][1];
        const pz = origin[2] + i * dirs[0][2] + j * dirs[1][2] + k * dirs[2][2];
        let d2 = Infinity;
        for (const c of centres) d2 = Math.min(d2, (px - c[0]) ** 2 + (py - c[1]) ** 2 + (pz - c[2]) ** 2);
        const into = r - Math.sqrt(d2); // mm inside the nearest sphere (negative outside)
        let v = s;
        if (into > -h) {
          let t = paint ? iso + into * slope : iso - into * slope;
          t = t < lo ? lo : t > hi ? hi : t;
          v = paint ? Math.max(s, t) : Math.min(s, t);
          if (int) v = paint ? Math.ceil(v) : Math.floor(v); // (rounded the stroke's way: the surface reaches r)
        }
        next[o] = v;
      }
    }
  return { region: [from[0], from[1], from[2], n[0], n[1], n[2]], old, next };
}

// Writes a block (x fastest) into the samples at region.
export function putBlock(vol, [x0, y0, z0, nx, ny, nz], block) {
  const sx = vol.dims[0], sxy = vol.dims[0] * vol.dims[1];
  for (let z = 0, o = 0; z < nz; z++)
    for (let y = 0; y < ny; y++, o += nx) vol.data.set(block.subarray(o, o + nx), (z0 + z) * sxy + (y0 + y) * sx + x0);
}

// The controller of the #live fieldset. hooks (view.js's): result(method, path, opts) (a job
// route's answer, rejecting with .status), samples(id) (the model's parsed NRRD, shared with the
// slice views when they show it), delta(m, arrayBuffer) (applies a delta to the model's slots and
// the GPU), reload(m) (its whole mesh again, since=0), mark(stroke) (the next frame's time into
// stroke.frame), cursor(radius|null) (the brush's sphere), changed() (the samples changed: the
// slices repaint).
export class LiveIso {
  constructor(els, hooks) {
    this.els = els, this.hooks = hooks;
    this.m = null, this.vol = null, this.range = null, this.iso = NaN, this.candidates = [];
    this.undoStack = [], this.queue = [], this.busy = false, this.wantIso = null, this.isoQueued = false, this.gesture = null;
    this.counts = { deltas: 0, reloads: 0, edits: 0, isos: 0, undos: 0, failed: 0 };
    this.strokes = [], this.isoTimes = []; // the last strokes' and iso changes' times (the bench's): {t0, sent, answered, applied, frame, how}
    this.loading = null;
    const e = els;
    // a drag's values on the slider's step (whole HU on a CT, not 883.8977); keys and typed values as they are
    const snap = (v) => Math.round(v / this.step) * this.step;
    e.range.addEventListener("input", () => this.slide(snap(+e.range.value), false));
    e.range.addEventListener("change", () => this.slide(snap(+e.range.value), true));
    // keys step by the slider's own step (its step is "any", so that the model's iso, whatever it
    // is, sits on it): arrows one, Page Up/Down ten, Home and End the ends
    e.range.addEventListener("keydown", (ev) => {
      if (!this.vol) return;
      const k = { ArrowRight: 1, ArrowUp: 1, ArrowLeft: -1, ArrowDown: -1, PageUp: 10, PageDown: -10 }[ev.key];
      const [lo, hi] = this.range;
      let v;
      if (k !== undefined) v = this.target + k * this.step;
      else if (ev.key === "Home") v = lo;
      else if (ev.key === "End") v = hi;
      else return;
      ev.preventDefault();
      this.gesture = null;
      this.slide(v, true);
    });
    e.value.addEventListener("change", () => { const v = +e.value.value; if (e.value.value.trim() !== "" && Number.isFinite(v)) this.slide(v, true); });
    e.mode.addEventListener("change", () => this.hooks.cursor(this.brushOn() ? this.radius() : null));
    e.radius.addEventListener("change", () => this.hooks.cursor(this.brushOn() ? this.radius() : null));
    e.undo.addEventListener("click", () => this.undo());
    e.model.addEventListener("change", () => this.choose(e.model.value));
  }

  // The view's models changed: the isosurface models of samples among them can be edited (the
  // first, or the one chosen before, is).
  attach(models) {
    this.candidates = models.filter((m) => m.res.source === "isosurface" && m.res.grid && m.res.label === undefined && m.slots);
    const e = this.els;
    e.box.hidden = !this.candidates.length;
    e.model.replaceChildren(...this.candidates.map((m) => {
      const o = document.createElement("option");
      o.value = m.res.id, o.textContent = m.res.name || m.res.id;
      return o;
    }));
    e.modelRow.hidden = this.candidates.length < 2;
    const keep = this.m && this.candidates.find((m) => m === this.m);
    if (keep) { e.model.value = keep.res.id; this.show(); return; }
    this.m = null, this.vol = null;
    if (this.candidates.length) this.choose(this.candidates[0].res.id);
    else this.hooks.cursor(null);
  }

  // Edits go to model id from now on: its samples are read (or shared with the slices), the
  // slider spans their range, the undo history starts empty.
  async choose(id, fresh = false) {
    const m = this.candidates.find((x) => x.res.id === id);
    if (!m) return;
    if (m !== this.m && !fresh) this.els.mode.value = "off"; // (another model: no brush until asked for)
    this.m = m, this.vol = null, this.range = null, this.iso = this.target = m.res.iso, this.undoStack = [], this.wantIso = null;
    this.els.model.value = id;
    this.counts = { deltas: 0, reloads: 0, edits: 0, isos: 0, undos: 0, failed: 0 }, this.strokes = [], this.isoTimes = [];
    this.enable(false);
    this.say("reading the samples…");
    const load = (this.loading = this.hooks.samples(id, fresh));
    let vol;
    try {
      vol = await load;
    } catch (e) {
      if (this.m === m) this.say("no samples, so no iso slider or brush: " + e.message);
      return;
    }
    if (this.m !== m || this.loading !== load) return;
    this.vol = vol;
    this.range = sampleRange(vol.data);
    const [lo, hi] = this.range, r = this.els.range, int = !(vol.data instanceof Float32Array);
    this.step = int && hi - lo >= 200 ? 1 : +((hi - lo) / 1000 || 1).toPrecision(3);
    r.min = String(lo), r.max = String(hi), r.step = "any";
    this.els.value.min = String(lo), this.els.value.max = String(hi);
    this.enable(true);
    this.show();
    this.say("");
    this.hooks.cursor(this.brushOn() ? this.radius() : null);
  }

  enable(on) {
    for (const el of [this.els.range, this.els.value, this.els.mode, this.els.radius]) el.disabled = !on;
    this.els.undo.disabled = !on || !this.undoStack.length;
  }

  brushOn() { return !!this.vol && this.els.mode.value !== "off"; }

  radius() {
    const r = +this.els.radius.value;
    return Number.isFinite(r) ? Math.min(BRUSH_MAX_MM, Math.max(BRUSH_MIN_MM, r)) : 5;
  }

  // The radius by a factor ([ and ] on the view), kept to a tenth of a mm.
  scaleRadius(k) {
    this.els.radius.value = String(+Math.min(BRUSH_MAX_MM, Math.max(BRUSH_MIN_MM, this.radius() * k)).toFixed(1));
    this.hooks.cursor(this.brushOn() ? this.radius() : null);
  }

  // The iso, the triangles the view holds and the version, as the controls show them.
  show() {
    const m = this.m, e = this.els;
    if (!m) return;
    e.name.textContent = m.res.name || m.res.id;
    if (this.vol && this.gesture === null) e.range.value = String(this.target);
    if (document.activeElement !== e.value) e.value.value = String(+this.target.toPrecision(7));
    e.count.textContent = "iso " + +this.iso.toPrecision(7) + " · " + m.slots.count.toLocaleString("en") + " triangles · version " + m.slots.version;
    e.count.dataset.triangles = m.slots.count;
    e.count.dataset.version = m.slots.version;
    e.undo.disabled = !this.vol || !this.undoStack.length;
    e.undo.textContent = this.undoStack.length ? "Undo " + this.undoStack[this.undoStack.length - 1].what : "Undo";
  }

  say(text) { this.els.state.textContent = text; }

  // ---- the changes, one at a time --------------------------------------------------------------

  // Queues fn (async) after every change asked before it.
  run(fn) {
    this.queue.push(fn);
    if (!this.busy) this.pump();
  }

  async pump() {
    this.busy = true;
    while (this.queue.length) {
      const fn = this.queue.shift();
      try {
        await fn();
      } catch (e) {
        this.counts.failed++;
        this.say(e.message);
      }
    }
    this.busy = false;
    this.show();
  }

  idle() { return !this.busy && !this.queue.length; }

  // The model's changes since the version the view holds (a delta), or its whole mesh when the
  // journal no longer reaches back that far (410). -> "delta" or "reload".
  async sync(m) {
    const since = m.slots.version;
    let r;
    try {
      r = await this.hooks.result("GET", "/models/" + m.res.id + "/mesh?format=delta&since=" + since);
    } catch (e) {
      if (e.status !== 410) throw e;
      await this.hooks.reload(m);
      this.counts.reloads++;
      return "reload";
    }
    this.hooks.delta(m, await r.arrayBuffer());
    this.counts.deltas++;
    return "delta";
  }

  // The slider moved (done: the gesture ended, a key press or the number typed): the value shown
  // at once, sent when the request before it has answered (only the last value waiting).
  slide(v, done) {
    if (!this.m || !this.vol) return;
    const [lo, hi] = this.range;
    v = Math.min(hi, Math.max(lo, v));
    if (this.gesture === null && v !== this.target) { // one undo step a gesture, back to the iso asked before it
      this.gesture = { from: this.target };
      this.remember({ kind: "iso", what: "iso " + +this.target.toPrecision(7), iso: this.target, bytes: 0 });
    }
    if (done) this.gesture = null;
    v = +v.toPrecision(7); // (a drag's values: no more digits than a person reads)
    this.els.value.value = String(v);
    this.setIso(v);
  }

  // Asks for iso v, coalesced with any value still waiting.
  setIso(v) {
    this.wantIso = this.target = v, this.wantAt = performance.now();
    if (this.isoQueued) return;
    this.isoQueued = true;
    const m = this.m;
    this.run(async () => {
      this.isoQueued = false;
      const want = this.wantIso, t = { t0: this.wantAt, iso: want };
      this.wantIso = null;
      if (want === null || want === this.iso || this.m !== m) return;
      this.say("iso " + want + "…");
      let res;
      try {
        t.sent = performance.now();
        res = await (await this.hooks.result("POST", "/models/" + m.res.id + "/iso?value=" + encodeURIComponent(want))).json();
      } catch (e) {
        if (this.wantIso === null) this.target = this.iso; // (nothing newer asked: the slider goes back)
        throw e;
      }
      t.answered = performance.now();
      m.res = res;
      this.iso = res.iso;
      this.counts.isos++;
      const how = await this.sync(m);
      t.how = how, t.applied = performance.now(), t.triangles = m.slots.count;
      this.hooks.mark(t);
      this.isoTimes.push(t);
      if (this.isoTimes.length > 100) this.isoTimes.shift();
      this.say(how === "reload" ? "iso " + res.iso + ": the whole mesh read again (the model's journal does not reach back to the view's version)" : "");
      this.show();
    });
  }

  // A brush stroke (pointer up, or Enter on the view) over these centres (patient mm): its block
  // computed from the page's samples, written into them at once (so that the next stroke builds
  // on it), sent as an edit, and the surface updated by the delta. t0: when the stroke ended.
  stroke(centres, t0 = performance.now()) {
    if (!this.brushOn() || !centres.length) return;
    const mode = this.els.mode.value, r = this.radius();
    let b;
    try {
      b = strokeBlock(this.vol, centres, r, mode, this.iso, this.range);
    } catch (e) {
      this.say(e.message);
      return;
    }
    if (!b) return;
    putBlock(this.vol, b.region, b.next);
    this.hooks.changed();
    const entry = { kind: "stroke", what: mode === "paint" ? "paint" : "erase", region: b.region, old: b.old, bytes: b.old.byteLength };
    this.remember(entry);
    const timing = { t0, mode, region: b.region, samples: b.next.length }, m = this.m;
    this.run(async () => {
      this.say(mode === "paint" ? "painting…" : "erasing…");
      await this.edit(m, b.region, b.next, timing);
      this.strokes.push(timing);
      if (this.strokes.length > 100) this.strokes.shift();
      this.say("");
    });
  }

  // One edit of the block at region: POST /models/{id}/edit, then the delta. A refused edit
  // leaves the page's samples unlike the model's: they are read again and the history dropped.
  // (m: the model the block was computed for, whichever the controls show by now)
  async edit(m, region, block, timing) {
    const t = timing || {};
    let res;
    try {
      const body = block.buffer.byteLength === block.byteLength ? block.buffer : block.slice().buffer;
      t.sent = performance.now();
      res = await (await this.hooks.result("POST", "/models/" + m.res.id + "/edit?region=" + region.join(","),
        { body, type: "application/octet-stream" })).json();
      t.answered = performance.now();
    } catch (e) {
      if (this.m !== m) throw e;
      await this.resync();
      throw new Error("the edit was refused (" + e.message + "): the samples were read again and the undo history cleared");
    }
    m.res = res;
    this.counts.edits++;
    t.how = await this.sync(m);
    t.applied = performance.now();
    t.version = m.slots.version;
    t.triangles = m.slots.count;
    if (timing) this.hooks.mark(t);
    this.show();
  }

  // The page's samples read again from the daemon (after a refused edit): the undo history, whose
  // old samples may no longer be the model's, goes with them (choose()).
  async resync() {
    this.vol = null;
    this.loading = null;
    await this.choose(this.m.res.id, true);
  }

  remember(entry) {
    this.undoStack.push(entry);
    let bytes = this.undoStack.reduce((s, x) => s + x.bytes, 0);
    while (this.undoStack.length > UNDO_MAX || (bytes > UNDO_BYTES && this.undoStack.length > 1)) bytes -= this.undoStack.shift().bytes;
    this.show();
  }

  // Undoes the last change: a stroke's block gets its old samples back (an edit), an iso change
  // its old iso. Queued after what is in flight.
  undo() {
    const entry = this.undoStack.pop();
    if (!entry || !this.m) return;
    this.gesture = null;
    this.counts.undos++;
    if (entry.kind === "iso") {
      this.range && (this.els.range.value = String(entry.iso));
      this.setIso(entry.iso);
    } else {
      putBlock(this.vol, entry.region, entry.old);
      this.hooks.changed();
      const m = this.m;
      this.run(async () => {
        this.say("undoing the " + entry.what + "…");
        await this.edit(m, entry.region, entry.old);
        this.say("");
      });
    }
    this.show();
  }

  stats() {
    const m = this.m;
    return m ? { id: m.res.id, iso: this.iso, range: this.range, triangles: m.slots.count, version: m.slots.version,
      apiVersion: m.res.version, undo: this.undoStack.length, idle: this.idle(), ready: !!this.vol, counts: { ...this.counts },
      strokes: this.strokes.map((s) => ({ ...s })), isos: this.isoTimes.map((s) => ({ ...s })) } : null;
  }
}
