// robomach teach pendant: the Machining card (issues 8, 16). Uses pendant.js's api(),
// followJob(), fraction(), safe() and $(): settings, the cell's options and the variations, run /
// compare with progress and cancel, the comparison table (sortable by clicking a header, the
// rule's pick and its reason, configurations the cell cannot run greyed), the choice the exports
// carry, and a force / feed plot along the path that opens large.
"use strict";

let machiningJob = null;
let machiningRows = [];
let machiningSort = { key: null, up: true };
let machiningTrace = null;

// The controllers, compensations, cell options and the bounds come from GET /api/choices.
function machiningCard(choices) {
  const options = choices.enums.cell_option;
  const card = document.createElement("fieldset");
  card.className = "card";
  card.id = "machining-card";
  card.innerHTML = `
    <legend>Machining <span id="mach-stale" class="pill pill-warn hidden"
      title="the program or the settings changed since: run it again">out of date</span></legend>
    <div class="row">
      <label>K <input id="mach-gain" type="number" data-range="MACHINING_PROCESS_GAIN_N" step="0.5"> N</label>
      <label>&alpha; <input id="mach-alpha" type="number" data-range="MACHINING_DEPTH_EXPONENT" step="0.05"></label>
      <label>&beta; <input id="mach-beta" type="number" data-range="MACHINING_FEED_EXPONENT" step="0.05"></label>
      <label>Limit <input id="mach-limit" type="number" data-range="MACHINING_FORCE_LIMIT_N" step="5"> N</label>
    </div>
    <div class="row">
      <label>Controller <select id="mach-controller" data-enum="cmrr_controller"></select></label>
      <label>Compensation <select id="mach-compensation" data-enum="compensation"></select></label>
      <label title="under offline compensation, how fuzzy and two-stage pick their stage: online (switching in the cell by the force) or planned (the program's speeds, no feed control in the cell)">Stages <select id="mach-stages" data-enum="machining_stages"></select></label>
      <span class="small">stock: <span id="mach-stock">-</span></span>
    </div>
    <div class="row">
      <span class="small">cell options:</span>
      ${options.values.map((v) => `<label class="small"><input type="checkbox" class="mach-option" value="${v}"> ${options.labels[v]}</label>`).join("")}
      <button id="mach-options-default" class="small">defaults</button>
      <label>Variations <input id="mach-variations" type="number" data-range="MACHINING_VARIATIONS" step="1"></label>
    </div>
    <div id="mach-notes" class="small"></div>
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
    <canvas id="mach-plot" width="560" height="200" aria-label="force and feed along the path"></canvas>
    <button id="mach-plot-large" disabled>Open the plot large</button>
    <div id="mach-large" class="mach-large hidden" role="dialog" aria-label="machining plot, large">
      <button id="mach-large-close">Close</button>
      <canvas id="mach-plot-big" aria-label="force and feed along the path, large"></canvas>
    </div>`;
  return card;
}

function showMachiningSettings(s) {
  $("mach-gain").value = s.process_gain_N;
  $("mach-alpha").value = s.depth_exponent;
  $("mach-beta").value = s.feed_exponent;
  $("mach-limit").value = s.force_limit_N;
  $("mach-controller").value = s.controller;
  $("mach-compensation").value = s.compensation;
  $("mach-stages").value = s.stages;
  $("mach-stock").textContent = s.stock_source;
  $("mach-chosen").textContent = `chosen: ${s.controller} / ${s.compensation}`;
  $("mach-stale").classList.toggle("hidden", s.status !== "stale");
  for (const box of document.querySelectorAll(".mach-option")) {
    box.checked = s.cell_options.includes(box.value);
  }
  $("mach-variations").value = s.variations;
  const notes = Object.values(s.stale_settings || {}).map((t) => `stale: ${t}`);
  if (s.program_needs) notes.push(`program: ${s.program_needs}`);
  $("mach-notes").textContent = notes.join(" | ");
}

async function putCellOptions() {
  const chosen = [...document.querySelectorAll(".mach-option")].filter((b) => b.checked)
    .map((b) => b.value);
  showMachiningSettings(await api("PUT", "/machining/settings", { cell_options: chosen }));
  await loadMachiningResult();
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

const MACH_COLUMNS = [
  ["cycle_time_s", "cycle [s]", 1], ["faster_than_constant_pct", "vs const [%]", 0],
  ["force_peak_N", "F peak [N]", 1], ["wall_error_max_mm", "wall max [mm]", 3],
  ["wall_error_rms_mm", "wall rms [mm]", 3]];
const MACH_P95 = [["cycle_time_p95_s", "cycle p95", 1], ["force_peak_p95_N", "peak p95", 1],
  ["wall_error_max_p95_mm", "wall p95", 3], ["within_limit_share", "in limit", 2]];

function sortedMachiningRows() {
  const rows = machiningRows.map((r, i) => [i, r]);
  const { key, up } = machiningSort;
  if (!key) return rows;
  const have = rows.filter(([, r]) => r[key] !== null && r[key] !== undefined);
  const lack = rows.filter(([, r]) => r[key] === null || r[key] === undefined);
  have.sort(([, a], [, b]) => (up ? 1 : -1) * (a[key] - b[key]));
  return have.concat(lack);
}

function showComparison(rows, reason, notes = []) {
  machiningRows = rows;
  const varied = rows.some((r) => r.cycle_time_p95_s !== undefined);
  const cols = MACH_COLUMNS.concat(varied ? MACH_P95 : []);
  const arrow = (k) => (machiningSort.key === k ? (machiningSort.up ? " \u25b2" : " \u25bc") : "");
  const head = `<th data-key="">configuration${arrow(null)}</th>`
    + cols.map(([k, h]) => `<th data-key="${k}" title="sort by ${h}">${h}${arrow(k)}</th>`).join("");
  const body = sortedMachiningRows().map(([, r]) => {
    const cls = [r.chosen ? "chosen" : "", r.runnable === false ? "unrunnable" : "",
      r.completed ? "" : "stopped"].filter(Boolean).join(" ");
    const why = r.needs ? `the cell lacks ${r.needs.join(" and ")}`
      : (r.refused ? r.refused : (r.completed ? "" : `stopped: ${r.stop_reason || "stopped"}`));
    const cells = cols.map(([k, , d]) => {
      if (k === "cycle_time_s" && !r.completed) return `<td class="status">${r.refused ? "refused" : "stopped"}</td>`;
      return `<td>${machCell(r[k], d)}</td>`;
    }).join("");
    return `<tr class="${cls}" title="${safeText(why)}"><td>${r.chosen ? "\u2605 " : ""}${r.controller} / ${r.compensation}</td>${cells}</tr>`;
  }).join("");
  $("mach-table").innerHTML = `<div class="mach-table-wrap"><table id="mach-comparison" class="results-table">`
    + `<thead><tr>${head}</tr></thead><tbody>${body}</tbody></table></div>`
    + `<p id="mach-reason" class="small">${reason ? `Rule's pick: ${safeText(reason)}` : ""}</p>`
    + notes.map((n) => `<p class="small mach-note">${safeText(n)}</p>`).join("");
  for (const th of $("mach-table").querySelectorAll("th")) {
    th.addEventListener("click", () => {
      const key = th.dataset.key || null;
      machiningSort = { key, up: machiningSort.key === key ? !machiningSort.up : true };
      showComparison(machiningRows, reason, notes);
    });
  }
  $("mach-pick").innerHTML = rows.map((r) => {
    const v = `${r.controller}/${r.compensation}`;
    const off = r.runnable === false ? " (cell lacks an option)" : "";
    return `<option value="${v}"${r.chosen ? " selected" : ""}>${v}${off}</option>`;
  }).join("");
  $("mach-choose").disabled = rows.length === 0;
}

function safeText(text) {
  return String(text).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
}

function drawMachiningPlot(trace, canvasId = "mach-plot") {
  if (canvasId === "mach-plot") {
    machiningTrace = trace;
    $("mach-plot-large").disabled = !trace;
  }
  const canvas = $(canvasId);
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
  showComparison(result.runs, result.choice_reason, result.notes || []);
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
  const card = machiningCard(await loadChoices());
  pendant.insertBefore(card, exportCard);
  await applyChoices(card);
  for (const id of ["mach-gain", "mach-alpha", "mach-beta", "mach-limit"]) {
    $(id).addEventListener("change", safe(putMachiningSettings));
  }
  for (const id of ["mach-controller", "mach-compensation"]) {
    $(id).addEventListener("change", safe(() => putMachiningChoice(
      $("mach-controller").value, $("mach-compensation").value)));
  }
  for (const box of document.querySelectorAll(".mach-option")) {
    box.addEventListener("change", safe(putCellOptions));
  }
  $("mach-options-default").addEventListener("click", safe(async () => {
    showMachiningSettings(await api("PUT", "/machining/settings", { cell_options_default: true }));
    await loadMachiningResult();
  }));
  $("mach-stages").addEventListener("change", safe(async () => {
    showMachiningSettings(await api("PUT", "/machining/settings",
      { stages: $("mach-stages").value }));
    await loadMachiningResult();
  }));
  $("mach-variations").addEventListener("change", safe(async () => {
    showMachiningSettings(await api("PUT", "/machining/settings",
      { variations: Number($("mach-variations").value) }));
  }));
  $("mach-plot-large").addEventListener("click", () => {
    const big = $("mach-plot-big");
    big.width = Math.max(800, Math.floor(window.innerWidth * 0.92));
    big.height = Math.max(400, Math.floor(window.innerHeight * 0.75));
    $("mach-large").classList.remove("hidden");
    drawMachiningPlot(machiningTrace, "mach-plot-big");
  });
  $("mach-large-close").addEventListener("click", () => $("mach-large").classList.add("hidden"));
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
