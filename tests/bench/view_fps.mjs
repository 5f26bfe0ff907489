// view_fps.mjs - tests/bench/view_fps.sh's browser side: opens /#models=IDS for each "label=IDS"
// argument and prints one line of frames a second while window.surfdView.bench() turns the view.
import { createRequire } from "node:module";
import path from "node:path";

const require = createRequire(path.resolve(process.env.NODE_PATH || "build/npm/node_modules") + "/");
const { chromium } = require("playwright-core");
const ms = 1000 * +(process.env.SECONDS_EACH || 5);
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox", "--enable-unsafe-swiftshader"] });
try {
  for (const arg of process.argv.slice(2)) {
    const [label, ids] = arg.split("=");
    const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
    await page.goto(process.env.URL + "/#models=" + ids);
    const n = ids.split(",").length;
    await page.waitForFunction((k) => window.surfdView && window.surfdView.stats().models.filter((m) => m.triangles > 0).length === k,
      n, { timeout: 300000 });
    await page.click("#exact-toggle"); // WebGL alone while turning
    const st = await page.evaluate(() => window.surfdView.stats());
    const tri = st.models.reduce((s, m) => s + m.triangles, 0);
    const r = await page.evaluate((t) => window.surfdView.bench(t), ms);
    const size = await page.evaluate(() => [document.getElementById("gl").width, document.getElementById("gl").height]);
    console.log(`${label}: ${n} model(s), ${tri} triangles, canvas ${size.join("x")}: ${r.fps.toFixed(1)} frames/s (${r.frames} in ${Math.round(r.ms)} ms)`);
    await page.close();
  }
} finally {
  await browser.close();
}
