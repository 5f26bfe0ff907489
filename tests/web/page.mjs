// page.mjs - the web page driven as a person would, in Debian's headless Chromium through
// playwright-core (nothing downloaded): load /, upload a contour file, wait for the job, read the
// volume shown against the API's, see the model in the 3D view (WebGL: SwiftShader) with as many
// triangles as the API's mesh, the exact render arrive over it lined up with it, turn it by
// dragging and by keys, zoom with the wheel, download the STL and the RT Structure Set; without a
// token also an RT Structure Set's ROIs together in their colours, keyboard-only use, a
// /#models= link and the mesh delta's apply function on hand-made deltas. Prints
// "PASS: ..." / "FAIL: ..." lines (tests/web/page.sh counts them); screenshots into SHOTS.
// Environment: URL, CONTOURS (a contour JSON), RTSS (an RT Structure Set), SHOTS (a directory),
// TOKEN (optional), NODE_PATH.
import { createRequire } from "node:module";
import fs from "node:fs";
import path from "node:path";

// playwright-core lives in build/npm (NODE_PATH), which ES modules do not search: required from there
const require = createRequire(path.resolve(process.env.NODE_PATH || "build/npm/node_modules") + "/");
const { chromium } = require("playwright-core");

const { URL: base, CONTOURS, RTSS, SHOTS, TOKEN = "", SERIES = "", DATA = "../shared/data" } = process.env;
const tag = TOKEN ? "token" : "open";
let failures = 0;
const check = (name, ok, detail = "") => {
  console.log((ok ? "PASS: " : "FAIL: ") + name + " (" + tag + ")" + (ok || !detail ? "" : ": " + detail));
  if (!ok) failures++;
};
const auth = TOKEN ? { Authorization: "Bearer " + TOKEN } : {};

// The stored models' ids (before a job makes one), and whether the view shows one new model alone, loaded.
async function storedIds() {
  return ((await (await fetch(base + "/models", { headers: auth })).json()).models || []).map((m) => m.id);
}
const opened = (old) => { const m = window.surfdView.stats().models; return m.length === 1 && !old.includes(m[0].id) && m[0].triangles > 0; };

// The API's triangle count of a model: the n_added of its whole mesh delta (API.md).
async function apiTriangles(id) {
  const r = await fetch(base + "/models/" + id + "/mesh?format=delta&since=0", { headers: auth });
  const b = Buffer.from(await r.arrayBuffer());
  return r.ok && b.toString("latin1", 0, 4) === "SFMD" ? b.readUInt32LE(16) : -1;
}

// An RT Structure Set through the form: every ROI a model, all in the 3D view in their colours;
// the exact render of too many patches refused and said so, of fewer lined up; keyboard-only use;
// a /#models= link; the mesh delta's apply function on hand-made deltas and on a drawn model.
async function structures(page, { view, frame, dist, lineUp, exactArrives }) {
  await page.setInputFiles("#file", RTSS);
  check("an RT Structure Set picks POST /model", (await page.inputValue("#route")) === "model");
  await page.click("#go");
  await page.waitForFunction(() => document.querySelectorAll("#job-output dl").length > 1, null, { timeout: 300000 });
  const n = await page.locator("#job-output dl").count();
  await page.waitForFunction((k) => { const v = window.surfdView.stats(); return v.models.length === k && v.models.every((m) => m.triangles > 0); },
    n, { timeout: 300000 });
  let v = await view();
  const want = [];
  for (const m of v.models) want.push(await apiTriangles(m.id));
  check("every ROI (" + n + ") is in the 3D view, each drawn with the API's triangles",
    v.models.length === n && n >= 5 && v.meshes === n && v.models.every((m, k) => m.triangles === want[k] && m.drawn === want[k]),
    JSON.stringify(v.models.map((m) => [m.name, m.triangles])) + " vs " + want);
  const heart = v.models.find((m) => m.name === "Heart"), bed = v.models.find((m) => m.name === "Tumor Bed");
  check("... in their RT Structure Set colours (the Heart #ff8000)", heart && heart.color === "#ff8000" && bed && bed.color === "#ff0000",
    JSON.stringify(v.models.map((m) => [m.name, m.color])));
  check("... each listed with its visibility and opacity", (await page.locator("#layers li input[type=checkbox]").count()) === n &&
    (await page.locator("#layers li input[type=range]").count()) === n);
  check("the address names the models (/#models=)", (await page.evaluate(() => location.hash)) === "#models=" + v.models.map((m) => m.id).join(","));
  await page.screenshot({ path: SHOTS + "/6-structures-webgl.png" });
  // all of them are more patches than one scene may hold: the page says so and stays on WebGL
  await page.waitForFunction(() => document.getElementById("view-caption").textContent.startsWith("no exact render"), null, { timeout: 180000 });
  check("the exact render of too many patches is refused and said so", (await page.textContent("#view-caption")).includes("100000") &&
    (await view()).showing === "webgl", await page.textContent("#view-caption"));
  // the large ones hidden, the rest render exactly
  const s0 = (await view()).serial;
  for (const name of ["BODY", "Lt Lung", "Breast"]) {
    const m = v.models.find((x) => x.name === name);
    if (m) await page.uncheck("#vis-" + m.id);
  }
  v = await view();
  check("hidden models are not drawn", v.meshes === v.models.filter((m) => m.visible).length && v.meshes < n, JSON.stringify(v));
  await exactArrives(s0);
  const lu = await lineUp();
  check("the exact render of the visible ROIs arrives, lined up with the WebGL frame", lu.covered > 0.002 && lu.iou > 0.85, JSON.stringify(lu));
  await page.screenshot({ path: SHOTS + "/7-structures-exact.png" });

  // keyboard only: View by Enter, then arrows, shift+arrows, + and -, Home, Tab to the toggle
  const row = page.locator("#models-table tbody tr", { hasText: "Heart" }).first();
  await row.locator("button", { hasText: "View" }).focus();
  await page.keyboard.press("Enter");
  await page.waitForFunction(() => { const v = window.surfdView.stats(); return v.models.length === 1 && v.models[0].triangles > 0; }, null, { timeout: 120000 });
  check("Enter on View opens the model alone, the view focused", (await page.evaluate(() => document.activeElement.id)) === "gl");
  const home = (await view()).camera;
  await page.keyboard.press("ArrowLeft");
  const k1 = (await view()).camera;
  check("an arrow key turns", JSON.stringify(k1.eye) !== JSON.stringify(home.eye) && JSON.stringify(k1.target) === JSON.stringify(home.target));
  await page.keyboard.press("+");
  const k2 = (await view()).camera;
  check("+ zooms in", dist(k2) < 0.95 * dist(k1), dist(k1) + " -> " + dist(k2));
  await page.keyboard.press("-");
  await page.keyboard.press("-");
  check("- zooms out", dist((await view()).camera) > dist(k2) * 1.2);
  await page.keyboard.press("Shift+ArrowRight");
  const k3 = (await view()).camera;
  check("shift+arrow pans", JSON.stringify(k3.target) !== JSON.stringify(k1.target));
  await page.keyboard.press("Home");
  const k4 = (await view()).camera;
  check("Home comes back to the first view", k4.eye.every((x, k) => Math.abs(x - home.eye[k]) < 1e-3 * dist(home)) &&
    k4.target.every((x, k) => Math.abs(x - home.target[k]) < 1e-3 * dist(home)), JSON.stringify([home, k4]));
  const ring = await page.evaluate(() => getComputedStyle(document.activeElement).outlineStyle);
  check("the focused view shows its focus", ring !== "none", ring);
  await page.keyboard.press("Tab");
  check("Tab goes from the view to the exact toggle", (await page.evaluate(() => document.activeElement.id)) === "exact-toggle");
  await page.keyboard.press("Space");
  check("Space turns the exact render off", (await page.getAttribute("#exact-toggle", "aria-pressed")) === "false" && (await view()).showing === "webgl");
  await page.keyboard.press("Space");

  // the mesh delta: hand-made deltas through MeshSlots, then one onto the drawn Heart
  const r = await page.evaluate(() => {
    const { MeshSlots, encodeDelta, decodeDelta, slotRanges } = window.surfdView.test;
    const T = (z) => [0, 0, z, 1, 0, z, 0, 1, z], out = {};
    const s = new MeshSlots(2);
    s.apply(decodeDelta(encodeDelta(0, 1, [], [[10, T(0)], [11, T(1)], [12, T(2)]])));
    out.added = s.count === 3 && s.version === 1 && s.capacity >= 3;
    const res = s.apply(decodeDelta(encodeDelta(1, 2, [10], [[13, T(3)], [12, T(5)]])));
    out.applied = s.count === 3 && s.version === 2 && res.removed === 1 && res.added === 2 && s.corners(10) === null &&
      s.corners(13)[2] === 3 && s.corners(12)[2] === 5 && s.corners(11)[2] === 1;
    let packed = s.slotOf.size === s.count;
    for (let k = 0; k < s.count; k++) packed = packed && s.slotOf.get(s.idOf[k]) === k;
    out.packed = packed;
    out.ranges = JSON.stringify(res.ranges) === "[[0,3]]" &&
      JSON.stringify(slotRanges([5, 100, 6, 40, 300, 5], 200)) === "[[5,7],[40,41],[100,101]]";
    out.normal = Math.abs(s.normal[9 * s.slotOf.get(13) + 2] - 1) < 1e-6;
    // a new iso: every held triangle out, others in (the slots laid out anew, one range)
    const w = s.apply(decodeDelta(encodeDelta(2, 3, [12, 11, 13], [[20, T(7)], [21, T(8)], [22, T(9)], [23, T(10)]])));
    let whole = s.count === 4 && w.removed === 3 && w.added === 4 && JSON.stringify(w.ranges) === "[[0,4]]" &&
      s.corners(11) === null && s.corners(13) === null && s.corners(22)[2] === 9 && s.slotOf.size === 4;
    for (let k = 0; k < s.count; k++) whole = whole && s.slotOf.get(s.idOf[k]) === k;
    out.whole = whole;
    // the id table against a Map, through 20 000 sets and deletes of ids that collide
    const { IdMap } = window.surfdView.test, im = new IdMap(4), ref = new Map();
    let same = true, seed = 7;
    for (let k = 0; k < 20000; k++) {
      seed = (Math.imul(seed, 1103515245) + 12345) >>> 0;
      const id = (seed >>> 8) % 3000 * 64; // (multiples of 64: many share a home)
      if (seed & 1) im.set(id, k), ref.set(id, k); else same = same && im.delete(id) === ref.delete(id);
      same = same && im.get(id) === ref.get(id) && im.size === ref.size;
    }
    for (const [id, v] of ref) same = same && im.get(id) === v;
    out.idmap = same;
    const throws = (f) => { try { f(); return false; } catch (e) { return true; } };
    out.wrongBase = throws(() => s.apply(decodeDelta(encodeDelta(1, 4, [], []))));
    out.short = throws(() => decodeDelta(new ArrayBuffer(19))) && throws(() => decodeDelta(encodeDelta(0, 1, [], [[1, T(0)]]).slice(0, 50)));
    return out;
  });
  check("a hand-made delta adds triangles to the slots (growing them)", r.added);
  check("a second delta removes one, adds one and replaces one", r.applied);
  check("the slots stay packed, every id at its slot", r.packed);
  check("... and say which slots to upload again (sorted ranges within the count, near ones joined)", r.ranges);
  check("an added triangle has its face normal", r.normal);
  check("a new iso's delta (every triangle out) lays the slots out anew: one range, every id at its slot", r.whole);
  check("the id table agrees with a Map through 20 000 sets and deletes of colliding ids", r.idmap);
  check("a delta from another version is refused", r.wrongBase);
  check("a truncated delta is refused", r.short);
  const one = (await view()).models[0];
  const after = await page.evaluate((id) => {
    const { encodeDelta } = window.surfdView.test;
    const out = window.surfdView.applyDelta(id, encodeDelta(1, 2, [0, 1, 2], [[9999999, [0, -300, -50, 10, -300, -50, 0, -300, -40]]]));
    return { out, m: window.surfdView.stats().models[0] };
  }, one.id);
  check("a delta onto the drawn model removes and adds in place", after.m.triangles === one.triangles - 2 && after.m.drawn === one.triangles - 2 &&
    after.out.removed === 3 && !after.out.grown, JSON.stringify([one.triangles, after]));

  // a link opens those models (bookmarkable), in a new tab
  const ids = v.models.filter((m) => ["Heart", "Tumor Bed"].includes(m.name)).map((m) => m.id);
  const tab = await page.context().newPage();
  await tab.goto(base + "/#models=" + ids.join(","));
  await tab.waitForFunction((k) => window.surfdView && window.surfdView.stats().models.filter((m) => m.triangles > 0).length === k, ids.length, { timeout: 120000 });
  const t = await tab.evaluate(() => window.surfdView.stats());
  check("/#models=ID,ID opens those models", t.models.map((m) => m.id).join(",") === ids.join(",") && t.meshes === ids.length, JSON.stringify(t.models));
  await tab.screenshot({ path: SHOTS + "/8-link-1280x800.png" });
  await tab.close();
  await frame();
}

// The CT beside the surfaces: the series a PACS sent listed by study, opened by keyboard in three
// slice views (window and level by preset and by drag), a surface made of it with its cut lines
// on every slice and the slices' planes in the 3D view, the model sent back to the PACS with one
// click, and a #series= link that opens the same.
async function workstation(page, { view, frame }) {
  const slicePixels = (id) => page.evaluate((i) => document.getElementById(i).toDataURL(), id);
  // pixels of a colour (within tol per channel) on a canvas, and those that are not black
  const count = (id, rgb, tol = 40) => page.evaluate(([i, c, t]) => {
    const cv = document.getElementById(i), d = cv.getContext("2d").getImageData(0, 0, cv.width, cv.height).data;
    let n = 0, lit = 0;
    for (let k = 0; k < d.length; k += 4) {
      if (Math.abs(d[k] - c[0]) <= t && Math.abs(d[k + 1] - c[1]) <= t && Math.abs(d[k + 2] - c[2]) <= t) n++;
      if (d[k] + d[k + 1] + d[k + 2] > 30 && d[k + 3] > 0) lit++;
    }
    return { n, lit };
  }, [id, rgb, tol]);
  await page.click("#series-refresh");
  const row = page.locator("#series-list tr[data-uid='" + SERIES + "']");
  await row.waitFor({ timeout: 30000 });
  const text = await row.textContent();
  check("the series the PACS sent is listed by study: CT, 27 instances, from ORTHANC", text.includes("CT") && text.includes("27 instances") &&
    text.includes("ORTHANC") && (await page.locator("#series-list .study h3").count()) >= 1, text);
  await row.locator("button", { hasText: "Open" }).focus();
  await page.keyboard.press("Enter");
  await page.waitForFunction(() => { const v = window.surfdView.stats(); return v.slices && v.slices.dims; }, null, { timeout: 60000 });
  let v = await view();
  check("Open shows its samples in three slice views (64 x 64 x 27, int16, soft tissue)", JSON.stringify(v.slices.dims) === "[64,64,27]" &&
    v.slices.type === "int16" && v.slices.preset === "soft" && v.slices.window === 400, JSON.stringify(v.slices));
  check("... and the address names it (#series=UID)", (await page.evaluate(() => location.hash)) === "#series=" + SERIES,
    await page.evaluate(() => location.hash));
  const lit = [];
  for (const n of ["axial", "coronal", "sagittal"]) lit.push((await count("slice-" + n, [0, 0, 0], 0)).lit);
  check("each slice view shows the CT (pixels lit)", lit.every((x) => x > 1000), JSON.stringify(lit));
  const before = await slicePixels("slice-axial");
  await page.selectOption("#wl-preset", "bone");
  v = await view();
  check("the bone preset changes the window and the slices' pixels", v.slices.window === 1800 && v.slices.level === 400 &&
    (await slicePixels("slice-axial")) !== before, JSON.stringify(v.slices));
  const box = await page.locator("#slice-coronal").boundingBox();
  const px0 = await slicePixels("slice-coronal");
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 - 80, box.y + box.height / 2 + 30, { steps: 5 });
  await page.mouse.up();
  v = await view();
  check("a drag on a slice changes window and level, and the pixels", v.slices.window < 1800 && v.slices.level !== 400 &&
    v.slices.preset === "custom" && (await slicePixels("slice-coronal")) !== px0, JSON.stringify(v.slices));
  await page.selectOption("#wl-preset", "soft");
  await page.focus("#slice-axial");
  const k0 = (await view()).slices.slices[0];
  await page.keyboard.press("ArrowUp");
  await page.keyboard.press("PageDown");
  check("arrow keys and Page Down move through the axial slices", (await view()).slices.slices[0] === Math.max(0, k0 + 1 - 10),
    JSON.stringify((await view()).slices));
  await page.keyboard.press("PageUp");
  // a surface of the series, its cut lines on every slice and the planes in the 3D view
  await page.fill("#surface-iso", "226.5");
  await page.click("#surface-make");
  await page.waitForFunction(() => { const v = window.surfdView.stats(); return v.models.length === 1 && v.models[0].triangles > 0; }, null,
    { timeout: 180000 });
  v = await view();
  const tri = await apiTriangles(v.models[0].id);
  check("Make a surface: the isosurface of the series in the 3D view, with the API's triangles", v.models[0].triangles === tri &&
    v.models[0].name.includes("226.5"), JSON.stringify(v.models) + " vs " + tri);
  await frame();
  v = await view();
  check("its cut lines are on every slice", v.slices.lines.every((x) => x > 10), JSON.stringify(v.slices.lines));
  const orange = await count("slice-axial", [230, 159, 0]);
  check("... drawn in the model's colour on the slice's pixels", orange.n > 50, JSON.stringify(orange));
  const red = await count("planes", [0xe0, 0x44, 0x3e]);
  check("the slices' planes are drawn in the 3D view (the axial one red)", red.n > 50, JSON.stringify(red));
  await page.locator("#slices").scrollIntoViewIfNeeded();
  await page.screenshot({ path: SHOTS + "/10-slices-1280x800.png" });
  await page.evaluate(() => document.getElementById("viewer").scrollIntoView());
  await page.screenshot({ path: SHOTS + "/11-slices-planes-1280x800.png" });
  // one click sends it to the PACS
  check("the PACS configured are offered", (await page.locator("#send-pacs option").allTextContents()).join(",") === "orthanc");
  await page.selectOption("#send-as", "rtstruct");
  await page.click("#send");
  await page.waitForFunction(() => document.getElementById("send-state").dataset.stored !== undefined, null, { timeout: 180000 });
  check("Send: the model is stored by the PACS (one instance)", (await page.getAttribute("#send-state", "data-stored")) === "1",
    await page.textContent("#send-state"));
  // a link to the series opens the slices with the surface on its frame
  const id = v.models[0].id;
  const tab = await page.context().newPage();
  await tab.goto(base + "/#series=" + SERIES);
  await tab.waitForFunction((m) => { const s = window.surfdView && window.surfdView.stats(); return s && s.slices && s.models.some((x) => x.id === m && x.triangles > 0); },
    id, { timeout: 120000 });
  const t = await tab.evaluate(() => window.surfdView.stats());
  check("/#series=UID opens its slices and the models on its frame", t.volume.id === SERIES && t.models.length === 1 && t.slices.lines.every((x) => x > 10),
    JSON.stringify([t.volume, t.slices]));
  await tab.close();
  // a volume model's own samples
  await page.click("#models-refresh");
  const mrow = page.locator("#models-table tbody tr[data-id='" + id + "']");
  await mrow.locator("button", { hasText: "Slices" }).click();
  await page.waitForFunction((m) => { const s = window.surfdView.stats(); return s.volume && s.volume.what === "model" && s.volume.id === m && s.slices; },
    id, { timeout: 60000 });
  check("Slices on an isosurface model shows its own samples", JSON.stringify((await view()).slices.dims) === "[64,64,27]");

  // drops: the series' files together (a DICOM folder's), and a MetaImage header with its data
  const dir = DATA + "/volumes/dicom_ct_head_64x64x27";
  const files = fs.readdirSync(dir).filter((f) => f.endsWith(".dcm")).sort().map((f) => path.join(dir, f));
  await page.setInputFiles("#file", files);
  await page.waitForFunction(() => document.getElementById("file-what").textContent.includes("27 DICOM files"));
  check("27 DICOM files chosen together are one series, to make a surface of", (await page.inputValue("#route")) === "isosurface",
    await page.textContent("#file-what"));
  await page.fill("input[name=iso]", "226.5");
  let known = await storedIds();
  await page.click("#go");
  await page.waitForFunction(opened, known, { timeout: 180000 });
  let d = (await view()).models[0];
  check("... the same surface as the series the PACS sent (its triangles), not named by the files", d.triangles === v.models[0].triangles &&
    !/IM0|slice/i.test(d.name), JSON.stringify(d));
  await page.setInputFiles("#file", [DATA + "/volumes/ct_head_crop64_int16.mhd", DATA + "/volumes/ct_head_crop64_int16.raw"]);
  await page.waitForFunction(() => document.getElementById("file-what").textContent.includes(".raw"));
  check("a .mhd with its .raw: one volume, to make a surface of", (await page.inputValue("#route")) === "isosurface");
  await page.fill("input[name=iso]", "226.5");
  known = await storedIds();
  await page.click("#go");
  await page.waitForFunction(opened, known, { timeout: 180000 });
  d = (await view()).models[0];
  check("... its surface, named from the file", d.name === "ct_head_crop64_int16", JSON.stringify(d));
  await page.screenshot({ path: SHOTS + "/12-drop-mhd-1280x800.png" });
}

// FNV-1a of a model's samples as the daemon serves them (GET /models/{id}/volume, the NRRD's data):
// what the page's copy must equal.
async function apiDigest(id) {
  const b = Buffer.from(await (await fetch(base + "/models/" + id + "/volume", { headers: auth })).arrayBuffer());
  const at = b.indexOf("\n\n") + 2;
  let h = 0x811c9dc5;
  for (let i = at; i < b.length; i++) h = Math.imul(h ^ b[i], 0x01000193);
  return h >>> 0;
}

// Live isosurfaces as a user works them: a CT volume made a surface with levels=2 (its changes
// journaled), its iso slider dragged (coalesced: one request in flight at a time) and stepped by a
// key, a brush stroke painted by mouse on the surface and one by Enter at the view's centre, each
// followed by its delta (the page's triangles the API's, no reload since=0), the page's samples
// the daemon's, and Ctrl+Z back through them; then a levels=1 model, whose edits keep no journal
// yet, stays right by reloading on 410.
async function liveIso(page, { view, frame }) {
  const live = async () => (await view()).live;
  const idle = () => page.waitForFunction(() => { const l = window.surfdView.stats().live; return l && l.ready && l.idle; }, null, { timeout: 180000 });
  const apiModel = async (id) => (await fetch(base + "/models/" + id, { headers: auth })).json();
  const log = []; // the page's requests of the model's mesh and changes, in order
  let inFlight = 0, maxInFlight = 0;
  const changeReq = (q) => /\/models\/[^/]+\/(iso|edit)\?/.test(q.url()) && q.method() === "POST";
  page.on("request", (q) => {
    if (/\/models\/[^/]+\/(mesh|iso|edit)/.test(q.url())) log.push(q.method() + " " + q.url().replace(base, ""));
    if (changeReq(q)) maxInFlight = Math.max(maxInFlight, ++inFlight);
  });
  const settle = (q) => { if (changeReq(q)) inFlight--; };
  page.on("requestfinished", settle);
  page.on("requestfailed", settle);

  const raw = DATA + "/volumes/ct_head_crop64_int16.raw";
  await page.setInputFiles("#file", [DATA + "/volumes/ct_head_crop64_int16.mhd", raw]);
  await page.waitForFunction(() => document.getElementById("file-what").textContent.includes(".raw"));
  await page.fill("input[name=iso]", "226.5");
  await page.selectOption("select[name=levels]", "2");
  const before = await storedIds();
  await page.click("#go");
  await page.waitForFunction((old) => { const v = window.surfdView.stats(); return v.models.length === 1 && !old.includes(v.models[0].id) &&
    v.live && v.live.id === v.models[0].id && v.live.ready; }, before, { timeout: 180000 });
  let l = await live();
  const id = l.id;
  let api = await apiModel(id);
  const samples = new Int16Array(new Uint8Array(fs.readFileSync(raw)).buffer);
  const lo = samples.reduce((a, x) => Math.min(a, x), Infinity), hi = samples.reduce((a, x) => Math.max(a, x), -Infinity);
  check("a volume's surface (levels=2) opens with its live tools: the iso slider spans the samples' range", api.levels === 2 &&
    !(await page.locator("#live").isHidden()) && +(await page.getAttribute("#iso-range", "min")) === lo &&
    +(await page.getAttribute("#iso-range", "max")) === hi && +(await page.inputValue("#iso-range")) === 226.5,
    JSON.stringify([api.levels, lo, hi, await page.getAttribute("#iso-range", "min"), await page.getAttribute("#iso-range", "max")]));
  check("... and shows the iso and the API's triangles", +(await page.getAttribute("#live-count", "data-triangles")) === api.triangles &&
    (await page.textContent("#live-count")).includes("iso 226.5"), (await page.textContent("#live-count")) + " vs " + api.triangles);
  check("the page's copy of the samples is the daemon's", (await page.evaluate(() => window.surfdView.test.liveDigest())) === (await apiDigest(id)));
  // its slices: the same copy of the samples (one in memory, painted as the surface is)
  await page.click("#models-refresh");
  await page.locator("#models-table tbody tr[data-id='" + id + "']").locator("button", { hasText: "Slices" }).click();
  await page.waitForFunction((m) => { const s = window.surfdView.stats(); return s.volume && s.volume.id === m && s.slices && s.live && s.live.id === m && s.live.ready; },
    id, { timeout: 60000 });
  check("Slices of the model share the live tools' copy of its samples", await page.evaluate(() => window.surfdView.test.sharedSamples()));
  const mark = log.length;

  // the slider dragged across: values coalesced, never two changes in flight, the last one wins
  await page.evaluate(() => { window.isoInputs = 0; document.getElementById("iso-range").addEventListener("input", () => window.isoInputs++); });
  await page.locator("#live").scrollIntoViewIfNeeded();
  const box = await page.locator("#iso-range").boundingBox();
  const y = box.y + box.height / 2, at = (f) => box.x + 8 + f * (box.width - 16);
  await page.mouse.move(at((226.5 - lo) / (hi - lo)), y);
  await page.mouse.down();
  for (let k = 1; k <= 12; k++) await page.mouse.move(at((226.5 - lo) / (hi - lo) + 0.02 * k), y);
  await page.mouse.up();
  await idle();
  l = await live();
  api = await apiModel(id);
  const posts = log.slice(mark).filter((x) => x.startsWith("POST") && x.includes("/iso?")).length;
  const slid = +(await page.inputValue("#iso-range"));
  check("a drag of the iso slider re-extracts at the value it ends on (the API's iso)", slid > 226.5 && l.iso === slid && api.iso === slid,
    JSON.stringify([slid, l.iso, api.iso]));
  const inputs = await page.evaluate(() => window.isoInputs);
  check("... its values coalesced: never two changes in flight, no more requests than values", maxInFlight === 1 && posts >= 1 && posts <= inputs,
    JSON.stringify({ maxInFlight, posts, inputs }));
  check("... the page's triangles are the API's after the delta", l.triangles === api.triangles && l.version === api.version &&
    +(await page.getAttribute("#live-count", "data-triangles")) === api.triangles, JSON.stringify([l, api.triangles, api.version]));
  const fetched = log.slice(mark).filter((x) => x.includes("format=delta"));
  check("... fetched as deltas since the view's version, never the whole mesh (since=0)", fetched.length >= 1 &&
    fetched.every((x) => !/since=0$/.test(x)) && l.counts.reloads === 0, JSON.stringify(fetched));
  await page.screenshot({ path: SHOTS + "/14-live-iso-1280x800.png" });
  // back to 226.5 typed, then one key step on the slider
  await page.fill("#iso-value", "226.5");
  await page.press("#iso-value", "Enter");
  await idle();
  await page.focus("#iso-range");
  await page.keyboard.press("ArrowRight");
  await idle();
  l = await live();
  api = await apiModel(id);
  check("a typed iso and an arrow key on the slider each re-extract (227.5: the API's triangles)", l.iso === 227.5 && api.iso === 227.5 &&
    l.triangles === api.triangles, JSON.stringify([l.iso, api.iso, l.triangles, api.triangles]));
  const isoTriangles = l.triangles, isoDigest = await apiDigest(id);

  // a brush stroke by mouse on the surface: paint a sphere, the surface updated by the delta
  await page.selectOption("#brush-mode", "paint");
  await page.fill("#brush-radius", "4");
  await page.press("#brush-radius", "Tab");
  await page.locator("#viewer").scrollIntoViewIfNeeded();
  const gl = await page.locator("#gl").boundingBox();
  let spot = null; // a point of the canvas over the surface, near the middle
  for (let r = 0; r < 0.4 && !spot; r += 0.05)
    for (let a = 0; a < 8 && !spot; a++) {
      const p = [gl.x + gl.width * (0.5 + r * Math.cos(a * Math.PI / 4)), gl.y + gl.height * (0.5 + r * Math.sin(a * Math.PI / 4))];
      if (await page.evaluate(([x, yy]) => window.surfdView.pickAt(x, yy), p)) spot = p;
    }
  check("with the brush on the view picks the surface under the pointer", !!spot && (await view()).brush === 4);
  const mk = log.length;
  await page.mouse.move(spot[0], spot[1]);
  await page.mouse.down();
  await page.mouse.move(spot[0] + 6, spot[1] + 3, { steps: 3 });
  await page.mouse.up();
  await idle();
  l = await live();
  api = await apiModel(id);
  const stroke = l.strokes[l.strokes.length - 1];
  check("a brush stroke paints: one edit, the surface changed", stroke && stroke.how === "delta" && l.counts.edits === 1 &&
    l.triangles !== isoTriangles && api.edit && /^\d+,\d+,\d+,\d+,\d+,\d+$/.test(api.edit.region), JSON.stringify([stroke, isoTriangles, api.edit]));
  check("... the page's triangles are the API's (same version)", l.triangles === api.triangles && l.version === api.version &&
    +(await page.getAttribute("#live-count", "data-triangles")) === api.triangles, JSON.stringify([l.triangles, api.triangles, l.version, api.version]));
  const after = log.slice(mk);
  check("... by a delta fetch since the version before, not a since=0 reload", after.some((x) => x.startsWith("POST") && x.includes("/edit?region=")) &&
    after.some((x) => x.includes("format=delta&since=" + (l.version - 1))) && !after.some((x) => /since=0$/.test(x)), JSON.stringify(after));
  const painted = await apiDigest(id);

  check("... and the page's samples are the daemon's after it (painted)", painted !== isoDigest &&
    (await page.evaluate(() => window.surfdView.test.liveDigest())) === painted);
  await frame();
  await page.screenshot({ path: SHOTS + "/15-live-brush-1280x800.png" });

  // keyboard: Enter on the view paints at its centre, ] grows the brush, Ctrl+Z undoes
  await page.focus("#gl");
  await page.keyboard.press("]");
  check("] grows the brush", (await view()).brush === 5, String((await view()).brush));
  const centre = await page.evaluate(() => { const b = document.getElementById("gl").getBoundingClientRect(); return window.surfdView.pickAt(b.left + b.width / 2, b.top + b.height / 2); });
  const v0 = (await live()).version;
  await page.keyboard.press("Enter");
  await idle();
  l = await live();
  api = await apiModel(id);
  check("Enter on the view paints at its centre (a second stroke, the API's triangles)", !!centre && l.version === v0 + 1 &&
    l.counts.edits === 2 && l.triangles === api.triangles, JSON.stringify([centre, v0, l.version, l.triangles, api.triangles]));
  await page.keyboard.press("Control+z");
  await idle();
  l = await live();
  api = await apiModel(id);
  check("Ctrl+Z undoes the keyboard stroke", l.triangles === api.triangles && (await apiDigest(id)) === painted &&
    (await page.evaluate(() => window.surfdView.test.liveDigest())) === painted, JSON.stringify([l.triangles, api.triangles]));
  // the axial slice through the mouse stroke (the model hidden: the samples alone, no cut lines), to compare with it undone
  await page.uncheck("#vis-" + id);
  const through = await page.evaluate((r) => { const el = document.getElementById("slice-axial-k"); el.value = String(r[2] + Math.floor(r[5] / 2));
    el.dispatchEvent(new Event("input")); return document.getElementById("slice-axial").toDataURL(); }, stroke.region);
  await page.click("#live-undo");
  await idle();
  const undone = await page.evaluate(() => document.getElementById("slice-axial").toDataURL());
  await page.check("#vis-" + id);
  l = await live();
  api = await apiModel(id);
  check("Undo takes back the mouse stroke: the triangles and the samples before it", l.triangles === isoTriangles && api.triangles === isoTriangles &&
    (await apiDigest(id)) === isoDigest && (await page.evaluate(() => window.surfdView.test.liveDigest())) === isoDigest,
    JSON.stringify([l.triangles, api.triangles, isoTriangles]));
  check("... and the axial slice through it is painted again without it (the samples shared)", undone !== through &&
    (await page.evaluate(() => window.surfdView.test.sharedSamples())));
  await page.keyboard.press("Control+z");
  await idle();
  l = await live();
  api = await apiModel(id);
  check("... and again the arrow key's iso step (226.5)", l.iso === 226.5 && api.iso === 226.5 && l.triangles === api.triangles &&
    +(await page.inputValue("#iso-range")) === 226.5, JSON.stringify([l.iso, api.iso]));
  check("every change came by delta: no reload since=0 of the levels=2 model", l.counts.reloads === 0 &&
    !log.slice(mark).some((x) => /since=0$/.test(x)), JSON.stringify(log.slice(mark)));
  check("the Undo button says what it undoes next (the typed iso)", (await page.textContent("#live-undo")).includes("iso"), await page.textContent("#live-undo"));

  // levels=1 (the default): an edit whose delta the journal may not keep is read again (410 -> since=0)
  await page.selectOption("#brush-mode", "off");
  await page.setInputFiles("#file", [DATA + "/volumes/ct_head_crop64_int16.mhd", raw]);
  await page.waitForFunction(() => document.getElementById("file-what").textContent.includes(".raw"));
  await page.fill("input[name=iso]", "226.5");
  await page.selectOption("select[name=levels]", "");
  const before1 = await storedIds();
  await page.click("#go");
  await page.waitForFunction((old) => { const v = window.surfdView.stats(); return v.models.length === 1 && !old.includes(v.models[0].id) &&
    v.live && v.live.id === v.models[0].id && v.live.ready; }, before1, { timeout: 180000 });
  const id1 = (await live()).id;
  await page.selectOption("#brush-mode", "erase");
  await page.focus("#gl");
  await page.keyboard.press("Enter");
  await idle();
  l = await live();
  api = await apiModel(id1);
  check("levels=1: an erase stroke keeps the page's triangles the API's (by delta, or by reload on 410)", l.counts.edits === 1 &&
    l.triangles === api.triangles && l.version === api.version && (l.counts.reloads === 1 || l.counts.deltas >= 1) &&
    (await page.evaluate(() => window.surfdView.test.liveDigest())) === (await apiDigest(id1)),
    JSON.stringify([l.triangles, api.triangles, l.counts]));
  await page.selectOption("#brush-mode", "off");
}

// WebGL in headless Chromium: SwiftShader (software), asked for explicitly
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox", "--enable-unsafe-swiftshader"] });
try {
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 }, acceptDownloads: true });
  const page = await context.newPage();
  const errors = [];
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
  page.on("pageerror", (e) => errors.push(String(e)));
  const gone = []; // deltas answered 410 (the journal does not reach back): each logged by Chromium as a console error
  page.on("response", (r) => { if (r.status() === 410 && /format=delta&since=[1-9]/.test(r.url())) gone.push(r.url()); });
  const outside = []; // requests that leave the daemon's origin (none may)
  page.on("request", (q) => {
    const u = new URL(q.url());
    if ((u.protocol === "http:" || u.protocol === "https:" || u.protocol === "ws:") && u.origin !== new URL(base).origin) outside.push(q.url());
  });
  const view = () => page.evaluate(() => window.surfdView.stats());
  const frame = () => page.evaluate(() => new Promise((res) => requestAnimationFrame(() => requestAnimationFrame(res))));
  const glPixels = async () => { await frame(); return page.evaluate(() => document.getElementById("gl").toDataURL()); };
  const dist = (c) => Math.hypot(...c.eye.map((x, k) => x - c.target[k]));
  // The exact picture against the WebGL frame under it: the pixels each covers (not the background)
  // and how well the two silhouettes overlap (intersection over union).
  const lineUp = () => page.evaluate(() => {
    const img = document.getElementById("exact"), gl = document.getElementById("gl"), w = img.naturalWidth, h = img.naturalHeight;
    const mask = (src) => {
      const c = document.createElement("canvas");
      c.width = w, c.height = h;
      const g = c.getContext("2d");
      g.drawImage(src, 0, 0, w, h);
      const d = g.getImageData(0, 0, w, h).data, m = new Uint8Array(w * h);
      for (let i = 0; i < w * h; i++) m[i] = Math.abs(d[4 * i] - 0x20) + Math.abs(d[4 * i + 1] - 0x26) + Math.abs(d[4 * i + 2] - 0x2e) > 40;
      return m;
    };
    const a = mask(img), b = mask(gl);
    let both = 0, either = 0, na = 0;
    for (let i = 0; i < w * h; i++) both += a[i] & b[i], either += a[i] | b[i], na += a[i];
    return { covered: na / (w * h), iou: either ? both / either : 0, w, h, cw: gl.clientWidth, ch: gl.clientHeight };
  });
  const exactArrives = (after) => page.waitForFunction((s) => { const v = window.surfdView.stats(); return v.showing === "exact" && v.exactSerial > s; },
    after, { timeout: 180000 });

  if (TOKEN) { // first without the token: the page says it needs one
    await page.goto(base + "/");
    await page.waitForFunction(() => document.getElementById("token-state").textContent.includes("token"));
    check("without a token the page asks for one", (await page.textContent("#token-state")).includes("wants a token"));
    await page.screenshot({ path: SHOTS + "/0-asks-token.png" });
    await page.fill("#token", TOKEN);
    await page.click("#token-form button[type=submit]");
    errors.length = 0; // the 401s asked for the token, as they should
    await page.reload();
    check("the token is kept in the tab's session storage", (await page.evaluate(() => sessionStorage.getItem("surfd.token"))) === TOKEN);
  } else {
    await page.goto(base + "/");
  }
  check("GET / is the page", (await page.title()) === "surfd");
  await page.waitForFunction(() => document.getElementById("version").textContent !== "");
  await page.screenshot({ path: SHOTS + "/1-loaded-" + tag + ".png" });

  if (!process.env.ONLY) { // (ONLY=workstation: that part alone, while working on it)
  // a file's route and type from the daemon's table of formats (GET /formats)
  await page.waitForFunction(() => state.formats.length > 0);
  for (const [name, route] of [["ct.nii.gz", "isosurface"], ["part.igs", "render"], ["head.mhd", "isosurface"], ["rs.dcm", "model"]]) {
    await page.setInputFiles("#file", { name, mimeType: "application/octet-stream", buffer: Buffer.from("x") });
    check("a file named " + name + " picks POST /" + route + " (the formats' table)", (await page.inputValue("#route")) === route);
  }
  check("... and is sent as the table's type (.nii.gz: application/x-nifti)",
    (await page.evaluate(() => typeOf("ct.nii.gz", "isosurface"))) === "application/x-nifti");
  await page.setInputFiles("#file", CONTOURS);
  check("a .json file picks POST /model", (await page.inputValue("#route")) === "model");
  await page.selectOption("select[name=caps]", "flat");
  await page.click("#go");
  await page.waitForSelector("#job-output dl", { timeout: 120000 });
  await page.screenshot({ path: SHOTS + "/2-model-" + tag + ".png" });
  const shown = (await page.textContent("#job-output dd.volume")).replace(/[^0-9.]/g, "");
  const id = await page.getAttribute("#models-table tbody tr", "data-id");
  fs.writeFileSync(SHOTS + "/model-" + tag + ".id", id); // page.sh checks its STL against its volume
  const api = await (await fetch(base + "/models/" + id, { headers: auth })).json();
  check("the volume on the page is the API's", shown === (api.volume_mm3 / 1000).toFixed(3), shown + " vs " + api.volume_mm3);
  check("the models table lists the model with its baselines",
    (await page.textContent("#models-table tbody tr")).includes((api.volume.cavalieri / 1000).toFixed(3)));

  // the 3D view opens on the new model: its mesh as the API has it
  await page.waitForFunction(() => window.surfdView && window.surfdView.stats().models.some((m) => m.triangles > 0), null, { timeout: 120000 });
  let v = await view();
  const tri = await apiTriangles(id);
  check("the 3D view draws the model with the API's triangles", v.models.length === 1 && v.models[0].id === id &&
    v.models[0].triangles === tri && v.models[0].drawn === tri && v.meshes === 1, JSON.stringify(v.models) + " vs " + tri);
  check("the view is WebGL", v.webgl >= 1);
  check("the page scrolled to the view", await page.evaluate(() => { const r = document.getElementById("viewer").getBoundingClientRect(); return r.top >= -2 && r.top < 200; }));
  await exactArrives(0);
  let lu = await lineUp();
  check("at rest surfd's exact render arrives, not blank", lu.covered > 0.002, JSON.stringify(lu));
  check("... as large as the WebGL view", lu.w === lu.cw && lu.h === lu.ch, JSON.stringify(lu));
  check("... and lined up with the WebGL frame (same camera)", lu.iou > 0.9, JSON.stringify(lu));
  await page.screenshot({ path: SHOTS + "/3-view-exact-" + tag + ".png" });

  // drag to turn: the exact picture gives way to WebGL frames that change
  await page.click("#exact-toggle"); // off: the canvas alone
  const before = await glPixels();
  const box = await page.locator("#gl").boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  v = await view();
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + 160, cy + 40, { steps: 8 });
  await page.mouse.up();
  const turned = await view();
  check("a drag turns the camera", JSON.stringify(turned.camera.eye) !== JSON.stringify(v.camera.eye) &&
    Math.abs(dist(turned.camera) - dist(v.camera)) < 1e-3 * dist(v.camera), JSON.stringify([v.camera, turned.camera]));
  check("... and the WebGL canvas's pixels change", (await glPixels()) !== before);
  await page.screenshot({ path: SHOTS + "/4-turned-" + tag + ".png" });
  await page.click("#exact-toggle"); // on again
  check("the toggle is one click each way", (await page.getAttribute("#exact-toggle", "aria-pressed")) === "true");
  const s0 = (await view()).serial;
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx - 60, cy, { steps: 4 });
  check("while moving the WebGL frame shows", (await view()).showing === "webgl");
  await page.mouse.up();
  await exactArrives(s0);
  lu = await lineUp();
  check("after the drag the exact render comes back, lined up", lu.covered > 0.002 && lu.iou > 0.9, JSON.stringify(lu));

  // zoom with the wheel: nearer, and the scale bar's millimetres shrink with it
  const far = await view(), mmBefore = +(await page.getAttribute("#scale", "data-mm")) / +(await page.getAttribute("#scale", "data-px"));
  await page.mouse.move(cx, cy);
  await page.mouse.wheel(0, -400);
  await frame();
  const near = await view(), mmAfter = +(await page.getAttribute("#scale", "data-mm")) / +(await page.getAttribute("#scale", "data-px"));
  check("the wheel zooms in", dist(near.camera) < 0.95 * dist(far.camera), dist(far.camera) + " -> " + dist(near.camera));
  check("... and the scale bar follows (mm per pixel)", Math.abs(mmAfter / mmBefore - dist(near.camera) / dist(far.camera)) < 0.02,
    mmBefore + " -> " + mmAfter);

  await page.selectOption("#mesh-format", "stl");
  const [dl] = await Promise.all([page.waitForEvent("download", { timeout: 120000 }), page.click("#download")]);
  await dl.saveAs(SHOTS + "/model-" + tag + ".stl");
  check("the STL downloads", dl.suggestedFilename().endsWith(".stl"), dl.suggestedFilename());
  await page.selectOption("#mesh-format", "rtstruct");
  const [rs] = await Promise.all([page.waitForEvent("download", { timeout: 120000 }), page.click("#download")]);
  await rs.saveAs(SHOTS + "/model-" + tag + ".dcm");
  check("the RT Structure Set downloads, named apart from the Encapsulated STL", rs.suggestedFilename().endsWith(".rtstruct.dcm"), rs.suggestedFilename());

  await page.click("#jobs-refresh");
  await page.waitForFunction(() => document.querySelectorAll("#jobs-table tbody tr").length > 0);
  check("the job list shows the jobs", (await page.textContent("#jobs-table tbody")).includes("succeeded"));

  if (!TOKEN) await structures(page, { view, frame, dist, lineUp, exactArrives });
  }
  if (SERIES) await workstation(page, { view, frame });
  if (SERIES || process.env.ONLY === "live") await liveIso(page, { view, frame });

  await page.setViewportSize({ width: 800, height: 1180 }); // a tablet, upright
  const wide = await page.evaluate(() => document.documentElement.scrollWidth);
  // what runs off, when something does: the deepest elements wider than the page that scroll nothing
  const off = wide <= 800 ? "" : await page.evaluate(() => [...document.querySelectorAll("body *")].filter((e) => {
    const r = e.getBoundingClientRect();
    return r.right + window.scrollX > 801 && getComputedStyle(e).overflowX === "visible" && ![...e.children].some((c) => c.getBoundingClientRect().right + window.scrollX > 801);
  }).slice(0, 6).map((e) => e.tagName + "#" + e.id + "." + e.className + " " + Math.round(e.getBoundingClientRect().right + window.scrollX)).join(", "));
  const culprit = wide <= 800 ? "" : await page.evaluate(() => [...document.querySelectorAll("header, main > section, footer")].filter((e) => {
    const d = e.style.display; e.style.display = "none"; const w = document.documentElement.scrollWidth; e.style.display = d; return w <= 800;
  }).map((e) => e.id || e.tagName).join(","));
  check("at tablet width nothing runs off the side", wide <= 800, "scroll width " + wide + ": " + off + "; without " + culprit);
  await page.screenshot({ path: SHOTS + "/5-tablet-" + tag + ".png", fullPage: true });

  await page.evaluate(() => document.getElementById("viewer").scrollIntoView());
  await page.screenshot({ path: SHOTS + "/9-view-800-" + tag + ".png" });
  if (SERIES) {
    await page.evaluate(() => document.getElementById("slices").scrollIntoView());
    await page.screenshot({ path: SHOTS + "/13-slices-800.png" });
  }
  // (a 410 is the API's answer to a delta the journal no longer holds: the page reloads since=0, which
  // liveIso checks; Chromium logs each failed fetch, so exactly that many such lines are expected)
  const real = errors.filter((e) => !/status of 410 \(Gone\)/.test(e));
  check("no console errors (beside one a delta answered 410, which the page reloads)", real.length === 0 &&
    errors.length - real.length === gone.length, errors.join(" | "));
  check("no request left the daemon's origin", outside.length === 0, outside.slice(0, 5).join(" "));
} catch (e) {
  check("the page ran through", false, String(e));
} finally {
  await browser.close();
}
process.exit(failures ? 1 : 0);
