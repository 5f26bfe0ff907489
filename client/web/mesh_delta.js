// mesh_delta.js - the binary mesh delta (application/vnd.surfd.mesh-delta, API.md) read into a
// growable triangle buffer: decodeDelta() parses one answer, MeshSlots keeps a model's triangles
// in a flat position/normal array with a map from triangle id to slot, so a later delta (issue 45)
// removes and adds triangles in place instead of the mesh being downloaded again. No DOM, no
// three.js: view.js hands the arrays to the GPU; the browser test drives this with a hand-made delta.

const MAGIC = 0x444d4653; // "SFMD" read little-endian
const HEAD = 20;          // magic, from_version, to_version, n_removed, n_added
const ADDED = 40;         // u32 id + 9 f32 corners
export const MAX_TRIANGLES = 1 << 26; // what one buffer may hold (the daemon's 40 M cap, rounded up)
const LITTLE = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1; // the delta's byte order is the host's

// An ArrayBuffer holding one delta -> {from, to, removed: Uint32Array, ids: Uint32Array,
// corners: Float32Array (9 a triangle)}; throws on a malformed one (what, and at which byte).
export function decodeDelta(buf) {
  const v = new DataView(buf);
  if (buf.byteLength < HEAD || v.getUint32(0, true) !== MAGIC) throw new Error("not a mesh delta (no SFMD header)");
  const from = v.getUint32(4, true), to = v.getUint32(8, true);
  const nr = v.getUint32(12, true), na = v.getUint32(16, true);
  if (nr > MAX_TRIANGLES || na > MAX_TRIANGLES || buf.byteLength !== HEAD + 4 * nr + ADDED * na)
    throw new Error("mesh delta of " + buf.byteLength + " bytes does not hold " + nr + " removals and " + na + " triangles");
  const removed = new Uint32Array(nr), ids = new Uint32Array(na), corners = new Float32Array(9 * na);
  if (LITTLE) { // (the layout's words are 4-aligned: read through views, not a getter a number)
    removed.set(new Uint32Array(buf, HEAD, nr));
    const w = new Uint32Array(buf, HEAD + 4 * nr, 10 * na), f = new Float32Array(buf, HEAD + 4 * nr, 10 * na);
    for (let k = 0; k < na; k++) {
      ids[k] = w[10 * k];
      for (let c = 0; c < 9; c++) corners[9 * k + c] = f[10 * k + 1 + c];
    }
    return { from, to, removed, ids, corners };
  }
  for (let k = 0; k < nr; k++) removed[k] = v.getUint32(HEAD + 4 * k, true);
  let p = HEAD + 4 * nr;
  for (let k = 0; k < na; k++, p += ADDED) {
    ids[k] = v.getUint32(p, true);
    for (let c = 0; c < 9; c++) corners[9 * k + c] = v.getFloat32(p + 4 + 4 * c, true);
  }
  return { from, to, removed, ids, corners };
}

// Triangle id -> slot: open addressing over typed arrays (a Map of 680 k numbers took 250 ms to
// fill, this some 30): get, has, set, delete (the entries after the hole moved back), size.
export class IdMap {
  constructor(n = 16) {
    this._make(Math.max(16, n));
  }

  _make(n) {
    let cap = 16;
    while (cap < 2 * n) cap *= 2;
    this.keys = new Uint32Array(cap), this.vals = new Int32Array(cap).fill(-1);
    this.mask = cap - 1, this.size = 0;
  }

  _home(id) { return Math.imul(id, 0x9e3779b1) >>> 0 & this.mask; }

  _find(id) {
    let h = this._home(id);
    while (this.vals[h] >= 0 && this.keys[h] !== id) h = (h + 1) & this.mask;
    return h;
  }

  get(id) { const h = this._find(id); return this.vals[h] >= 0 ? this.vals[h] : undefined; }

  has(id) { return this.vals[this._find(id)] >= 0; }

  set(id, slot) {
    if (2 * (this.size + 1) > this.keys.length) { // (grown before it is half full)
      const k = this.keys, v = this.vals;
      this._make(2 * (this.size + 1));
      for (let i = 0; i < k.length; i++) if (v[i] >= 0) this.set(k[i], v[i]);
    }
    const h = this._find(id);
    if (this.vals[h] < 0) this.size++;
    this.keys[h] = id, this.vals[h] = slot;
    return this;
  }

  delete(id) {
    let h = this._find(id);
    if (this.vals[h] < 0) return false;
    this.vals[h] = -1, this.size--;
    for (let j = (h + 1) & this.mask; this.vals[j] >= 0; j = (j + 1) & this.mask) {
      const want = this._home(this.keys[j]); // j's entry fills the hole unless its home lies cyclically in (h, j]
      if (j > h ? want <= h || want > j : want <= h && want > j) {
        this.keys[h] = this.keys[j], this.vals[h] = this.vals[j], this.vals[j] = -1, h = j;
      }
    }
    return true;
  }

}

// A model's triangles: slot s holds one triangle's 3 corners at position[9s..9s+8] and its face
// normal (repeated at each corner: flat shading, which a delta keeps right without neighbours) at
// normal[9s..]. Invariants: slots 0..count-1 are in use; idOf[s] is slot s's triangle id and
// slotOf.get(idOf[s]) === s. A removal moves the last slot into the hole, so the used slots stay
// packed (one draw range); capacity doubles when full (the caller re-uploads: `grown`).
export class MeshSlots {
  constructor(capacity = 1024) {
    this.version = 0;
    this.count = 0;
    this.slotOf = new IdMap(capacity);
    this._alloc(Math.max(1, capacity));
  }

  _alloc(cap) {
    const pos = new Float32Array(9 * cap), nrm = new Float32Array(9 * cap), id = new Uint32Array(cap);
    if (this.position) { pos.set(this.position.subarray(0, 9 * this.count)); nrm.set(this.normal.subarray(0, 9 * this.count)); id.set(this.idOf.subarray(0, this.count)); }
    this.position = pos, this.normal = nrm, this.idOf = id, this.capacity = cap;
  }

  // Applies a decoded delta: its removals first, then its additions (an id added again replaces
  // its triangle). Throws when the delta does not start at this mesh's version (the caller asks
  // again with ?since). Returns {removed, added, grown, changed: [first slot, end) touched, ranges:
  // the slots written, as sorted [first, end) ranges within the count (what the GPU needs again:
  // a change of a few hundred triangles in a large mesh is a few hundred small ranges, not the span
  // from its first hole to the end)}.
  apply(d) {
    if (d.from !== this.version) throw new Error("delta from version " + d.from + " onto version " + this.version);
    let lo = Infinity, hi = 0, removed = 0, grown = false;
    const touched = [];
    // every held triangle taken out (a new iso): the slots laid out anew, not emptied one by one
    // and their ranges sorted (on the CT head's 680 k triangles that was most of the page's second)
    let whole = this.count > 0 && d.removed.length >= this.count;
    if (whole) {
      let held = 0;
      for (const id of d.removed) held += this.slotOf.has(id) ? 1 : 0;
      whole = held === this.count;
    }
    if (whole) removed = this.count, this.count = 0;
    const anew = this.count === 0; // (every slot written from the first: one range, none sorted)
    if (anew) this.slotOf = new IdMap(d.ids.length); // (sized once, not grown by doubling)
    for (const id of whole ? [] : d.removed) {
      const s = this.slotOf.get(id);
      if (s === undefined) continue; // not held: nothing to remove
      const last = this.count - 1;
      if (s !== last) {
        this.position.copyWithin(9 * s, 9 * last, 9 * last + 9);
        this.normal.copyWithin(9 * s, 9 * last, 9 * last + 9);
        this.idOf[s] = this.idOf[last];
        this.slotOf.set(this.idOf[s], s);
        touched.push(s);
      }
      this.slotOf.delete(id);
      this.count = last;
      removed++;
      lo = Math.min(lo, s), hi = Math.max(hi, s + 1);
    }
    const n = d.ids.length;
    if (this.count + n > this.capacity) {
      if (this.count + n > MAX_TRIANGLES) throw new Error("a mesh of more than " + MAX_TRIANGLES + " triangles");
      let cap = this.capacity;
      while (cap < this.count + n) cap *= 2;
      this._alloc(Math.min(cap, MAX_TRIANGLES));
      grown = true;
    }
    for (let k = 0; k < n; k++) {
      let s = this.slotOf.get(d.ids[k]);
      if (s === undefined) s = this.count++, this.slotOf.set(d.ids[k], s), this.idOf[s] = d.ids[k];
      this._put(s, d.corners, 9 * k);
      if (!anew) touched.push(s), lo = Math.min(lo, s), hi = Math.max(hi, s + 1);
    }
    this.version = d.to;
    if (anew) return { removed, added: n, grown, changed: [0, this.count], ranges: this.count ? [[0, this.count]] : [] };
    return { removed, added: n, grown, changed: lo < hi ? [lo, hi] : [0, 0], ranges: slotRanges(touched, this.count) };
  }

  _put(s, c, o) {
    const P = this.position, N = this.normal, b = 9 * s;
    for (let i = 0; i < 9; i++) P[b + i] = c[o + i];
    const ux = c[o + 3] - c[o], uy = c[o + 4] - c[o + 1], uz = c[o + 5] - c[o + 2];
    const vx = c[o + 6] - c[o], vy = c[o + 7] - c[o + 1], vz = c[o + 8] - c[o + 2];
    let nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    const l = Math.sqrt(nx * nx + ny * ny + nz * nz) || 1; // (Math.hypot is several times slower)
    nx /= l, ny /= l, nz /= l;
    for (let i = 0; i < 3; i++) N[b + 3 * i] = nx, N[b + 3 * i + 1] = ny, N[b + 3 * i + 2] = nz;
  }

  // The corners of triangle id (9 numbers), or null: what the browser test reads back.
  corners(id) {
    const s = this.slotOf.get(id);
    return s === undefined ? null : Array.from(this.position.subarray(9 * s, 9 * s + 9));
  }
}

// Slots (unsorted, repeats allowed) as sorted [first, end) ranges below count, ranges less than
// RANGE_GAP slots apart joined (one upload of a few slots more costs less than one more call).
const RANGE_GAP = 16;
export function slotRanges(slots, count) {
  const s = Int32Array.from(slots.filter((x) => x < count)).sort(), out = [];
  for (const x of s) {
    const r = out[out.length - 1];
    if (r && x <= r[1] + RANGE_GAP) r[1] = Math.max(r[1], x + 1);
    else out.push([x, x + 1]);
  }
  return out;
}

// A delta's bytes from its parts (the browser test's hand-made deltas): removed ids, and added
// triangles as [id, [9 corners]].
export function encodeDelta(from, to, removed, added) {
  const buf = new ArrayBuffer(HEAD + 4 * removed.length + ADDED * added.length), v = new DataView(buf);
  v.setUint32(0, MAGIC, true), v.setUint32(4, from, true), v.setUint32(8, to, true);
  v.setUint32(12, removed.length, true), v.setUint32(16, added.length, true);
  let p = HEAD;
  for (const id of removed) v.setUint32(p, id, true), p += 4;
  for (const [id, c] of added) {
    v.setUint32(p, id, true);
    for (let k = 0; k < 9; k++) v.setFloat32(p + 4 + 4 * k, c[k], true);
    p += ADDED;
  }
  return buf;
}
