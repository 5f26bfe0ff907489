// page.mjs - the web page driven as a person would, in Debian's headless Chromium through
// playwright-core (nothing downloaded): load /, upload a contour file, wait for the job, read the
// volume shown against the API's, see the render, turn it by keyboard, download the STL and the
// RT Structure Set. Prints
// "PASS: ..." / "FAIL: ..." lines (tests/web/page.sh counts them); screenshots into SHOTS.
// Environment: URL, CONTOURS (a contour JSON), SHOTS (a directory), TOKEN (optional), NODE_PATH.
import { createRequire } from "node:module";
import path from "node:path";

// playwright-core lives in build/npm (NODE_PATH), which ES modules do not search: required from there
const require = createRequire(path.resolve(process.env.NODE_PATH || "build/npm/node_modules") + "/");
const { chromium } = require("playwright-core");

const { URL: base, CONTOURS, SHOTS, TOKEN = "" } = process.env;
const tag = TOKEN ? "token" : "open";
let failures = 0;
const check = (name, ok, detail = "") => {
  console.log((ok ? "PASS: " : "FAIL: ") + name + " (" + tag + ")" + (ok || !detail ? "" : ": " + detail));
  if (!ok) failures++;
};
const auth = TOKEN ? { Authorization: "Bearer " + TOKEN } : {};

const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox"] });
try {
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 }, acceptDownloads: true });
  const page = await context.newPage();
  const errors = [];
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
  page.on("pageerror", (e) => errors.push(String(e)));

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
  const api = await (await fetch(base + "/models/" + id, { headers: auth })).json();
  check("the volume on the page is the API's", shown === (api.volume_mm3 / 1000).toFixed(3), shown + " vs " + api.volume_mm3);
  check("the models table lists the model with its baselines",
    (await page.textContent("#models-table tbody tr")).includes((api.volume.cavalieri / 1000).toFixed(3)));

  await page.waitForFunction(() => document.getElementById("view").naturalWidth > 0, null, { timeout: 120000 });
  const first = await page.getAttribute("#view", "src");
  await page.screenshot({ path: SHOTS + "/3-rendered-" + tag + ".png" });
  check("the model's render appears", first && first.startsWith("blob:"));

  await page.focus("#azimuth");
  for (let k = 0; k < 3; k++) await page.keyboard.press("ArrowRight");
  await page.waitForFunction(() => document.getElementById("view").dataset.azimuth === "45", null, { timeout: 120000 });
  check("turned by keyboard: a new view at azimuth 45", (await page.getAttribute("#view", "src")) !== first);
  const focusRing = await page.evaluate(() => getComputedStyle(document.activeElement).outlineStyle);
  check("the focused control shows its focus", focusRing !== "none", focusRing);
  await page.screenshot({ path: SHOTS + "/4-turned-" + tag + ".png" });

  await page.selectOption("#mesh-format", "stl");
  const [dl] = await Promise.all([page.waitForEvent("download", { timeout: 120000 }), page.click("#download")]);
  await dl.saveAs(SHOTS + "/model-" + tag + ".stl");
  check("the STL downloads", dl.suggestedFilename().endsWith(".stl"), dl.suggestedFilename());
  await page.selectOption("#mesh-format", "rtstruct");
  const [rs] = await Promise.all([page.waitForEvent("download", { timeout: 120000 }), page.click("#download")]);
  await rs.saveAs(SHOTS + "/model-" + tag + ".dcm");
  check("the RT Structure Set downloads", rs.suggestedFilename().endsWith(".dcm"), rs.suggestedFilename());

  await page.click("#jobs-refresh");
  await page.waitForFunction(() => document.querySelectorAll("#jobs-table tbody tr").length > 0);
  check("the job list shows the jobs", (await page.textContent("#jobs-table tbody")).includes("succeeded"));

  await page.setViewportSize({ width: 800, height: 1180 }); // a tablet, upright
  const wide = await page.evaluate(() => document.documentElement.scrollWidth);
  check("at tablet width nothing runs off the side", wide <= 800, "scroll width " + wide);
  await page.screenshot({ path: SHOTS + "/5-tablet-" + tag + ".png", fullPage: true });

  check("no console errors", errors.length === 0, errors.join(" | "));
} catch (e) {
  check("the page ran through", false, String(e));
} finally {
  await browser.close();
}
process.exit(failures ? 1 : 0);
