// robomach teach pendant: the Machining card (issue 8). Uses pendant.js's api(), followJob(),
// fraction(), safe() and $(): settings, run / compare with progress and cancel, the comparison
// table, the choice the exports carry, and a small force / feed plot along the path (canvas).
"use strict";

const MACHINING_CONTROLLERS = ["constant", "fixed-pi", "adaptive-pi", "fuzzy", "two-stage",
  "adaptive-lq"];
const MACHINING_COMPENSATIONS = ["off", "offline", "online"];
let machiningJob = null;

function machiningCard() {
  const options = (names) => names.map((n) => `<option value="${n}">${n}</option>`).join("");
  const card = document.createElement("fieldset");
  card.className = "card";
  card.id = "machining-card";
  card.innerHTML = `
    <legend>Machining <span id="mach-stale" class="pill pill-warn hidden"
      title="the program or the settings changed since: run it again">out of date</span></legend>
    <div class="row">
      <label>K <input id="mach-gain" type="number" min="0.1" max="10000" step="0.5"> N</label>
      <label>&alpha; <input id="mach-alpha" type="number" min="0" max="3" step="0.05"></label>
      <label>&beta; <input id="mach-beta" type="number" min="0.01" max="2" step="0.05"></label>
      <label>Limit <input id="mach-limit" type="number" min="1.5" max="1400" step="5"> N</label>
    </div>
    <div class="row">
      <label>Controller <select id="mach-controller">${options(MACHINING_CONTROLLERS)}</select></label>
      <label>Compensation <select id="mach-compensation">${options(MACHINING_COMPENSATIONS)}</select></label>
      <span class="small">stock: <span id="mach-stock">-</span></span>
    </div>
    <div class="row">
      <button id="mach-run" class="primary">Run</button>
      <button id="mach-compare">Compare all</button>
      <button id="mach-cancel" disabled>Cancel</button>
      <progress id="mach-progress" max="1" value="0"></progress>
      <span id="mach-status" class="small">idle</span>
    </div>
    <div id="mach-table" class="small"></div>
    <div class="row">
      <select id="mach-pick" aria-label="configuration to choose"></select>
      <button id="mach-choose" disabled>Choose</button>
      <span id="mach-chosen" class="small"></span>
    </div>
    <canvas id="mach-plot" width="560" height="200" aria-label="force and feed along the path"></canvas>`;
  return card;
}

function showMachiningSettings(s) {
  $("mach-gain").value = s.process_gain_N;
  $("mach-alpha").value = s.depth_exponent;
  $("mach-beta").value = s.feed_exponent;
  $("mach-limit").value = s.force_limit_N;
  $("mach-controller").value = s.controller;
  $("mach-compensation").value = s.compensation;
  $("mach-stock").textContent = s.stock_source;
  $("mach-chosen").textContent = `chosen: ${s.controller} / ${s.compensation}`;
  $("mach-stale").classList.toggle("hidden", s.status !== "stale");
}

async function putMachiningSettings() {
  const body = {
    process_gain_N: Number($("mach-gain").value),
    depth_exponent: Number($("mach-alpha").value),
    feed_exponent: Number($("mach-beta").value),
    force_limit_N: Number($("mach-limit").value),
  };
  showMachiningSettings(await api("PUT", "/machining/settings", body));
}

async function putMachiningChoice(controller, compensation) {
  showMachiningSettings(await api("PUT", "/machining/choice", { controller, compensation }));
}

const machCell = (v, d = 1) => (v === null || v === undefined ? "-" : (typeof v === "number" ? v.toFixed(d) : String(v)));

function showComparison(rows) {
  const head = ["controller", "comp.", "cycle [s]", "vs const [%]", "F peak [N]", "wall max [mm]",
    "wall rms [mm]", "x real time"];
  const body = rows.map((r) => `<tr${r.chosen ? ' class="chosen"' : ""}><td>${r.controller}</td>`
    + `<td>${r.compensation}</td><td>${r.cycle_time_s === null ? "stopped" : machCell(r.cycle_time_s)}</td>`
    + `<td>${machCell(r.faster_than_constant_pct, 0)}</td><td>${machCell(r.force_peak_N)}</td>`
    + `<td>${machCell(r.wall_error_max_mm, 3)}</td><td>${machCell(r.wall_error_rms_mm, 3)}</td>`
    + `<td>${machCell(r.realtime_factor, 0)}</td></tr>`).join("");
  $("mach-table").innerHTML = `<table id="mach-comparison" class="results-table"><thead><tr>`
    + head.map((h) => `<th>${h}</th>`).join("") + `</tr></thead><tbody>${body}</tbody></table>`;
  $("mach-pick").innerHTML = rows.map((r) => {
    const v = `${r.controller}/${r.compensation}`;
    return `<option value="${v}"${r.chosen ? " selected" : ""}>${v}</option>`;
  }).join("");
  $("mach-choose").disabled = rows.length === 0;
}

function drawMachiningPlot(trace) {
  const canvas = $("mach-plot");
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, pad = 28;
  ctx.clearRect(0, 0, W, H);
  if (!trace || trace.path_mm.length < 2) return;
  const x = trace.path_mm;
  const xmax = x[x.length - 1] || 1;
  const fmax = Math.max(trace.limit_N, ...trace.force_max_N) * 1.1;
  const vmax = Math.max(...trace.feed_max_mm_s, 1) * 1.1;
  const px = (v) => pad + (W - 2 * pad) * v / xmax;
  const line = (ys, top, color, dash = []) => {
    ctx.beginPath();
    ctx.setLineDash(dash);
    ctx.strokeStyle = color;
    ys.forEach((y, i) => {
      const X = px(x[i]), Y = H - pad - (H - 2 * pad) * y / top;
      if (i === 0) ctx.moveTo(X, Y); else ctx.lineTo(X, Y);
    });
    ctx.stroke();
  };
  line(trace.force_N, fmax, "#d62728");
  line(x.map(() => trace.limit_N), fmax, "#000", [4, 3]);
  line(x.map(() => trace.reference_N), fmax, "#1d3557", [8, 4]);
  line(trace.feed_mm_s, vmax, "#2a9d8f");
  ctx.setLineDash([]);
  ctx.fillStyle = "#333";
  ctx.font = "11px sans-serif";
  ctx.fillText(`force (red, 0-${fmax.toFixed(0)} N), limit, reference; feed (green, 0-${vmax.toFixed(1)} mm/s)`, pad, 12);
  ctx.fillText(`path 0-${xmax.toFixed(0)} mm: ${trace.controller} / ${trace.compensation}`, pad, H - 8);
}

async function loadMachiningResult() {
  let result;
  try {
    result = await api("GET", "/machining/result?points=400", undefined, { quiet: true });
  } catch (err) {
    if (err.status === 409) { $("mach-table").textContent = "no machining result yet"; return; }
    throw err;
  }
  showComparison(result.runs);
  drawMachiningPlot(result.trace);
  $("mach-stale").classList.toggle("hidden", result.status !== "stale");
}

async function startMachining(kind) {
  const start = await api("POST", `/machining/${kind}`, {});
  machiningJob = start.job_id;
  $("mach-run").disabled = $("mach-compare").disabled = true;
  $("mach-cancel").disabled = false;
  try {
    const job = await followJob(machiningJob, (j) => {
      $("mach-progress").value = fraction(j.progress);
      $("mach-status").textContent = `${j.status} ${Math.round(fraction(j.progress) * 100)} %`;
    });
    $("mach-status").textContent = job.error ? `${job.status}: ${job.error}` : job.status;
    if (job.status === "failed") showMessage(`machining: ${job.error || job.status}`);
  } finally {
    machiningJob = null;
    $("mach-run").disabled = $("mach-compare").disabled = false;
    $("mach-cancel").disabled = true;
  }
  await loadMachiningResult();
  showMachiningSettings(await api("GET", "/machining/settings", undefined, { quiet: true }));
}

async function initMachining() {
  const pendant = document.querySelector("section.pendant");
  const exportCard = $("export-card");
  pendant.insertBefore(machiningCard(), exportCard);
  for (const id of ["mach-gain", "mach-alpha", "mach-beta", "mach-limit"]) {
    $(id).addEventListener("change", safe(putMachiningSettings));
  }
  for (const id of ["mach-controller", "mach-compensation"]) {
    $(id).addEventListener("change", safe(() => putMachiningChoice(
      $("mach-controller").value, $("mach-compensation").value)));
  }
  $("mach-run").addEventListener("click", safe(() => startMachining("run")));
  $("mach-compare").addEventListener("click", safe(() => startMachining("compare")));
  $("mach-cancel").addEventListener("click", safe(async () => {
    if (machiningJob !== null) await api("POST", `/jobs/${machiningJob}/cancel`, {});
  }));
  $("mach-choose").addEventListener("click", safe(() => {
    const [controller, compensation] = $("mach-pick").value.split("/");
    return putMachiningChoice(controller, compensation);
  }));
  showMachiningSettings(await api("GET", "/machining/settings", undefined, { quiet: true }));
  await loadMachiningResult();
}

document.addEventListener("DOMContentLoaded", () => { initMachining().catch(() => {}); });
