// view_fps.mjs - tests/bench/view_fps.sh's browser side. Each "label=IDS" argument: /#models=IDS
// opened, one line of frames a second while window.surfdView.bench() turns the view. Each
// "brush:label=ID": that isosurface model alone, STROKES brush strokes by mouse on its surface
// (paint and erase in turn, each at its own point near the view's centre), and the medians of
// the time from mouse up to the frame that shows the surface changed, and of its parts: the
// stroke's block computed and sent, the edit's request, the delta fetched and applied, the frame;
// then four iso changes typed in, timed the same way.
import { createRequire } from "node:module";
import path from "node:path";

const require = createRequire(path.resolve(process.env.NODE_PATH || "build/npm/node_modules") + "/");
const { chromium } = require("playwright-core");
const ms = 1000 * +(process.env.SECONDS_EACH || 5), strokes = +(process.env.STROKES || 11);
const median = (xs) => { const s = xs.slice().sort((a, b) => a - b); return s.length % 2 ? s[(s.length - 1) / 2] : (s[s.length / 2 - 1] + s[s.length / 2]) / 2; };
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox", "--enable-unsafe-swiftshader"] });

async function open(ids, live) {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
  await page.goto(process.env.URL + "/#models=" + ids);
  const n = ids.split(",").length;
  await page.waitForFunction(([k, l]) => { const v = window.surfdView && window.surfdView.stats();
    return v && v.models.filter((m) => m.triangles > 0).length === k && (!l || (v.live && v.live.ready)); }, [n, live], { timeout: 600000 });
  await page.click("#exact-toggle"); // WebGL alone
  return page;
}

async function fps(label, ids) {
  const page = await open(ids, false), n = ids.split(",").length;
  const st = await page.evaluate(() => window.surfdView.stats());
  const tri = st.models.reduce((s, m) => s + m.triangles, 0);
  const r = await page.evaluate((t) => window.surfdView.bench(t), ms);
  const size = await page.evaluate(() => [document.getElementById("gl").width, document.getElementById("gl").height]);
  console.log(`${label}: ${n} model(s), ${tri} triangles, canvas ${size.join("x")}: ${r.fps.toFixed(1)} frames/s (${r.frames} in ${Math.round(r.ms)} ms)`);
  await page.close();
}

async function brush(label, id) {
  const page = await open(id, true);
  await page.selectOption("#brush-mode", "paint");
  await page.fill("#brush-radius", "3");
  await page.press("#brush-radius", "Tab");
  await page.evaluate(() => document.getElementById("gl").scrollIntoView());
  const gl = await page.locator("#gl").boundingBox();
  const spots = []; // points of the canvas over the surface, around its centre
  let pickMs = [];
  for (let r = 0.02; r < 0.3 && spots.length < strokes; r += 0.03)
    for (let a = 0; a < 12 && spots.length < strokes; a++) {
      const p = [gl.x + gl.width * (0.5 + r * Math.cos(a * Math.PI / 6)), gl.y + gl.height * (0.5 + r * Math.sin(a * Math.PI / 6))];
      const t = await page.evaluate(([x, y]) => { const t0 = performance.now(); const h = window.surfdView.pickAt(x, y); return [h ? 1 : 0, performance.now() - t0]; }, p);
      pickMs.push(t[1]);
      if (t[0]) spots.push(p);
    }
  const parts = { total: [], compute: [], request: [], delta: [], frame: [] };
  const how = {};
  for (let k = 0; k < spots.length; k++) {
    await page.selectOption("#brush-mode", k % 2 ? "erase" : "paint");
    const [x, y] = spots[k], before = (await page.evaluate(() => window.surfdView.stats().live.strokes.length));
    await page.mouse.move(x, y);
    await page.mouse.down();
    await page.mouse.move(x + 4, y + 2, { steps: 2 });
    await page.mouse.up();
    await page.waitForFunction((b) => { const l = window.surfdView.stats().live; return l.idle && l.strokes.length > b && l.strokes[l.strokes.length - 1].frame; },
      before, { timeout: 600000 });
    const s = (await page.evaluate(() => window.surfdView.stats().live.strokes)).pop();
    parts.total.push(s.frame - s.t0), parts.compute.push(s.sent - s.t0), parts.request.push(s.answered - s.sent);
    parts.delta.push(s.applied - s.answered), parts.frame.push(s.frame - s.applied);
    how[s.how] = (how[s.how] || 0) + 1;
  }
  // iso changes: 300, then back to 226.5, and again (typed into the value, Enter)
  const iso = { total: [], request: [], delta: [], frame: [] }, isoHow = {};
  for (const v of ["300", "226.5", "300", "226.5"]) {
    const before = (await page.evaluate(() => window.surfdView.stats().live.isos.length));
    await page.fill("#iso-value", v);
    await page.press("#iso-value", "Enter");
    await page.waitForFunction((b) => { const l = window.surfdView.stats().live; return l.idle && l.isos.length > b && l.isos[l.isos.length - 1].frame; },
      before, { timeout: 600000 });
    const s = (await page.evaluate(() => window.surfdView.stats().live.isos)).pop();
    iso.total.push(s.frame - s.t0), iso.request.push(s.answered - s.sent), iso.delta.push(s.applied - s.answered), iso.frame.push(s.frame - s.applied);
    isoHow[s.how] = (isoHow[s.how] || 0) + 1;
  }
  const st = await page.evaluate(() => window.surfdView.stats().live);
  const f = (xs) => median(xs).toFixed(0);
  console.log(`${label}: ${spots.length} strokes (radius 3 mm, paint and erase in turn), ${st.triangles} triangles at the end, surface by ` +
    Object.entries(how).map(([k, v]) => v + " " + k).join(", ") + `: stroke to updated surface median ${f(parts.total)} ms ` +
    `(min ${Math.min(...parts.total).toFixed(0)}, max ${Math.max(...parts.total).toFixed(0)}); parts' medians: block ${f(parts.compute)}, ` +
    `edit request ${f(parts.request)}, delta fetched and applied ${f(parts.delta)}, frame ${f(parts.frame)} ms; a pick ${f(pickMs)} ms`);
  console.log(`${label}: 4 iso changes (300, 226.5, 300, 226.5), surface by ` + Object.entries(isoHow).map(([k, v]) => v + " " + k).join(", ") +
    `: value to updated surface median ${f(iso.total)} ms; iso request ${f(iso.request)}, delta or mesh fetched and applied ${f(iso.delta)}, frame ${f(iso.frame)} ms`);
  await page.close();
}

try {
  for (const arg of process.argv.slice(2)) {
    const k = arg.lastIndexOf("="), label = arg.slice(0, k), ids = arg.slice(k + 1);
    if (label.startsWith("brush:")) await brush(label.slice(6), ids);
    else await fps(label, ids);
  }
} finally {
  await browser.close();
}
