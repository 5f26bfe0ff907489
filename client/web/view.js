// view.js - the page's 3D view (index.html's #viewer): stored models drawn with three.js from
// their binary mesh delta, turned, zoomed and panned with mouse, touch and keys around DICOM
// patient axes (LPS: +x left, +y posterior, +z superior), and replaced by surfd's exact render of
// the same camera when the view rests; an isosurface model's live tools (live.js: the iso slider,
// the brush picked on the mesh here, undo). Bundled with three.js by esbuild into build/web/view.js
// (client/web/README.md); app.js calls it through window.surfdView once the module has run. It
// never fetches anything but the daemon's own routes, through app.js's api().
import {
  AmbientLight, BoxGeometry, BufferAttribute, BufferGeometry, CanvasTexture, Color, DirectionalLight, DoubleSide, Mesh,
  MeshBasicMaterial, MeshPhongMaterial, MOUSE, PerspectiveCamera, Raycaster, Scene, Sphere, SphereGeometry, SRGBColorSpace,
  Vector2, Vector3, WebGLRenderer,
} from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { decodeDelta, encodeDelta, IdMap, MeshSlots, slotRanges } from "./mesh_delta.js";
import { parseNrrd, SliceViews, VIEWS } from "./slices.js";
import { LiveIso, putBlock, sampleRange, strokeBlock } from "./live.js";

const REST_MS = 400;         // the view at rest this long: ask for the exact render
const FOV = 30;              // vertical, degrees: the same number goes to surfd's camera
const BACKGROUND = 0x20262e; // both pictures' (surfd's as linear RGB, below)
const KEY_TURN = Math.PI / 24, KEY_ZOOM = 1.15, KEY_PAN = 40; // radians, factor, pixels a key press
const EXACT_MAX_SIDE = 1600; // the exact render's longest side at most (pixels)
const SCENE_MAX_PATCHES = 100000; // what one scene may hold (core/trace/scene.h, SCENE_MAX_OBJECTS): not asked beyond
const BRUSH_STEP = 0.4;      // a stroke's centres at least this many radii apart (closer ones add nothing to paint)
const BRUSH_KEY_SCALE = 1.25; // [ and ] change the brush's radius by this factor
// The palette of models without an RT Structure Set colour (sRGB).
const PALETTE = [[230, 159, 0], [86, 180, 233], [0, 158, 115], [240, 228, 66], [0, 114, 178], [213, 94, 0], [204, 121, 167]];

const $ = (id) => document.getElementById(id);
const ctx = { api: null, problemOf: null };
const models = new Map(); // id -> {res, slots, geom, mesh, color: Color (linear), visible, opacity}
let renderer, axes, scene, camera, controls, cubeScene, cubeCamera, slices, volumeOf = null;
let serial = 0, restTimer = 0, exactAbort = null, exactOn = true, exactShown = false, frames = 0, drawPending = false;
let live, brush = null, cursor, marks = []; // the live tools, the brush's radius while it is on, its sphere, strokes awaiting a frame

// ---- requests --------------------------------------------------------------------------------

// A job route's answer: the body when it ends within the server's wait, else the job followed
// (GET /jobs/ID until it ends) and its result fetched. Rejects with the problem's text.
async function result(method, path, opts = {}) {
  let r = await ctx.api(method, path, opts);
  if (r.status === 202) {
    const loc = r.headers.get("Location") || "/jobs/" + (await r.json()).id;
    for (let wait = 100; ; wait = Math.min(1000, wait * 1.5)) {
      await new Promise((res) => setTimeout(res, wait));
      if (opts.signal && opts.signal.aborted) {
        ctx.api("POST", loc + "/cancel").catch(() => {});
        throw new DOMException("aborted", "AbortError");
      }
      const j = await ctx.api("GET", loc, { signal: opts.signal });
      if (!j.ok) throw new Error(await ctx.problemOf(j));
      const job = await j.json();
      if (job.state === "succeeded") break;
      if (job.state === "failed" || job.state === "cancelled") throw new Error(job.error ? job.error.detail || job.error.title : job.state);
    }
    r = await ctx.api("GET", loc + "/result", { signal: opts.signal });
  }
  if (!r.ok) throw Object.assign(new Error(await ctx.problemOf(r)), { status: r.status });
  return r;
}

// ---- the scene -------------------------------------------------------------------------------

function colourOf(res, k) {
  const c = Array.isArray(res.roi_display_color) && res.roi_display_color.length === 3 ? res.roi_display_color : PALETTE[k % PALETTE.length];
  return new Color().setRGB(c[0] / 255, c[1] / 255, c[2] / 255, SRGBColorSpace); // kept linear
}

function letterTexture(text) {
  const c = document.createElement("canvas");
  c.width = c.height = 128;
  const g = c.getContext("2d");
  g.fillStyle = "#dfe6ee";
  g.fillRect(0, 0, 128, 128);
  g.strokeStyle = "#5a6270";
  g.lineWidth = 6;
  g.strokeRect(3, 3, 122, 122);
  g.fillStyle = "#1b1f24";
  g.font = "bold 80px system-ui, sans-serif";
  g.textAlign = "center";
  g.textBaseline = "middle";
  g.fillText(text, 64, 68);
  const t = new CanvasTexture(c);
  t.colorSpace = SRGBColorSpace;
  return t;
}

// The orientation cube, on a canvas of its own over both pictures: its faces named by the patient
// side they face (BoxGeometry's face order +x, -x, +y, -y, +z, -z; LPS: +x left, +y posterior, +z
// superior).
function makeCube() {
  axes = new WebGLRenderer({ canvas: $("axes"), antialias: true, alpha: true });
  axes.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  cubeScene = new Scene();
  const cube = new Mesh(new BoxGeometry(1, 1, 1), ["L", "R", "P", "A", "S", "I"].map((s) => new MeshBasicMaterial({ map: letterTexture(s) })));
  cubeScene.add(cube);
  cubeCamera = new PerspectiveCamera(FOV, 1, 0.1, 10);
}

function init(opts) {
  ctx.api = opts.api;
  ctx.problemOf = opts.problemOf;
  const canvas = $("gl");
  renderer = new WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.setClearColor(BACKGROUND);
  scene = new Scene();
  camera = new PerspectiveCamera(FOV, 4 / 3, 0.1, 1e5);
  camera.up.set(0, 0, 1); // superior up, before the controls read it
  scene.add(camera);
  // surfd's default lights, in the camera's frame: a key light from the upper left behind the
  // viewer (0.85) and a head light (0.25), ambient 0.12 (core/trace/render.c)
  const key = new DirectionalLight(0xffffff, 0.85 * Math.PI);
  key.position.set(-0.6, 0.9, 0.7);
  const head = new DirectionalLight(0xffffff, 0.25 * Math.PI);
  head.position.set(0, 0, 1);
  camera.add(key, key.target, head, head.target);
  scene.add(new AmbientLight(0xffffff, 0.12 * Math.PI));
  makeCube();
  slices = new SliceViews({ canvases: VIEWS.map((v) => $("slice-" + v.name)), ranges: VIEWS.map((v) => $("slice-" + v.name + "-k")),
    preset: $("wl-preset"), window: $("wl-window"), level: $("wl-level"), caption: $("slices-caption") }, cutMeshes, planes);
  $("slices-close").addEventListener("click", closeVolume);
  controls = new OrbitControls(camera, canvas);
  controls.addEventListener("change", moved);
  canvas.addEventListener("keydown", keys);
  new ResizeObserver(resize).observe($("stage"));
  $("exact-toggle").addEventListener("click", () => setExact(!exactOn));
  $("view-reset").addEventListener("click", () => { reset(); canvas.focus(); });
  initLive(canvas);
  resize();
}

function resize() {
  const s = $("stage"), w = s.clientWidth, h = s.clientHeight;
  if (!w || !h) return;
  renderer.setSize(w, h, true);
  const c = Math.round(Math.max(48, Math.min(96, w / 6)));
  axes.setSize(c, c, true);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  moved();
}

// Draws one WebGL frame: the models, then the orientation cube in the lower right corner.
function draw() {
  const w = renderer.domElement.clientWidth, h = renderer.domElement.clientHeight;
  const d = camera.position.distanceTo(controls.target), r = radius();
  camera.near = Math.max(d - 2 * r, d / 1000, 1e-3);
  camera.far = d + 2 * r;
  camera.updateProjectionMatrix();
  renderer.render(scene, camera);
  cubeCamera.position.set(0, 0, 3.2).applyQuaternion(camera.quaternion);
  cubeCamera.quaternion.copy(camera.quaternion);
  axes.render(cubeScene, cubeCamera);
  frames++;
  scaleBar(d, h);
  planes();
  if (marks.length) { // strokes whose delta this frame shows: the frame is up at the next one's start
    const done = marks;
    marks = [];
    requestAnimationFrame(() => { const t = performance.now(); for (const m of done) m.frame = t; });
  }
}

function requestDraw() {
  if (renderer && !drawPending) drawPending = true, requestAnimationFrame(() => { drawPending = false; draw(); });
}

// The slice views' planes over both pictures (a 2D canvas of its own, so that the exact render
// keeps them): each slice's rectangle in its view's colour.
function planes() {
  const c = $("planes"), w = c.clientWidth, h = c.clientHeight;
  if (!w || !h) return;
  const dpr = Math.min(window.devicePixelRatio || 1, 2);
  if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) c.width = Math.round(w * dpr), c.height = Math.round(h * dpr);
  const g = c.getContext("2d");
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, w, h);
  if (!slices || !slices.vol || !camera) return;
  camera.updateMatrixWorld();
  VIEWS.forEach((view, i) => {
    const pts = slices.corners(i).map((p) => new Vector3(...p).project(camera));
    if (pts.some((p) => p.z < -1 || p.z > 1)) return; // (behind the camera)
    g.beginPath();
    pts.forEach((p, k) => g[k ? "lineTo" : "moveTo"](((p.x + 1) / 2) * w, ((1 - p.y) / 2) * h));
    g.closePath();
    g.fillStyle = view.colour + "22";
    g.fill();
    g.strokeStyle = view.colour;
    g.lineWidth = 1.5;
    g.stroke();
  });
}

// The visible models' triangles, for the slices' cut lines.
function cutMeshes() {
  return [...models.values()].filter((m) => m.visible && m.slots && m.slots.count)
    .map((m) => ({ colour: "#" + m.color.getHexString(SRGBColorSpace), position: m.slots.position, count: m.slots.count }));
}

// Opens a volume's samples in the slice views: what (a "model" or "series"), its id, a name.
async function openVolume(what, id, name) {
  $("slices").hidden = false;
  $("viewer").hidden = false;
  $("slices-name").textContent = name || id;
  $("slices-caption").textContent = "loading the samples…";
  let vol = null;
  if (what === "model" && live.m && live.m.res.id === id) // (the live tools' copy: one, kept in step)
    vol = live.vol || (live.loading ? await live.loading.catch(() => null) : null);
  if (!vol) {
    const r = await ctx.api("GET", (what === "series" ? "/series/" : "/models/") + encodeURIComponent(id) + "/volume");
    if (!r.ok) {
      const why = await ctx.problemOf(r);
      $("slices-caption").textContent = "no samples: " + why;
      throw new Error(why);
    }
    vol = parseNrrd(await r.arrayBuffer());
  }
  volumeOf = { what, id, name };
  address();
  slices.open(vol, name || id);
  if (!models.size) reset();
  else moved();
  return slices.stats();
}

function closeVolume() {
  volumeOf = null;
  address();
  slices.close();
  $("slices").hidden = true;
  if (!models.size) $("viewer").hidden = true;
  moved();
}

// A bar of a round length in mm, as long as that is at the centre of turning.
function scaleBar(d, h) {
  const mmPerPx = (2 * d * Math.tan((FOV * Math.PI) / 360)) / h;
  const want = 120 * mmPerPx, p = Math.pow(10, Math.floor(Math.log10(want)));
  const mm = [5, 2, 1].map((k) => k * p).find((x) => x <= want) || p;
  const bar = $("scale");
  bar.querySelector("span").style.width = Math.round(mm / mmPerPx) + "px";
  bar.querySelector("b").textContent = (mm >= 1 ? mm.toFixed(0) : mm.toPrecision(1)) + " mm";
  bar.dataset.mm = mm;
  bar.dataset.px = (mm / mmPerPx).toFixed(1);
}

// The bounding sphere of the visible models (of all when none is visible).
function bounds() {
  const s = new Sphere();
  let any = false;
  if (slices && slices.vol && !models.size) {
    const [lo, hi] = slices.box(), c = new Vector3(...lo).add(new Vector3(...hi)).multiplyScalar(0.5);
    return new Sphere(c, Math.max(1, c.distanceTo(new Vector3(...hi))));
  }
  for (const m of models.values()) {
    if (!m.geom || (!m.visible && [...models.values()].some((x) => x.visible))) continue;
    if (!m.geom.boundingSphere) m.geom.computeBoundingSphere();
    if (!any) s.copy(m.geom.boundingSphere), any = true;
    else s.union(m.geom.boundingSphere);
  }
  return any ? s : new Sphere(new Vector3(), 100);
}

function radius() { return Math.max(bounds().radius, 1e-3); }

// Frames the visible models from the patient's front, a little from the right and above
// (superior up); Home and "Reset view" come back here.
function reset() {
  const s = bounds(), d = (1.15 * s.radius) / Math.sin((FOV * Math.PI) / 360);
  controls.target.copy(s.center);
  camera.position.copy(s.center).add(new Vector3(-0.35, -1, 0.3).normalize().multiplyScalar(d));
  camera.up.set(0, 0, 1);
  controls.update();
  moved();
}

// Keyboard: arrows turn, shift+arrows pan, + and - zoom, Home resets (the canvas has the focus).
function keys(ev) {
  const k = ev.key, turn = { ArrowLeft: [1, 0], ArrowRight: [-1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] }[k];
  if (turn && ev.shiftKey) controls.pan(-turn[0] * KEY_PAN, turn[1] * KEY_PAN);
  else if (turn) {
    if (turn[0]) controls.rotateLeft(turn[0] * KEY_TURN);
    else controls.rotateUp(turn[1] * KEY_TURN);
  } else if (k === "+" || k === "=") controls.dollyIn(1 / KEY_ZOOM); // (OrbitControls: a scale below 1 is nearer)
  else if (k === "-" || k === "_") controls.dollyOut(1 / KEY_ZOOM);
  else if (k === "Home") reset();
  else if (brush !== null && (k === "Enter" || k === " ")) { // a stroke at the surface under the view's centre
    const p = pick(0, 0);
    if (p) live.stroke([p]);
    else live.say("no surface at the view's centre: turn or pan it there");
  } else if (brush !== null && (k === "[" || k === "]")) live.scaleRadius(k === "]" ? BRUSH_KEY_SCALE : 1 / BRUSH_KEY_SCALE);
  else return;
  ev.preventDefault();
  controls.update();
}

// ---- the exact render at rest -----------------------------------------------------------------

// The camera moved (or the models or the size changed): a WebGL frame now, the exact picture
// hidden and asked for again once nothing has moved for REST_MS.
function moved() {
  serial++;
  if (exactAbort) exactAbort.abort(), exactAbort = null;
  clearTimeout(restTimer);
  showExact(false);
  if (!renderer) return;
  requestDraw();
  if (exactOn && brush === null && [...models.values()].some((m) => m.visible && m.geom)) restTimer = setTimeout(exact, REST_MS);
  else caption(!models.size ? "" : brush !== null ? "brush on: the WebGL view (the exact render comes back when the brush is off)"
    : exactOn ? "" : "WebGL view (exact render off)");
}

function vec(v) { return [v.x, v.y, v.z].map((x) => +x.toPrecision(9)); }

// The same camera for surfd (API.md §Scene: fov vertical, up orthogonal to the view): the picture
// lines up with the WebGL frame pixel for pixel.
function exactScene(w, h) {
  const up = new Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
  const bg = new Color(BACKGROUND);
  const objects = [...models.values()].filter((m) => m.visible && m.geom)
    .map((m) => ({ type: "model", id: m.res.id, material: { color: [m.color.r, m.color.g, m.color.b].map((x) => +x.toFixed(5)) } }));
  return { image: { width: w, height: h, background: [bg.r, bg.g, bg.b].map((x) => +x.toFixed(5)) },
    camera: { eye: vec(camera.position), target: vec(controls.target), up: vec(up), fov_deg: FOV }, objects };
}

async function exact() {
  const my = serial, el = renderer.domElement;
  const patches = [...models.values()].filter((m) => m.visible).reduce((n, m) => n + (m.res.patches || 0), 0);
  if (patches > SCENE_MAX_PATCHES) {
    caption("no exact render: the visible models have " + patches + " patches, more than the " + SCENE_MAX_PATCHES +
      " one render takes; hide some (the WebGL view stays)");
    return;
  }
  let w = el.clientWidth, h = el.clientHeight;
  const k = Math.min(1, EXACT_MAX_SIDE / Math.max(w, h));
  w = Math.max(1, Math.round(w * k)), h = Math.max(1, Math.round(h * k));
  const ctl = new AbortController();
  exactAbort = ctl;
  caption("exact render…");
  const t0 = performance.now();
  try {
    const body = JSON.stringify(exactScene(w, h));
    const r = await result("POST", "/render", { body, type: "application/json", signal: ctl.signal });
    const blob = await r.blob();
    if (my !== serial) return;
    const img = $("exact"), url = URL.createObjectURL(blob);
    await new Promise((res, rej) => { img.onload = res; img.onerror = () => rej(new Error("the exact render is not an image")); img.src = url; });
    if (img.dataset.url) URL.revokeObjectURL(img.dataset.url);
    img.dataset.url = url;
    if (my !== serial) return;
    img.dataset.serial = my;
    showExact(true);
    const ms = r.headers.get("X-Render-Ms");
    caption("exact render: " + Math.round(performance.now() - t0) + " ms" + (ms ? " (tracing " + Math.round(+ms) + " ms)" : ""));
  } catch (e) {
    if (e.name !== "AbortError" && my === serial) caption("no exact render: " + e.message + " (the WebGL view stays)");
  } finally {
    if (exactAbort === ctl) exactAbort = null;
  }
}

function showExact(on) {
  exactShown = on && exactOn;
  $("exact").hidden = !exactShown;
  $("stage").dataset.showing = exactShown ? "exact" : "webgl";
}

function setExact(on) {
  exactOn = on;
  const b = $("exact-toggle");
  b.setAttribute("aria-pressed", String(on));
  b.textContent = on ? "Exact at rest: on" : "Exact at rest: off";
  moved();
}

function caption(text) { $("view-caption").textContent = text; }

// ---- models ------------------------------------------------------------------------------------

// Loads a model's whole mesh (since=0) into its slots and the GPU.
async function load(m) {
  const r = await result("GET", "/models/" + m.res.id + "/mesh?format=delta&since=0");
  const d = decodeDelta(await r.arrayBuffer());
  m.slots = new MeshSlots(Math.max(1, d.ids.length));
  m.slots.apply(d);
  upload(m, true);
}

// The slots into the model's geometry: new attributes when they grew, else the slot ranges changed.
function upload(m, fresh, ranges) {
  const s = m.slots;
  if (fresh || !m.geom) {
    if (m.geom) m.geom.dispose();
    m.geom = new BufferGeometry();
    m.geom.setAttribute("position", new BufferAttribute(s.position, 3));
    m.geom.setAttribute("normal", new BufferAttribute(s.normal, 3));
    if (!m.mesh) {
      m.mesh = new Mesh(m.geom, new MeshPhongMaterial({ color: m.color, specular: 0x4d4d4d, shininess: 40, side: DoubleSide }));
      scene.add(m.mesh);
    } else m.mesh.geometry = m.geom;
  } else if (ranges && ranges.length) {
    for (const a of [m.geom.attributes.position, m.geom.attributes.normal]) {
      a.clearUpdateRanges();
      for (const [lo, hi] of ranges) a.addUpdateRange(9 * lo, 9 * (hi - lo));
      a.needsUpdate = true;
    }
  }
  m.geom.setDrawRange(0, 3 * s.count);
  m.geom.boundingSphere = null;
  style(m);
  const lab = document.querySelector("#layers li[data-id='" + m.res.id + "'] label");
  if (lab) lab.textContent = layerText(m);
  if (slices) slices.draw();
}

// A later delta onto a loaded model (issue 45's edits): removals and additions in place.
function deltaInto(m, buf) {
  const out = m.slots.apply(decodeDelta(buf));
  upload(m, out.grown, out.ranges);
  moved();
  return out;
}

function applyDelta(id, buf) {
  const m = models.get(id);
  if (!m || !m.slots) throw new Error("model " + id + " is not in the view");
  return deltaInto(m, buf);
}

function style(m) {
  if (!m.mesh) return;
  m.mesh.visible = m.visible;
  m.mesh.material.opacity = m.opacity;
  m.mesh.material.transparent = m.opacity < 1;
  m.mesh.material.depthWrite = m.opacity >= 1;
  m.mesh.renderOrder = m.opacity < 1 ? 1 : 0;
}

// Opens these model resources in the view (replacing what it showed unless add), loads their
// meshes, frames them and names them in the page's address (#models=ID,ID).
async function open(list, { add = false } = {}) {
  if (!add) {
    for (const m of models.values()) if (m.mesh) scene.remove(m.mesh), m.geom.dispose(), m.mesh.material.dispose();
    models.clear();
  }
  const fresh = [];
  for (const res of list) {
    if (models.has(res.id)) continue;
    const m = { res, slots: null, geom: null, mesh: null, color: colourOf(res, models.size), visible: true, opacity: 1 };
    models.set(res.id, m);
    fresh.push(m);
  }
  $("viewer").hidden = false;
  $("viewer-name").textContent = [...models.values()].map((m) => m.res.name || m.res.id).join(", ");
  address();
  layers();
  live.attach([...models.values()]);
  moved();
  caption("loading " + fresh.length + " mesh" + (fresh.length === 1 ? "" : "es") + "…");
  const failed = [];
  await Promise.all(fresh.map((m) => load(m).catch((e) => failed.push((m.res.name || m.res.id) + ": " + e.message))));
  for (const m of fresh) if (!m.geom && models.get(m.res.id) === m) models.delete(m.res.id);
  layers();
  live.attach([...models.values()]);
  reset();
  if (failed.length) caption("could not load " + failed.join("; "));
  return failed;
}

// The list of models in the view: each with its colour, visibility and opacity.
function layers() {
  const ul = $("layers");
  ul.replaceChildren(...[...models.values()].map((m) => {
    const li = document.createElement("li"), name = m.res.name || m.res.id;
    li.dataset.id = m.res.id;
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = "#" + m.color.getHexString(SRGBColorSpace);
    const vis = document.createElement("input");
    vis.type = "checkbox";
    vis.checked = m.visible;
    vis.id = "vis-" + m.res.id;
    vis.addEventListener("change", () => { m.visible = vis.checked; style(m); slices.draw(); moved(); });
    const lab = document.createElement("label");
    lab.htmlFor = vis.id;
    lab.textContent = layerText(m);
    const op = document.createElement("input");
    op.type = "range", op.min = "0", op.max = "1", op.step = "0.05", op.value = String(m.opacity);
    op.setAttribute("aria-label", "Opacity of " + name);
    op.addEventListener("input", () => { m.opacity = +op.value; style(m); moved(); });
    li.append(vis, sw, lab, op);
    return li;
  }));
}

function layerText(m) { return (m.res.name || m.res.id) + (m.slots ? " (" + m.slots.count + " triangles)" : " (loading)"); }

// Takes a model out of the view (deleted, say).
function close(id) {
  const m = models.get(id);
  if (!m) return;
  if (m.mesh) scene.remove(m.mesh), m.geom.dispose(), m.mesh.material.dispose();
  models.delete(id);
  live.attach([...models.values()]);
  address();
  if (!models.size && !slices.vol) $("viewer").hidden = true;
  slices.draw();
  layers();
  moved();
}

function ids() { return [...models.keys()]; }

// The page's address names what the view shows (a bookmark, a link to share): #series=UID (or
// #volume=ID, a model's samples) for the slices, &models=ID,ID for the 3D view.
function address() {
  const parts = [];
  if (volumeOf) parts.push((volumeOf.what === "series" ? "series=" : "volume=") + volumeOf.id);
  if (models.size) parts.push("models=" + [...models.keys()].join(","));
  history.replaceState(null, "", parts.length ? "#" + parts.join("&") : location.pathname);
}

// ---- live isosurfaces: the brush on the mesh (live.js does the rest) ------------------------------

function initLive(canvas) {
  cursor = new Mesh(new SphereGeometry(1, 24, 16), new MeshBasicMaterial({ color: 0xffe070, wireframe: true, transparent: true, opacity: 0.6 }));
  cursor.visible = false;
  cursor.renderOrder = 2;
  scene.add(cursor);
  live = new LiveIso({ box: $("live"), name: $("live-name"), model: $("live-model"), modelRow: $("live-model-row"), range: $("iso-range"),
    value: $("iso-value"), count: $("live-count"), mode: $("brush-mode"), radius: $("brush-radius"), undo: $("live-undo"), state: $("live-state") },
  { result, samples, delta: deltaInto, reload: async (m) => { await load(m); moved(); }, mark: (t) => { marks.push(t); requestDraw(); },
    cursor: brushTo, changed: () => { if (slices.vol && live.vol === slices.vol) slices.repaint(); } });
  // a stroke: pointer down on the surface, the centres it passes over, pointer up (a mouse or a
  // pen; one finger still turns the view)
  let stroke = null, hover = null, hoverPending = false, picked = null;
  const ndc = (ev) => { const b = canvas.getBoundingClientRect(); return [((ev.clientX - b.left) / b.width) * 2 - 1, 1 - ((ev.clientY - b.top) / b.height) * 2]; };
  const follow = () => {
    hoverPending = false;
    if (!hover || brush === null) return;
    picked = hover;
    const p = pick(...hover);
    cursorAt(p);
    if (stroke && p) {
      const last = stroke.centres[stroke.centres.length - 1];
      if (!last || Math.hypot(p[0] - last[0], p[1] - last[1], p[2] - last[2]) >= BRUSH_STEP * brush) stroke.centres.push(p);
    }
  };
  canvas.addEventListener("pointerdown", (ev) => {
    if (brush === null || ev.button !== 0 || ev.pointerType === "touch") return;
    stroke = { centres: [] };
    hover = ndc(ev);
    follow();
  });
  canvas.addEventListener("pointermove", (ev) => {
    if (brush === null || ev.pointerType === "touch") return;
    hover = ndc(ev);
    if (!hoverPending) hoverPending = true, requestAnimationFrame(follow);
  });
  canvas.addEventListener("pointerup", (ev) => {
    if (!stroke) return;
    const t0 = performance.now(), at = ndc(ev);
    if (!picked || at[0] !== picked[0] || at[1] !== picked[1]) hover = at, follow(); // (where the last pick was: not again)
    const centres = stroke.centres;
    stroke = null;
    if (centres.length) live.stroke(centres, t0);
    else live.say("the brush was over no surface of " + (live.m ? live.m.res.name || live.m.res.id : "the model"));
  });
  canvas.addEventListener("pointerleave", () => { if (!stroke) cursorAt(null); });
  // Ctrl+Z (Cmd+Z) anywhere but in a text field: the last stroke or iso change undone
  document.addEventListener("keydown", (ev) => {
    if (!(ev.ctrlKey || ev.metaKey) || ev.shiftKey || ev.altKey || ev.key.toLowerCase() !== "z" || !live.m || $("live").hidden) return;
    const t = ev.target;
    if (t && (t.isContentEditable || (t.tagName === "INPUT" && !["range", "checkbox", "radio", "button"].includes(t.type)) || t.tagName === "TEXTAREA")) return;
    ev.preventDefault();
    live.undo();
  });
}

// The brush on (its radius, mm) or off (null): the left button paints instead of turning.
function brushTo(r) {
  brush = r;
  controls.mouseButtons.LEFT = r === null ? MOUSE.ROTATE : null;
  $("gl").classList.toggle("brush", r !== null);
  if (r === null) cursor.visible = false;
  else cursor.scale.setScalar(r);
  moved();
}

function cursorAt(p) {
  cursor.visible = brush !== null && !!p;
  if (p) cursor.position.set(p[0], p[1], p[2]);
  requestDraw();
}

// The model's samples for the live tools: the slices' copy when they show them (one copy, kept in
// step), else read (GET /models/{id}/volume); fresh: read again (the slices take the new copy).
async function samples(id, fresh) {
  const shown = volumeOf && volumeOf.what === "model" && volumeOf.id === id && slices.vol;
  if (shown && !fresh) return slices.vol;
  const r = await ctx.api("GET", "/models/" + encodeURIComponent(id) + "/volume");
  if (!r.ok) throw new Error(await ctx.problemOf(r));
  const vol = parseNrrd(await r.arrayBuffer());
  if (shown) slices.replace(vol);
  return vol;
}

// The nearest point of the live model's surface under a point of the view (normalised device
// coordinates, -1..1, y up), or null: a ray against every triangle the view holds (Möller-Trumbore,
// both faces), what is drawn being what is picked.
const raycaster = new Raycaster();
function pick(x, y) {
  const m = live && live.m;
  if (!m || !m.slots || !m.visible) return null;
  camera.updateMatrixWorld();
  raycaster.setFromCamera(new Vector2(x, y), camera);
  const { origin: o, direction: d } = raycaster.ray, P = m.slots.position, n = m.slots.count;
  const ox = o.x, oy = o.y, oz = o.z, dx = d.x, dy = d.y, dz = d.z;
  let best = Infinity;
  for (let t = 0, b = 0; t < n; t++, b += 9) {
    const ax = P[b], ay = P[b + 1], az = P[b + 2];
    const e1x = P[b + 3] - ax, e1y = P[b + 4] - ay, e1z = P[b + 5] - az, e2x = P[b + 6] - ax, e2y = P[b + 7] - ay, e2z = P[b + 8] - az;
    const px = dy * e2z - dz * e2y, py = dz * e2x - dx * e2z, pz = dx * e2y - dy * e2x;
    const det = e1x * px + e1y * py + e1z * pz;
    if (det > -1e-12 && det < 1e-12) continue;
    const inv = 1 / det, sx = ox - ax, sy = oy - ay, sz = oz - az;
    const u = (sx * px + sy * py + sz * pz) * inv;
    if (u < 0 || u > 1) continue;
    const qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
    const v = (dx * qx + dy * qy + dz * qz) * inv;
    if (v < 0 || u + v > 1) continue;
    const dist = (e2x * qx + e2y * qy + e2z * qz) * inv;
    if (dist > 0 && dist < best) best = dist;
  }
  return best < Infinity ? [ox + best * dx, oy + best * dy, oz + best * dz] : null;
}

// The test hook's and the bench's: the surface point under a CSS pixel of the view, or null.
function pickAt(cx, cy) {
  const b = $("gl").getBoundingClientRect();
  return pick(((cx - b.left) / b.width) * 2 - 1, 1 - ((cy - b.top) / b.height) * 2);
}

// ---- the read-only test hook and the bench ----------------------------------------------------

function stats() {
  return {
    models: [...models.values()].map((m) => ({ id: m.res.id, name: m.res.name || "", triangles: m.slots ? m.slots.count : 0,
      drawn: m.mesh ? m.geom.drawRange.count / 3 : 0, visible: m.visible, opacity: m.opacity,
      color: "#" + m.color.getHexString(SRGBColorSpace) })),
    meshes: scene ? scene.children.filter((o) => o.isMesh && o.visible).length : 0,
    showing: exactShown ? "exact" : "webgl", exactSerial: +($("exact").dataset.serial || 0), serial, frames,
    camera: { eye: vec(camera.position), target: vec(controls.target), fov: camera.fov, aspect: camera.aspect },
    webgl: renderer ? (renderer.capabilities.isWebGL2 ? 2 : 1) : 0,
    slices: slices ? slices.stats() : null, volume: volumeOf, live: live ? live.stats() : null, brush,
  };
}

// FNV-1a of the live tools' copy of the samples (the browser test's: it must stay the daemon's).
function liveDigest() {
  if (!live.vol) return null;
  const d = live.vol.data, b = new Uint8Array(d.buffer, d.byteOffset, d.byteLength);
  let h = 0x811c9dc5;
  for (let i = 0; i < b.length; i++) h = Math.imul(h ^ b[i], 0x01000193);
  return h >>> 0;
}

// Frames a second while the view turns a little every frame for ms milliseconds.
function bench(ms = 3000) {
  return new Promise((res) => {
    const t0 = performance.now();
    let n = 0;
    const step = (t) => {
      controls.rotateLeft(0.02);
      n++;
      if (t - t0 < ms) requestAnimationFrame(step);
      else res({ fps: (1000 * n) / (t - t0), frames: n, ms: t - t0 });
    };
    requestAnimationFrame(step);
  });
}

window.surfdView = { init, open, close, ids, applyDelta, stats, bench, reset, openVolume, closeVolume, pickAt,
  test: { decodeDelta, encodeDelta, IdMap, MeshSlots, slotRanges, strokeBlock, putBlock, sampleRange, liveDigest,
    sharedSamples: () => !!live.vol && live.vol === slices.vol } };
window.dispatchEvent(new Event("surfdview"));
