// app.js - the page at / (index.html): submits a file to the route the user picks as a job,
// follows its progress (cancel on the way), lists the stored models with their volumes beside
// the baselines, opens them in the 3D view (view.js, window.surfdView; /#models=ID,ID opens those),
// downloads their meshes, lists the jobs. Standard DOM and fetch only; the bearer token lives in
// this tab's sessionStorage and goes in the Authorization header, never in a URL.
"use strict";

const $ = (id) => document.getElementById(id);
const TOKEN_KEY = "surfd.token";
const state = { job: null, formats: [], inView: [], pacs: [], series: null, files: [] };

// ---- requests ------------------------------------------------------------------------------

function token() { return sessionStorage.getItem(TOKEN_KEY) || ""; }

async function api(method, path, { body, type, headers, signal } = {}) {
  const h = Object.assign({}, headers || {});
  if (token()) h.Authorization = "Bearer " + token();
  if (type) h["Content-Type"] = type;
  const r = await fetch(path, { method, headers: h, body, signal });
  if (r.status === 401) askToken();
  return r;
}

// The problem+json body of a failed answer as one line: detail, and where (the pointer).
async function problemOf(r) {
  try {
    return problemText(await r.json());
  } catch (e) {
    return r.status + " " + r.statusText;
  }
}

function problemText(p) {
  if (!p) return "failed";
  const at = (p.errors || []).map((e) => e.pointer).filter((x) => x).join(", ");
  return (p.title ? p.title + ": " : "") + (p.detail || "") + (at ? " (at " + at + ")" : "");
}

function askToken() {
  $("token-state").textContent = token() ? "the server refused this token" : "the server wants a token";
  $("token").focus();
}

// ---- the form ------------------------------------------------------------------------------

// The daemon's table of input formats (GET /formats), asked for until it comes (a token may be needed first).
async function loadFormats() {
  if (state.formats.length) return;
  const f = await api("GET", "/formats");
  if (f.ok) state.formats = (await f.json()).formats;
}

// A file's format by its name on a route (null for every route), from the table.
function formatOf(name, route) {
  const n = name.toLowerCase();
  return state.formats.find((f) => (!route || f.routes.includes("/" + route)) && f.extensions.some((e) => n.endsWith(e)));
}

// Content-Type of a file for a route, from the table (a file it does not know: sniffed by the daemon).
function typeOf(name, route) {
  const f = formatOf(name, route);
  return f ? f.media[0] : "application/octet-stream";
}

// The route a file goes to: contours and structure sets to /model, scenes to /render, volumes to
// /isosurface.
function routeFor(name) {
  const f = formatOf(name, null);
  if (!f || f.routes.includes("/model")) return "model";
  return f.routes.includes("/render") ? "render" : "isosurface";
}

function showOptions() {
  const route = $("route").value;
  for (const el of document.querySelectorAll("[data-for]")) {
    const on = el.dataset.for.split(" ").includes(route);
    el.hidden = !on;
    for (const input of el.querySelectorAll("input, select")) input.disabled = !on;
  }
}

// The query of the chosen route from the form's visible options.
function queryOf(form, route) {
  const q = new URLSearchParams();
  const names = { model: ["method", "caps", "roi"], volume: ["method", "caps", "roi"],
    isosurface: ["iso", "levels", "max_error", "features", "dims", "type", "spacing"],
    "matrix-model": ["iso", "dims", "type", "spacing"], render: ["width", "height", "rmethod"] }[route];
  for (const n of names) {
    const el = form.elements[n];
    if (!el || el.disabled) continue;
    const v = el.type === "checkbox" ? (el.checked ? el.value : "") : el.value.trim();
    if (v) q.set(n === "rmethod" ? "method" : n, v);
  }
  const s = q.toString();
  return s ? "?" + s : "";
}

// ---- what was dropped -------------------------------------------------------------------------

const base = (name) => name.replace(/^.*[\\/]/, "").replace(/\.(nii\.gz|[^.]*)$/i, "");
const isDicomName = (name) => /\.(dcm|dicom|ima)$/i.test(name) || !/\.[^./\\]{1,5}$/.test(name);

// What the files chosen or dropped are, as one request: a single file; a header and its data
// file (.mhd/.nhdr with .raw...) as the multipart pair the volume routes read; several DICOM files
// (a series, a folder of one) as a multipart series. {kind, body(), type, name, label}.
function upload(files) {
  files = files.filter((f) => f.size > 0 && !/^\./.test(f.name) && !/^(DICOMDIR|.*\.(txt|json\.bak))$/i.test(f.name));
  if (!files.length) return null;
  const header = files.find((f) => /\.(mhd|nhdr)$/i.test(f.name));
  if (header && files.length === 2) {
    const data = files.find((f) => f !== header);
    return { kind: "pair", name: base(header.name), label: header.name + " with " + data.name, type: undefined,
      body: () => { const fd = new FormData(); fd.append("header", header, header.name); fd.append("data", data, data.name); return fd; } };
  }
  if (files.length > 1) {
    const dicom = files.filter((f) => isDicomName(f.name));
    if (dicom.length !== files.length) return { error: "several files are read as one DICOM series (.dcm) or a header with its data file (.mhd or .nhdr, and its .raw); not " + files.map((f) => f.name).slice(0, 4).join(", ") };
    // (the parts' own names may name the patient: numbered instead, as surfctl does)
    return { kind: "series", name: "", label: files.length + " DICOM files (a series)", type: undefined,
      body: () => { const fd = new FormData(); files.forEach((f, k) => fd.append("slice", f, "slice" + String(k + 1).padStart(4, "0") + ".dcm")); return fd; } };
  }
  const f = files[0];
  return { kind: "one", name: isDicomName(f.name) ? "" : base(f.name), label: f.name, file: f, body: () => f };
}

// The files of a drop, folders walked (a DICOM folder: every file under it).
async function droppedFiles(dt) {
  const entries = [...(dt.items || [])].map((i) => (i.webkitGetAsEntry ? i.webkitGetAsEntry() : null)).filter((e) => e);
  if (!entries.length) return [...dt.files];
  const out = [];
  const walk = async (e) => {
    if (e.isFile) out.push(await new Promise((res, rej) => e.file(res, rej)));
    else if (e.isDirectory) {
      const reader = e.createReader();
      for (;;) {
        const batch = await new Promise((res, rej) => reader.readEntries(res, rej));
        if (!batch.length) break;
        for (const x of batch) await walk(x);
      }
    }
  };
  for (const e of entries) await walk(e);
  return out;
}

// Files chosen: what they are said, the intent that fits them picked.
async function chosen(files) {
  await loadFormats();
  state.files = files;
  const u = upload(files);
  $("file-what").textContent = !u ? "" : u.error || "Chosen: " + u.label;
  if (!u || u.error) return;
  $("route").value = u.kind === "one" ? routeFor(u.file.name) : "isosurface";
  showOptions();
}

async function submit(ev) {
  ev.preventDefault();
  const form = $("job-form"), u = upload(state.files), route = $("route").value;
  if (!u) { $("file").focus(); return; }
  if (u.error) { setError(u.error); return; }
  setError("");
  $("progress-box").hidden = true; // the last job's "succeeded 100 %" is not this one's
  $("job-output").replaceChildren();
  $("go").disabled = true;
  try {
    await loadFormats();
    let q = queryOf(form, route);
    if (u.name && (route === "isosurface" || route === "model") && !/[?&]name=/.test(q)) // named from the source
      q += (q ? "&" : "?") + "name=" + encodeURIComponent(u.name);
    const r = await api("POST", "/" + route + q, { body: u.body(), type: u.kind === "one" ? typeOf(u.file.name, route) : undefined,
      headers: { Prefer: "respond-async" } });
    if (r.status !== 202) {
      setError(r.ok ? "unexpected answer " + r.status : await problemOf(r));
      return;
    }
    await follow(await r.json(), route, u.name || "volume");
  } catch (e) {
    setError(String(e));
  } finally {
    $("go").disabled = false;
    $("cancel").disabled = true;
  }
}

function setError(text) {
  $("job-error").textContent = text;
  $("job-error").hidden = !text;
}

function setProgress(job) {
  $("progress-box").hidden = false;
  $("progress").value = job.progress || 0;
  $("progress-text").textContent = job.state + " " + Math.round(100 * (job.progress || 0)) + " %";
}

const sleep = (ms) => new Promise((res) => setTimeout(res, ms));

// Polls the job until it ends, backing off from 200 ms to 2 s; then shows its result.
async function follow(job, route, fileName) {
  state.job = job.id;
  $("cancel").disabled = false;
  let wait = 200;
  while (job.state === "queued" || job.state === "running") {
    setProgress(job);
    await sleep(wait);
    wait = Math.min(2000, wait * 1.5);
    const r = await api("GET", "/jobs/" + job.id);
    if (!r.ok) { setError(await problemOf(r)); return; }
    job = await r.json();
  }
  setProgress(job);
  state.job = null;
  refreshJobs();
  if (job.state !== "succeeded") {
    setError(job.state === "cancelled" ? "the job was cancelled" : problemText(job.error));
    return;
  }
  const r = await api("GET", "/jobs/" + job.id + "/result");
  if (!r.ok) { setError(await problemOf(r)); return; }
  if (route === "render") {
    const img = new Image();
    img.alt = "The rendered scene";
    img.src = URL.createObjectURL(await r.blob());
    img.id = "render-result";
    $("job-output").replaceChildren(img);
    return;
  }
  const answer = await r.json();
  if (route === "matrix-model") {
    const a = document.createElement("a");
    a.href = URL.createObjectURL(new Blob([JSON.stringify(answer)], { type: "application/json" }));
    a.download = fileName.replace(/\.[^.]*$/, "") + ".matrices.json";
    a.textContent = "Download the matrices (" + answer.matrix_model.size.join(" × ") + " voxels, exact: " + answer.exact + ")";
    $("job-output").replaceChildren(a);
    return;
  }
  const models = answer.models || [answer];
  $("job-output").replaceChildren(...models.map(figures));
  if ((answer.skipped || []).length) { // an RT Structure Set's ROIs that made no model, and why
    const p = document.createElement("p");
    p.className = "skipped";
    p.textContent = "Not modelled: " + answer.skipped.map((x) => x.name + " (" + x.reason + ")").join("; ");
    $("job-output").prepend(p);
  }
  if (route !== "volume") {
    await refreshModels();
    const stored = models.filter((m) => m.id);
    if (stored.length) view(stored);
  }
}

async function cancel() {
  if (!state.job) return;
  const r = await api("POST", "/jobs/" + state.job + "/cancel");
  if (!r.ok && r.status !== 202) setError(await problemOf(r));
}

// ---- figures and models ---------------------------------------------------------------------

const cm3 = (mm3) => (typeof mm3 === "number" ? (mm3 / 1000).toFixed(3) : "—");

function volumes(m) {
  const v = m.volume || {};
  return { surfd: m.volume_mm3, trapezoid: v.trapezoid, cavalieri: v.cavalieri, frustum: v.frustum };
}

// A model's (or a measured volume's) figures as a definition list.
function figures(m) {
  const dl = document.createElement("dl");
  dl.className = "figures";
  dl.dataset.volume = m.volume_mm3;
  const v = volumes(m);
  const rows = [["Name", m.name || m.id || ""], ["Volume (surfd)", cm3(v.surfd) + " cm³"],
    ["Trapezoid", cm3(v.trapezoid) + " cm³"], ["Cavalieri", cm3(v.cavalieri) + " cm³"],
    ["Frustum", cm3(v.frustum) + " cm³"], ["Area", m.area_mm2 ? (m.area_mm2 / 100).toFixed(2) + " cm²" : "—"],
    ["Caps", m.caps || "—"], ["Source", m.source || "contours"]];
  for (const [k, val] of rows) {
    const dt = document.createElement("dt"), dd = document.createElement("dd");
    dt.textContent = k;
    dd.textContent = val;
    if (k === "Volume (surfd)") dd.className = "volume";
    dl.append(dt, dd);
  }
  return dl;
}

function cell(text, cls) {
  const td = document.createElement("td");
  td.textContent = text;
  if (cls) td.className = cls;
  return td;
}

function button(text, fn, label) {
  const b = document.createElement("button");
  b.type = "button";
  b.className = "small";
  b.textContent = text;
  b.setAttribute("aria-label", label);
  b.addEventListener("click", fn);
  return b;
}

async function refreshModels() {
  const r = await api("GET", "/models");
  const body = $("models-table").tBodies[0];
  if (!r.ok) { body.replaceChildren(); return; }
  const list = (await r.json()).models || [];
  const named = new Map();
  for (const m of list) named.set(m.name || m.id, (named.get(m.name || m.id) || 0) + 1);
  body.replaceChildren(...list.map((m) => {
    const tr = document.createElement("tr");
    tr.dataset.id = m.id;
    const v = volumes(m), name = cell(m.name || m.id);
    if (named.get(m.name || m.id) > 1) { // rows one can tell apart: when it was made, and its id
      const small = document.createElement("span");
      small.className = "muted twin";
      small.textContent = " " + (m.created ? new Date(m.created).toLocaleString() + " · " : "") + m.id.slice(0, 8);
      name.append(small);
    }
    tr.append(name, cell(m.source || "contours"), cell(m.caps || "—"), cell(cm3(v.surfd), "num"),
      cell(cm3(v.trapezoid), "num"), cell(cm3(v.cavalieri), "num"), cell(cm3(v.frustum), "num"),
      cell(m.triangles ? m.triangles + " triangles" : (m.patches || 0) + " patches", "num"));
    const td = document.createElement("td");
    td.className = "actions";
    td.append(button("View", () => view([m]), "View " + (m.name || m.id)),
      button("Add", () => view([m], true), "Add " + (m.name || m.id) + " to the view"));
    if (m.source === "isosurface" && m.grid)
      td.append(button("Slices", () => slicesOfModel(m), "Slices of " + (m.name || m.id) + "'s volume"));
    td.append(
      button("Delete", () => remove(m), "Delete " + (m.name || m.id)));
    tr.append(td);
    return tr;
  }));
}

async function remove(m) {
  if (!confirm("Delete the model " + (m.name || m.id) + "?")) return;
  const r = await api("DELETE", "/models/" + m.id);
  if (!r.ok) setError(await problemOf(r));
  const v = await whenView();
  v.close(m.id);
  state.inView = state.inView.filter((x) => x.id !== m.id);
  downloadChoices();
  refreshModels();
}

// ---- the 3D view (view.js) -------------------------------------------------------------------

// The view module, once it has run (a module script runs after this one).
function whenView() {
  if (window.surfdView) return Promise.resolve(window.surfdView);
  return new Promise((res) => window.addEventListener("surfdview", () => res(window.surfdView), { once: true }));
}

// Opens model resources in the 3D view (added to what it shows with add), scrolled to and focused.
async function view(list, add = false) {
  const v = await whenView();
  $("viewer").hidden = false;
  $("viewer").scrollIntoView({ block: "start" });
  $("gl").focus({ preventScroll: true });
  $("download-state").textContent = ""; // the last download's name is not this view's
  state.inView = add ? state.inView.concat(list.filter((m) => !state.inView.some((x) => x.id === m.id))) : list.slice();
  downloadChoices();
  await v.open(list, { add });
}

function downloadChoices() {
  $("download-model").replaceChildren(...state.inView.map((m) => {
    const o = document.createElement("option");
    o.value = m.id;
    o.textContent = m.name || m.id;
    return o;
  }));
}

// /#models=ID,ID: those models in the view; #series=UID a series' slices (with the models on its
// frame, or &models= those); #volume=ID a model's samples (a bookmark, a link from a colleague).
async function openFromAddress() {
  const a = {};
  for (const part of location.hash.replace(/^#/, "").split("&")) {
    const kv = /^(models|series|volume)=([\w,.-]+)$/.exec(part);
    if (kv) a[kv[1]] = kv[2];
  }
  const v = await whenView();
  const shown = v.stats().volume;
  if (a.series && !(shown && shown.what === "series" && shown.id === a.series)) {
    await openSeries(a.series, a.models ? a.models.split(",") : null);
    return;
  }
  if (a.volume && !(shown && shown.what === "model" && shown.id === a.volume)) {
    const r = await api("GET", "/models/" + encodeURIComponent(a.volume));
    if (r.ok) await slicesOfModel(await r.json(), a.models ? null : undefined);
    else setError("not opened: " + a.volume + " (" + (await problemOf(r)) + ")");
    if (!a.models) return;
  }
  if (!a.models) return;
  const ids = a.models.split(",").filter((x) => x);
  if (ids.join(",") === v.ids().join(",")) return;
  const found = [], missing = [];
  for (const id of ids) {
    const r = await api("GET", "/models/" + encodeURIComponent(id));
    if (r.ok) found.push(await r.json());
    else missing.push(id + " (" + (await problemOf(r)) + ")");
  }
  if (found.length) await view(found);
  if (missing.length) setError("not opened: " + missing.join(", "));
}

// ---- slices, series and PACS -----------------------------------------------------------------

// A job route's answer: at once, or its job followed until it ends (GET /jobs/ID), then its result.
async function jobResult(method, path, opts = {}) {
  let r = await api(method, path, opts);
  if (r.status === 202) {
    const loc = r.headers.get("Location") || "/jobs/" + (await r.json()).id;
    for (let wait = 200; ; wait = Math.min(2000, wait * 1.5)) {
      await sleep(wait);
      const j = await api("GET", loc);
      if (!j.ok) throw new Error(await problemOf(j));
      const job = await j.json();
      if (job.state === "succeeded") break;
      if (job.state === "failed" || job.state === "cancelled") throw new Error(job.error ? problemText(job.error) : job.state);
    }
    r = await api("GET", loc + "/result");
  }
  if (!r.ok) throw new Error(await problemOf(r));
  return r;
}

// An isosurface model's volume in the slice views, the model in the 3D view (unless models is null).
async function slicesOfModel(m, models) {
  const v = await whenView();
  state.series = null;
  $("surface-from").hidden = true;
  if (models !== null) await view([m]);
  $("slices").scrollIntoView({ block: "start" });
  try {
    await v.openVolume("model", m.id, m.name || m.id);
  } catch (e) { /* said in the slices' caption */ }
}

// A series' samples in the slice views, with the models made on it (its frame of reference) or
// those ids, in the 3D view.
async function openSeries(uid, ids) {
  const v = await whenView();
  const r = await api("GET", "/series/" + encodeURIComponent(uid));
  if (!r.ok) { setError("series " + uid + ": " + (await problemOf(r))); return; }
  const se = await r.json();
  state.series = se;
  const name = seriesName(se);
  $("surface-from").hidden = false;
  if ((se.modality || "") !== "CT") $("surface-iso").value = "";
  let list = [];
  const all = await api("GET", "/models");
  if (all.ok) {
    const ms = (await all.json()).models || [];
    list = ids ? ms.filter((m) => ids.includes(m.id))
      : ms.filter((m) => (m.referenced_series && m.referenced_series.series_instance_uid === uid) ||
        (se.frame_of_reference_uid && m.frame_of_reference_uid === se.frame_of_reference_uid));
  }
  $("slices").hidden = false;
  $("slices").scrollIntoView({ block: "start" });
  if (list.length) await view(list);
  else { v.open([]); state.inView = []; downloadChoices(); }
  try {
    await v.openVolume("series", uid, name);
  } catch (e) { /* said in the slices' caption */ }
  $("slice-axial").focus({ preventScroll: true });
}

function seriesName(se) {
  return (se.modality || "series") + " · " + (se.dims ? se.dims.join(" × ") + " · " : "") + (se.instances || 0) + " instance" + (se.instances === 1 ? "" : "s");
}

// "Make a surface" of the open series at the iso value: an isosurface model, added to the view.
async function surfaceOfSeries() {
  const se = state.series, iso = $("surface-iso").value.trim();
  if (!se) return;
  if (!iso) { $("surface-iso").focus(); $("slices-caption").textContent = "give the value the surface passes through"; return; }
  $("surface-make").disabled = true;
  $("slices-caption").textContent = "making the surface at " + iso + "…";
  try {
    const q = new URLSearchParams({ series: se.uid, iso, name: (se.modality || "series") + " surface at " + iso });
    const m = await (await jobResult("POST", "/isosurface?" + q)).json();
    $("slices-caption").textContent = "surface made: " + m.triangles + " triangles, " + cm3(m.volume_mm3) + " cm³";
    await refreshModels();
    await view([m], true);
    $("slices").scrollIntoView({ block: "start" });
  } catch (e) {
    $("slices-caption").textContent = "no surface: " + e.message;
  } finally {
    $("surface-make").disabled = false;
  }
}

// GET /series: the series received, grouped by study (what the API gives: no patient names).
async function refreshSeries() {
  const r = await api("GET", "/series");
  const box = $("series-list");
  if (!r.ok) { box.replaceChildren(); $("series").hidden = true; return; }
  const list = (await r.json()).series || [];
  $("series").hidden = false;
  if (!list.length) {
    const p = document.createElement("p");
    p.className = "muted";
    p.textContent = "None yet: a PACS or planning system sends series to surfd's DICOM node (serve --dicom-listen).";
    box.replaceChildren(p);
    return;
  }
  const studies = new Map();
  for (const se of list) {
    const k = se.study_uid || "";
    if (!studies.has(k)) studies.set(k, []);
    studies.get(k).push(se);
  }
  let n = 0;
  box.replaceChildren(...[...studies].map(([study, ses]) => {
    const div = document.createElement("div"), h = document.createElement("h3");
    div.className = "study";
    h.textContent = study ? "Study " + (++n) + " (" + study + ")" : "No study";
    const table = document.createElement("table"), body = document.createElement("tbody");
    table.className = "series-table";
    body.append(...ses.map((se) => {
      const tr = document.createElement("tr");
      tr.dataset.uid = se.uid;
      tr.append(cell(se.modality || "—"), cell((se.instances || 0) + " instance" + (se.instances === 1 ? "" : "s"), "num"),
        cell(se.source || ""), cell(se.last_received ? new Date(se.last_received).toLocaleString() : ""), cell(se.uid, "uid"));
      const td = document.createElement("td");
      const job = se.links && se.links.job;
      if (se.modality === "RTSTRUCT") {
        td.append(job ? button("Models", () => openJobModels(job.replace(/^\/jobs\//, "")), "Models made of structure set " + se.uid)
          : button("Make models", () => modelsOfSeries(se), "Make the models of structure set " + se.uid));
      } else {
        td.append(button("Open", () => { location.hash = "series=" + se.uid; }, "Open series " + se.uid + " in the slice views"));
      }
      tr.append(td);
      return tr;
    }));
    table.append(body);
    const scroll = document.createElement("div");
    scroll.className = "scroll";
    scroll.append(table);
    div.append(h, scroll);
    return div;
  }));
}

async function openJobModels(job) {
  try {
    const a = await (await jobResult("GET", "/jobs/" + job + "/result")).json();
    const ms = a.models || [a];
    if (ms.length) await view(ms);
  } catch (e) { setError(e.message); }
}

async function modelsOfSeries(se) {
  setError("");
  try {
    const a = await (await jobResult("POST", "/model?series=" + encodeURIComponent(se.uid))).json();
    await refreshModels();
    await view(a.models || [a]);
  } catch (e) { setError(e.message); }
}

// GET /pacs: the PACS a model can be sent to (the send row shows only when there is one).
async function loadPacs() {
  const r = await api("GET", "/pacs");
  state.pacs = r.ok ? (await r.json()).pacs || [] : [];
  $("send-row").hidden = !state.pacs.length;
  $("send-pacs").replaceChildren(...state.pacs.map((p) => {
    const o = document.createElement("option");
    o.value = o.textContent = p.name;
    return o;
  }));
}

// One click: the chosen model of the view to the chosen PACS, as an RT Structure Set or a SEG.
async function sendToPacs() {
  const m = state.inView.find((x) => x.id === $("download-model").value), pacs = $("send-pacs").value, as = $("send-as").value;
  if (!m || !pacs) return;
  $("send").disabled = true;
  $("send-state").textContent = "sending " + (m.name || m.id) + " to " + pacs + "…";
  try {
    const a = await (await jobResult("POST", "/models/" + m.id + "/send?" + new URLSearchParams({ pacs, as }))).json();
    const ok = (a.instances || []).filter((i) => i.stored).length;
    $("send-state").textContent = "sent to " + pacs + ": " + ok + " of " + (a.instances || []).length + " instance" +
      ((a.instances || []).length === 1 ? "" : "s") + " stored";
    $("send-state").dataset.stored = ok;
  } catch (e) {
    $("send-state").textContent = "not sent: " + e.message;
    $("send-state").dataset.stored = 0;
  } finally {
    $("send").disabled = false;
  }
}

async function download() {
  const m = state.inView.find((x) => x.id === $("download-model").value), fmt = $("mesh-format").value;
  if (!m) return;
  $("download-state").textContent = fmt === "rtstruct" ? "cutting the structure set…" : "meshing…";
  const r = await api("GET", "/models/" + m.id + (fmt === "rtstruct" ? "/rtstruct" : "/mesh?format=" + fmt));
  if (!r.ok) { $("download-state").textContent = await problemOf(r); return; }
  const a = $("download-link");
  a.href = URL.createObjectURL(await r.blob());
  // (the two DICOM objects named apart: NAME.rtstruct.dcm, NAME.stl.dcm)
  a.download = (m.name || m.id).replace(/[^\w.-]+/g, "_") + "." + ({ rtstruct: "rtstruct.dcm", "dicom-stl": "stl.dcm" }[fmt] || fmt);
  a.click();
  $("download-state").textContent = "downloaded " + a.download;
}

// ---- jobs ------------------------------------------------------------------------------------

async function refreshJobs() {
  const r = await api("GET", "/jobs");
  const body = $("jobs-table").tBodies[0];
  if (!r.ok) { body.replaceChildren(); return; }
  const list = (await r.json()).jobs || [];
  body.replaceChildren(...list.slice(0, 50).map((j) => {
    const tr = document.createElement("tr");
    tr.append(cell(j.id.slice(0, 12)), cell(j.kind), cell(j.state), cell(Math.round(100 * (j.progress || 0)) + " %", "num"),
      cell(j.created ? new Date(j.created).toLocaleString() : ""), cell(j.error ? problemText(j.error) : ""));
    return tr;
  }));
}

// ---- start -----------------------------------------------------------------------------------

async function start() {
  $("token").value = token();
  $("token-form").addEventListener("submit", (ev) => {
    ev.preventDefault();
    sessionStorage.setItem(TOKEN_KEY, $("token").value.trim());
    $("token-state").textContent = token() ? "token kept for this tab" : "";
    refreshAll();
  });
  $("token-forget").addEventListener("click", () => {
    sessionStorage.removeItem(TOKEN_KEY);
    $("token").value = "";
    $("token-state").textContent = "token forgotten";
  });
  $("route").addEventListener("change", showOptions);
  $("file").addEventListener("change", () => chosen([...$("file").files]));
  $("folder").addEventListener("change", () => chosen([...$("folder").files]));
  const drop = $("drop");
  drop.addEventListener("dragover", (ev) => { ev.preventDefault(); drop.classList.add("over"); });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", async (ev) => {
    ev.preventDefault();
    drop.classList.remove("over");
    const files = await droppedFiles(ev.dataTransfer);
    if (files.length) chosen(files);
  });
  $("job-form").addEventListener("submit", submit);
  $("cancel").addEventListener("click", cancel);
  whenView().then((v) => v.init({ api, problemOf }));
  window.addEventListener("hashchange", openFromAddress);
  $("download").addEventListener("click", download);
  $("models-refresh").addEventListener("click", refreshModels);
  $("series-refresh").addEventListener("click", refreshSeries);
  $("surface-make").addEventListener("click", surfaceOfSeries);
  $("send").addEventListener("click", sendToPacs);
  $("jobs-refresh").addEventListener("click", refreshJobs);
  showOptions();
  refreshAll();
}

async function refreshAll() {
  const r = await api("GET", "/version");
  if (r.ok) {
    const v = await r.json();
    $("version").textContent = v.version || "";
  }
  await loadFormats();
  await Promise.all([refreshModels(), refreshJobs(), refreshSeries(), loadPacs()]);
  await openFromAddress();
}

start();
