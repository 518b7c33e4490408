// robomach teach pendant: a FlexPendant-like page over the REST API (mm, N, deg).
// Plain JS, no build step. Every mutating call carries the bearer token from the token field
// (kept in localStorage); every 4xx/5xx shows its "detail" in the message bar.
"use strict";

const API = "/api";
const TOKEN_KEY = "robomach.token";
const STATE_PERIOD_MS = 200;
const JOB_PERIOD_MS = 250;
const CLICK_MS = 300; // a press shorter than this is a click: one push of the set duration
const DEFAULT_VISER_PORT = 8080;
const TERMINAL = new Set(["done", "succeeded", "success", "completed", "finished",
  "failed", "error", "cancelled", "canceled"]);

const $ = (id) => document.getElementById(id);
let selectedGuide = null;
let learnJob = null;
let stateBusy = false;
let moves = 0; // robot-moving calls answered; a poll that overlaps one is stale

// ---------------------------------------------------------------- messages and requests

function showMessage(text, kind = "error") {
  const box = $("message");
  $("message-text").textContent = text;
  box.classList.toggle("info", kind === "info");
  box.classList.remove("hidden");
}

function clearMessage() {
  $("message").classList.add("hidden");
}

function headers(json) {
  const h = {};
  if (json) h["Content-Type"] = "application/json";
  const token = $("token").value.trim();
  if (token) h["Authorization"] = `Bearer ${token}`;
  return h;
}

function detailOf(body, status) {
  if (body && typeof body === "object" && "detail" in body) {
    const d = body.detail;
    if (typeof d === "string") return d;
    // FastAPI validation errors: a list of {loc, msg}.
    if (Array.isArray(d)) {
      return d.map((e) => `${(e.loc || []).filter((p) => p !== "body").join(".")}: ${e.msg}`)
        .join("; ");
    }
    return JSON.stringify(d);
  }
  return `HTTP ${status}`;
}

// fetch + JSON + error reporting; throws after showing the message.
// Every choice and number range of the core (GET /api/choices, robomach_core.choices): the
// menus (select[data-enum]) and the number inputs' bounds (input[data-range]) follow it, so the
// page never accepts what the server refuses, nor refuses what it takes.
let choicesLoaded = null;
let choicesTexts = null;  // the sentences every page shows alike (choices' "texts")
const CHOICES_LOADED = "choicesloaded";  // a menu got its options (listen to redraw from them)
function loadChoices() {
  if (!choicesLoaded) {
    choicesLoaded = api("GET", "/choices", undefined, { quiet: true }).catch((err) => {
      choicesLoaded = null;
      throw err;
    });
  }
  return choicesLoaded;
}

async function applyChoices(root = document) {
  const choices = await loadChoices();
  choicesTexts = choices.texts || null;
  for (const el of root.querySelectorAll("[data-text]")) {
    const text = choicesTexts && choicesTexts[el.dataset.text];
    if (typeof text === "string") el.textContent = text;
  }
  for (const el of root.querySelectorAll("input[data-range]")) {
    const range = choices.ranges[el.dataset.range];
    if (!range) continue;
    el.min = range.min;
    el.max = range.max;
    // A number with a default has it from the core (limits.py), the one place it is written.
    if (el.value === "" && range.default !== null && range.default !== undefined) {
      el.value = range.default;
    }
    if (!el.title) el.title = `${range.label}: ${range.text}`;
  }
  for (const el of root.querySelectorAll("select[data-enum]")) {
    const choice = choices.enums[el.dataset.enum];
    if (!choice || el.options.length) continue;
    for (const value of choice.values) {
      const option = document.createElement("option");
      option.value = value;
      option.textContent = choice.labels[value] || value;
      el.append(option);
    }
    if (el.dataset.default) el.value = el.dataset.default;
    // Not "change": that means the user chose, and a menu showing the session's state (the
    // click mode) would send its first option over the session's value on every page load.
    el.dispatchEvent(new Event(CHOICES_LOADED));
  }
  return choices;
}

async function api(method, path, body, { text = false, quiet = false } = {}) {
  let response;
  try {
    response = await fetch(API + path, {
      method,
      headers: headers(body !== undefined),
      body: body === undefined ? undefined : JSON.stringify(body),
    });
  } catch (err) {
    setConnected(false);
    if (!quiet) showMessage(`cannot reach the server: ${err.message}`);
    throw err;
  }
  if (!response.ok) {
    let parsed = null;
    try { parsed = await response.json(); } catch (_) { /* not JSON */ }
    const message = detailOf(parsed, response.status);
    if (!quiet) showMessage(message);  // the user's terms: not the route
    const err = new Error(message);
    err.status = response.status;
    throw err;
  }
  if (text) return response.text();
  if (response.status === 204) return null;
  const type = response.headers.get("content-type") || "";
  return type.includes("json") ? response.json() : response.text();
}

function setConnected(ok) {
  const pill = $("connection");
  pill.textContent = ok ? "online" : "offline";
  pill.className = `pill ${ok ? "pill-on" : "pill-off"}`;
}

// ---------------------------------------------------------------- pose display

function eulerZyxDeg([w, x, y, z]) {
  // ABB's EulerZYX convention: R = Rz * Ry * Rx; returns [rx, ry, rz] in degrees.
  const rx = Math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y));
  const sinp = Math.max(-1, Math.min(1, 2 * (w * y - z * x)));
  const ry = Math.asin(sinp);
  const rz = Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
  return [rx, ry, rz].map((a) => (a * 180) / Math.PI);
}

const fmt = (v, digits = 2) => (Number.isFinite(v) ? v.toFixed(digits) : "-");

function showState(state) {
  if (!state || !state.tcp) return;
  const p = state.tcp.position_mm;
  const q = state.tcp.quaternion_wxyz;
  const [rx, ry, rz] = eulerZyxDeg(q);
  $("pose-x").textContent = fmt(p[0]);
  $("pose-y").textContent = fmt(p[1]);
  $("pose-z").textContent = fmt(p[2]);
  $("pose-rx").textContent = fmt(rx);
  $("pose-ry").textContent = fmt(ry);
  $("pose-rz").textContent = fmt(rz);
  $("pose-quat").textContent = q.map((v) => fmt(v, 5)).join(", ");
  $("pose-joints").textContent = (state.joints_deg || []).map((v) => fmt(v, 1)).join(", ");
  const f = (state.wrench && state.wrench.force_N) || [0, 0, 0];
  $("pose-force").textContent =
    `${f.map((v) => fmt(v, 1)).join(", ")} (|F| ${fmt(Math.hypot(...f), 1)})`;
  const contact = $("contact");
  contact.textContent = state.in_contact ? "contact" : "free";
  contact.className = `pill ${state.in_contact ? "pill-warn" : "pill-off"}`;
  showStatus(state.project_status);
}

// Results computed from inputs that changed since are kept but marked "out of date".
function showStatus(status) {
  if (!status) return;
  const reasons = status.reasons || {};
  for (const [id, stage] of [["learn-stale", "recording"], ["post-stale", "postprocess"]]) {
    const stale = status[stage] === "stale";
    $(id).classList.toggle("hidden", !stale);
    if (stale && reasons[stage]) $(id).title = reasons[stage];
  }
}

async function pollState() {
  if (stateBusy) return;
  stateBusy = true;
  const movesBefore = moves;
  try {
    const state = await api("GET", "/state", undefined, { quiet: true });
    // A push or jog answered meanwhile shows a newer pose than this poll may have read.
    if (moves === movesBefore) showState(state);
    setConnected(true);
  } catch (_) {
    setConnected(false);
  } finally {
    stateBusy = false;
  }
}

// ---------------------------------------------------------------- jog, push, compliance

function showMove(state) {
  moves += 1;
  showState(state);
}

async function jog(axis, sign) {
  const rotational = axis.startsWith("r");
  const field = rotational ? "jog-step-deg" : (axis === "z" && $("jog-step-z") ? "jog-step-z" : "jog-step-mm");
  const step = Number($(field).value) * sign;
  const body = { axis, step, frame: $("jog-frame") ? $("jog-frame").value : "tool" };
  const speed = $(rotational ? "jog-rate" : "jog-speed");
  if (speed && Number(speed.value) > 0) body.speed = Number(speed.value);
  showMove(await api("POST", "/leadthrough/jog", body));
}

async function push(dir, sign) {
  const force = [0, 0, 0];
  force[dir] = Number($("push-force").value) * sign;
  const duration = Number($("push-duration").value);
  showMove(await api("POST", "/leadthrough/push", { force_N: force, duration_s: duration }));
}

// Hold-to-push: one push per press, repeated while the button stays pressed.
function bindHold(button, action) {
  let held = false;
  let downAt = 0;
  const loop = async () => {
    do {
      try { await action(); } catch (_) { held = false; }
    } while (held);
  };
  button.addEventListener("pointerdown", (ev) => {
    if (ev.button !== 0 || held) return;
    held = true;
    downAt = performance.now();
    loop();
  });
  for (const ev of ["pointerup", "pointerleave", "pointercancel"]) {
    button.addEventListener(ev, () => {
      // Let go after holding: the push running on the server stops within a control
      // period (a short click gives one whole push of the set duration).
      if (held && performance.now() - downAt > CLICK_MS) {
        api("POST", "/leadthrough/stop", {}, { quiet: true }).catch(() => {});
      }
      held = false;
    });
  }
  // Keyboard users: Enter/Space give one push.
  button.addEventListener("keydown", (ev) => {
    if (ev.key === "Enter" || ev.key === " ") { ev.preventDefault(); action().catch(() => {}); }
  });
}

function showCompliance(c) {
  if (!c || !Array.isArray(c.axes)) return;
  for (const el of document.querySelectorAll(".comp")) el.checked = c.axes.includes(el.value);
  if (c.frame) $("comp-frame").value = c.frame;
}

async function putCompliance() {
  const axes = [...document.querySelectorAll(".comp:checked")].map((el) => el.value);
  showCompliance(await api("PUT", "/leadthrough/compliance", { axes, frame: $("comp-frame").value }));
}

// ---------------------------------------------------------------- guide points

function guideRows(body) {
  if (Array.isArray(body)) return body;
  return (body && (body.guide_points || body.items)) || [];
}

function guideForce(g) {
  if (Array.isArray(g.force_N)) return Math.hypot(...g.force_N);
  if (typeof g.force_N === "number") return g.force_N;
  return NaN;
}

function showGuides(body) {
  const rows = guideRows(body);
  const tbody = $("guide-list");
  tbody.textContent = "";
  rows.forEach((g, i) => {
    const index = g.index ?? i;
    const p = g.position_mm || (g.tcp && g.tcp.position_mm) || [NaN, NaN, NaN];
    const tr = document.createElement("tr");
    tr.dataset.index = index;
    tr.className = index === selectedGuide ? "selected" : "";
    for (const v of [String(index + 1), fmt(p[0], 1), fmt(p[1], 1), fmt(p[2], 1),
      fmt(guideForce(g), 1)]) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
    tr.addEventListener("click", () => {
      selectedGuide = index;
      for (const other of tbody.children) other.classList.toggle("selected", other === tr);
    });
    tbody.appendChild(tr);
  });
  if (!rows.some((g, i) => (g.index ?? i) === selectedGuide)) selectedGuide = null;
  $("guide-count").textContent = rows.length;
}

const refreshGuides = async () => showGuides(await api("GET", "/guide-points"));

async function recordGuide() {
  await api("POST", "/guide-points", {});
  await refreshGuides();
}

async function deleteGuide() {
  if (selectedGuide === null) {
    showMessage("select a guide point in the list first");
    return;
  }
  await api("DELETE", `/guide-points/${selectedGuide}`);
  selectedGuide = null;
  await refreshGuides();
}

// ---------------------------------------------------------------- jobs

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function fraction(progress) {
  const p = Number(progress) || 0;
  return p > 1 ? p / 100 : p;
}

// Polls a job to its end, reporting progress; resolves with the final job body.
async function followJob(jobId, onProgress) {
  for (;;) {
    const job = await api("GET", `/jobs/${jobId}`, undefined, { quiet: true });
    onProgress(job);
    if (TERMINAL.has(String(job.status).toLowerCase())) return job;
    await sleep(JOB_PERIOD_MS);
  }
}

function jobFailed(job) {
  const s = String(job.status).toLowerCase();
  return s === "failed" || s === "error";
}

async function loadExample() {
  const start = await api("POST", "/guide-points/example", {});
  const jobId = start.job_id ?? start.id;
  $("example-progress-row").classList.remove("hidden");
  $("guide-example").disabled = true;
  try {
    const job = await followJob(jobId, (j) => {
      $("example-progress").value = fraction(j.progress);
      $("example-status").textContent = `${j.status} ${Math.round(fraction(j.progress) * 100)} %`;
    });
    if (jobFailed(job)) showMessage(`load the example: ${job.error || job.status}`);
  } finally {
    $("guide-example").disabled = false;
    await refreshGuides();
  }
}

async function startLearning() {
  const body = {
    force_N: Number($("learn-force").value),
    speed_mm_s: Number($("learn-speed").value),
    closed: $("learn-closed").checked,
    wall_side: $("learn-wall-side").value,
    floor_clearance_mm: Number($("learn-floor").value),
  };
  const start = await api("POST", "/path-learning", body);
  showLearnWarnings(start.findings || start.warnings || []);
  learnJob = start.job_id ?? start.id;
  $("learn-start").disabled = true;
  $("learn-cancel").disabled = false;
  try {
    const job = await followJob(learnJob, (j) => {
      $("learn-progress").value = fraction(j.progress);
      $("learn-status").textContent = `${j.status} ${Math.round(fraction(j.progress) * 100)} %`;
    });
    if (jobFailed(job)) showMessage(`path learning: ${job.error || job.status}`);
    $("learn-status").textContent = job.error ? `${job.status}: ${job.error}` : job.status;
  } finally {
    learnJob = null;
    $("learn-start").disabled = false;
    $("learn-cancel").disabled = true;
  }
}

// The check before a run with the card's settings (refusals come first); shown again by itself
// whenever the guide points or the cell change (quietly: no message bar for a check).
async function checkGuides({ quiet = false } = {}) {
  const q = new URLSearchParams({
    force_N: $("learn-force").value,
    closed: $("learn-closed").checked,
    wall_side: $("learn-wall-side").value || "auto",  // its menu may not be filled yet
  });
  const check = await api("GET", `/path-learning/check?${q}`, undefined, { quiet });
  showLearnWarnings(check.findings, check.wall_side);
}

async function cancelLearning() {
  if (learnJob !== null) await api("POST", `/jobs/${learnJob}/cancel`, {});
}

// ---------------------------------------------------------------- post-processing, export

function pick(obj, ...keys) {
  for (const k of keys) if (obj && obj[k] !== undefined && obj[k] !== null) return obj[k];
  return undefined;
}

async function runPostprocess() {
  const body = {
    force_min_N: Number($("post-fmin").value),
    force_max_N: Number($("post-fmax").value),
    tolerance_mm: Number($("post-tol").value),
    arcs: $("post-arcs").checked,
  };
  showPostprocess(await api("POST", "/postprocess", body));
}

function showPostprocessSettings(s) {
  if (!s) return;
  if (s.force_min_N !== undefined) $("post-fmin").value = s.force_min_N;
  if (s.force_max_N !== undefined) $("post-fmax").value = s.force_max_N;
  if (s.tolerance_mm !== undefined) $("post-tol").value = s.tolerance_mm;
  if (s.arcs !== undefined) $("post-arcs").checked = s.arcs;
}

function showPostprocess(r) {
  if (!r) return;
  const counts = r.counts || r;
  const dev = r.deviation || r.deviations || r.score || r;
  $("post-samples").textContent = pick(counts, "samples_raw", "samples") ?? "-";
  $("post-filtered").textContent = pick(counts, "samples_filtered", "filtered") ?? "-";
  $("post-targets").textContent = pick(counts, "targets", "targets_count", "reduced") ?? "-";
  const max = pick(dev, "max_deviation_mm", "max_mm");
  const rms = pick(dev, "rms_deviation_mm", "rms_mm");
  $("post-max").textContent = max === undefined ? "n/a" : `${fmt(max, 3)} mm`;
  $("post-rms").textContent = rms === undefined ? "n/a" : `${fmt(rms, 3)} mm`;
  const meshMax = pick(r, "mesh_max_deviation_mm");
  const meshRms = pick(r, "mesh_rms_deviation_mm");
  const over = pick(r, "mesh_overcut_mm");
  const air = pick(r, "mesh_air_mm");
  $("post-mesh").textContent =
    meshMax === undefined
      ? "n/a"
      : `max ${fmt(meshMax, 3)} mm, RMS ${fmt(meshRms, 3)} mm` +
        (over === undefined || over === null ? "" : `; overcut ${fmt(over, 3)}, air ${fmt(air, 3)} mm`);
  const follows = pick(r, "follows_taught_wall");
  $("post-taught").textContent =
    follows === undefined || follows === null ? "-" : `${follows ? "\u2714" : "\u26d4"} ${r.taught_wall}`;
  const problems = r.problems || [];
  const list = $("post-problems");
  list.replaceChildren(
    ...problems.map((p) => {
      const li = document.createElement("li");
      li.textContent = `\u26d4 not fit to machine: ${p}`;
      return li;
    }),
  );
  list.classList.toggle("hidden", problems.length === 0);
  const moves = pick(r, "moves");
  $("post-moves").textContent =
    moves === undefined
      ? "-"
      : `${moves} (${r.circular_moves || 0} circular; straight program ${r.straight_moves})`;
}

// The check before a run (docs/guide_points.md): each finding marked by its severity, in the
// words every page uses (GET /api/choices "texts"): a refusal (learning will not start) in red
// and bold, a warning in amber, a note in grey; and the wall side the run will follow.
function findingItem(f) {
  const li = document.createElement("li");
  const finding = typeof f === "string" ? { severity: "warning", message: f } : f;
  li.className = `finding finding-${finding.severity}`;
  li.dataset.severity = finding.severity;
  const texts = (choicesTexts && choicesTexts.severity) || {};
  const icons = (choicesTexts && choicesTexts.severity_icon) || {};
  const label = document.createElement("b");
  label.textContent = `${icons[finding.severity] || ""} ${texts[finding.severity] || finding.severity}: `;
  const also = (finding.also_at || []).map((k) => `G${k}`).join(", ");
  li.append(label, document.createTextNode(
    also ? `${finding.message} (the same at ${also})` : finding.message));
  return li;
}

function showLearnWarnings(findings, wallSide) {
  const list = $("learn-warnings");
  list.replaceChildren(...findings.map(findingItem));
  list.classList.toggle("hidden", findings.length === 0);
  if (wallSide !== undefined) {
    $("learn-wall").textContent = wallSide;
    $("learn-wall").classList.toggle("hidden", !wallSide);
  }
}

// ---------------------------------------------------------------- export
// The menus come from GET /api/export/languages (the server's language registry): the
// languages the arm's controller runs and their files.

let exportLanguages = [];

function option(value, label) {
  const o = document.createElement("option");
  o.value = value;
  o.textContent = label;
  return o;
}

async function loadLanguages() {
  const all = await api("GET", "/export/languages", undefined, { quiet: true });
  const previous = $("export-language").value;
  exportLanguages = all.filter((l) => l.offered);
  $("export-language").replaceChildren(...exportLanguages.map((l) => option(l.name, l.title)));
  if (exportLanguages.some((l) => l.name === previous)) $("export-language").value = previous;
  showExportFiles();
}

function showExportFiles() {
  const lang = exportLanguages.find((l) => l.name === $("export-language").value);
  const previous = $("export-file").value;
  const files = lang ? [...lang.files, ...(lang.force_control_files || [])] : [];
  $("export-file").replaceChildren(...files.map((f) => option(f, f)));
  if (files.includes(previous)) $("export-file").value = previous;
  $("export-download").textContent = files.length ? `Download ${$("export-file").value}` : "Download";
}

// One file of the program in the chosen language (GET /api/export/program/{language}).
async function programFile(file) {
  const language = $("export-language").value;
  if (!language) throw new Error("this arm's controller runs none of the program languages");
  const fc = file.startsWith("program_fc.");
  const query = new URLSearchParams({ file, force_control: String(fc) });
  if (fc) query.set("module_name", "LearnedPathFC");
  return api("GET", `/export/program/${encodeURIComponent(language)}?${query}`, undefined, {
    text: true,
  });
}

async function previewProgram() {
  await loadLanguages();
  const lang = exportLanguages.find((l) => l.name === $("export-language").value);
  const text = await programFile(lang ? lang.files[0] : "");
  const pre = $("rapid-preview");
  pre.textContent = text;
  pre.classList.remove("hidden");
}

async function downloadProgram() {
  await loadLanguages();
  const file = $("export-file").value;
  const text = await programFile(file);
  const url = URL.createObjectURL(new Blob([text], { type: "text/plain" }));
  const a = document.createElement("a");
  a.href = url;
  a.download = file;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

// ---------------------------------------------------------------- viser scene

// The scene URL: ?viser=<url> wins; then the server's /api/health "viser_url" (or
// "viser_port" on this page's host), or /api/workbench "viser_port"; else port 8080.
async function viserUrl() {
  const fromQuery = new URLSearchParams(location.search).get("viser");
  if (fromQuery) return fromQuery;
  const host = location.hostname || "localhost";
  try {
    const health = await api("GET", "/health", undefined, { quiet: true });
    setConnected(true);
    if (health && health.viser_url) {
      // A server bound to 0.0.0.0 does not know the name the browser used.
      const u = new URL(health.viser_url, location.href);
      if (["0.0.0.0", "::", "[::]"].includes(u.hostname)) u.hostname = host;
      return u.toString();
    }
    if (health && health.viser_port) return `${location.protocol}//${host}:${health.viser_port}/`;
    const wb = await api("GET", "/workbench", undefined, { quiet: true });
    if (wb && wb.viser_port) return `${location.protocol}//${host}:${wb.viser_port}/`;
  } catch (_) { /* fall through to the default */ }
  return `${location.protocol}//${host}:${DEFAULT_VISER_PORT}/`;
}

// ---------------------------------------------------------------- wiring

// What the server already holds: compliance, post-processing settings and the last result.
async function loadSettings() {
  showCompliance(await api("GET", "/leadthrough/compliance", undefined, { quiet: true }));
  const trace = await api("GET", "/path-learning/recording?max_points=2", undefined,
    { quiet: true }).catch(() => null);
  if (trace && trace.source === "recording") {
    $("learn-progress").value = 1;
    $("learn-status").textContent = `recorded ${trace.samples_total} samples: ${trace.stop_reason}`;
  }
  const post = await api("GET", "/postprocess", undefined, { quiet: true });
  if (post) {
    showPostprocessSettings(post.settings);
    showPostprocess(post.result);
  }
}

function safe(fn) {
  // Errors were already shown by api(); keep them out of the console's uncaught list.
  return (...args) => fn(...args).catch(() => {});
}

async function init() {
  const token = $("token");
  token.value = localStorage.getItem(TOKEN_KEY) || "";
  token.addEventListener("change", () => localStorage.setItem(TOKEN_KEY, token.value.trim()));
  await applyChoices().catch(() => {});  // the menus and bounds; pollState says if it is down
  $("message-close").addEventListener("click", clearMessage);

  for (const b of document.querySelectorAll("button.jog")) {
    b.addEventListener("click", safe(() => jog(b.dataset.axis, Number(b.dataset.sign))));
  }
  for (const b of document.querySelectorAll("button.push")) {
    bindHold(b, () => push(Number(b.dataset.dir), Number(b.dataset.sign)));
  }
  for (const el of document.querySelectorAll(".comp, #comp-frame")) {
    el.addEventListener("change", safe(putCompliance));
  }
  $("guide-record").addEventListener("click", safe(recordGuide));
  $("guide-delete").addEventListener("click", safe(deleteGuide));
  $("guide-example").addEventListener("click", safe(loadExample));
  $("learn-start").addEventListener("click", safe(startLearning));
  $("learn-cancel").addEventListener("click", safe(cancelLearning));
  $("learn-check").addEventListener("click", safe(() => checkGuides()));
  $("learn-wall-side").addEventListener("change", safe(() => checkGuides()));
  $("learn-closed").addEventListener("change", safe(() => checkGuides({ quiet: true })));
  $("post-run").addEventListener("click", safe(runPostprocess));
  $("export-preview").addEventListener("click", safe(previewProgram));
  $("export-download").addEventListener("click", safe(downloadProgram));
  $("export-language").addEventListener("change", showExportFiles);
  $("export-language").addEventListener("focus", safe(loadLanguages));
  $("export-file").addEventListener("change", showExportFiles);

  const url = await viserUrl();
  $("viser-frame").src = url;
  $("viser-link").href = url;
  $("viser-link").textContent = url;

  await pollState();
  safe(refreshGuides)();
  safe(loadSettings)();
  safe(loadLanguages)();
  setInterval(pollState, STATE_PERIOD_MS);
}

document.addEventListener("DOMContentLoaded", init);
