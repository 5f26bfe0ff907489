// mesh_delta.js - the binary mesh delta (application/vnd.surfd.mesh-delta, API.md) read into a
// growable triangle buffer: decodeDelta() parses one answer, MeshSlots keeps a model's triangles
// in a flat position/normal array with a map from triangle id to slot, so a later delta (issue 45)
// removes and adds triangles in place instead of the mesh being downloaded again. No DOM, no
// three.js: view.js hands the arrays to the GPU; the browser test drives this with a hand-made delta.

const MAGIC = 0x444d4653; // "SFMD" read little-endian
const HEAD = 20;          // magic, from_version, to_version, n_removed, n_added
const ADDED = 40;         // u32 id + 9 f32 corners
export const MAX_TRIANGLES = 1 << 26; // what one buffer may hold (the daemon's 40 M cap, rounded up)

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
  for (let k = 0; k < nr; k++) removed[k] = v.getUint32(HEAD + 4 * k, true);
  let p = HEAD + 4 * nr;
  for (let k = 0; k < na; k++, p += ADDED) {
    ids[k] = v.getUint32(p, true);
    for (let c = 0; c < 9; c++) corners[9 * k + c] = v.getFloat32(p + 4 + 4 * c, true);
  }
  return { from, to, removed, ids, corners };
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
    this.slotOf = new Map();
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
    for (const id of d.removed) {
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
      touched.push(s);
      lo = Math.min(lo, s), hi = Math.max(hi, s + 1);
    }
    this.version = d.to;
    return { removed, added: n, grown, changed: lo < hi ? [lo, hi] : [0, 0], ranges: slotRanges(touched, this.count) };
  }

  _put(s, c, o) {
    const P = this.position, N = this.normal, b = 9 * s;
    for (let i = 0; i < 9; i++) P[b + i] = c[o + i];
    const ux = c[o + 3] - c[o], uy = c[o + 4] - c[o + 1], uz = c[o + 5] - c[o + 2];
    const vx = c[o + 6] - c[o], vy = c[o + 7] - c[o + 1], vz = c[o + 8] - c[o + 2];
    let nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    const l = Math.hypot(nx, ny, nz) || 1;
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
