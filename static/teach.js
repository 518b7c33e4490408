// robomach teach pendant: quick teaching on top of pendant.js (same page, its helpers).
//  - server push: GET /api/events (server-sent events) keeps the page in sync with viser and
//    scripts; EventSource reconnects by itself after a restart, and the 3D scene reloads then;
//    polling (pendant.js) stays as the fallback.
//  - jog frame shown beside the numbers, touch-off buttons, the tool's gap and force,
//  - keyboard jogging (arrows, PageUp/PageDown, Shift = 10x) and G/Enter to record,
//  - the browser Gamepad API: sticks jog at a speed, button A records,
//  - teaching by pointing: what a click on the part does, a typed point forwarded through
//    REST, the proposed guide points with their reachability, accept / delete / discard,
//  - the CAD-only program beside the learned one, Home, Clear all.
"use strict";

const GAMEPAD_PERIOD_MS = 100;
const GAMEPAD_DEADZONE = 0.15;
const TOOL_PERIOD_MS = 200;
const GUIDE_FALLBACK_MS = 2000;
const KEY_JOGS = {
  ArrowLeft: ["x", -1], ArrowRight: ["x", 1],
  ArrowDown: ["y", -1], ArrowUp: ["y", 1],
  PageDown: ["z", -1], PageUp: ["z", 1],
};

let eventsLive = false;
let moving = false; // one motion request at a time from this page
let toolTimer = null;

// ---------------------------------------------------------------- frame labels

function jogFrame() {
  return $("jog-frame").value;
}

function showFrame() {
  for (const el of document.querySelectorAll("[data-frame-label]")) {
    const option = $("jog-frame").selectedOptions[0];  // its words: GET /api/choices
    el.textContent = option ? option.textContent : jogFrame();
  }
}

// ---------------------------------------------------------------- motions

async function exclusive(fn) {
  if (moving) return;
  moving = true;
  document.body.dataset.moving = "";  // for a busy cursor, and for tests to wait on
  try {
    await fn();
  } finally {
    moving = false;
    delete document.body.dataset.moving;
  }
}

async function jogBy(axis, sign, factor = 1) {
  const rotational = axis.startsWith("r");
  const field = rotational ? "jog-step-deg" : axis === "z" ? "jog-step-z" : "jog-step-mm";
  const step = Number($(field).value) * sign * factor;
  const body = { axis, step, frame: jogFrame() };
  const speed = Number($(rotational ? "jog-rate" : "jog-speed").value);
  if (speed > 0) body.speed = speed;
  showMove(await api("POST", "/leadthrough/jog", body));
}

async function touchOff(axis, sign) {
  const body = {
    axis,
    direction: sign,
    force_N: Number($("touch-force").value),
    max_travel_mm: Number($("touch-travel").value),
    frame: jogFrame(),
  };
  clearMessage();
  const state = await api("POST", "/leadthrough/touch-off", body);
  showMove(state);
  const f = state.wrench.force_N;
  showMessage(`touched at ${fmt(Math.hypot(...f), 1)} N: record the guide point (G)`, "info");
}

// A recorded guide point ends the touch-off's "record the guide point" banner.
const recordGuideNow = recordGuide;
// eslint-disable-next-line no-global-assign
recordGuide = async () => {
  await recordGuideNow();
  if (!$("message").classList.contains("hidden") && $("message").classList.contains("info")) {
    clearMessage();
  }
};

// ---------------------------------------------------------------- teaching by pointing

let selectedProposed = null;

function pointMm() {
  return ["point-x", "point-y", "point-z"].map((id) => Number($(id).value));
}

function showPointing(s) {
  if (!s) return;
  $("point-mode").value = s.click_mode;
  if (document.activeElement !== $("point-gap")) $("point-gap").value = s.gap_mm;
  if (document.activeElement !== $("point-height")) $("point-height").value = s.height_above_floor_mm;
}

async function putPointing() {
  showPointing(await api("PUT", "/guide-points/pointing", {
    click_mode: $("point-mode").value,
    gap_mm: Number($("point-gap").value),
    height_above_floor_mm: Number($("point-height").value),
  }));
}

function showProposal(p) {
  const tbody = $("proposal-list");
  tbody.textContent = "";
  const has = Boolean(p && p.points);
  for (const id of ["proposal-accept", "proposal-discard", "proposal-delete"]) $(id).disabled = !has;
  if (!has) {
    $("point-summary").textContent = "";
    selectedProposed = null;
    return;
  }
  const counts = { ok: 0, near: 0, unreachable: 0 };
  for (const q of p.points) counts[q.reach] += 1;
  $("point-summary").textContent =
    `${p.points.length} proposed points along the ${p.closed ? "closed" : "open"} wall ` +
    `(${fmt(p.wall_length_mm, 0)} mm) at z = ${fmt(p.height_wobj_mm, 1)} mm, wall side ` +
    `${p.wall_side}: ${counts.ok} ok, ${counts.near} near a limit, ${counts.unreachable} ` +
    `unreachable. ${p.notes.join(" ")}`;
  for (const q of p.points) {
    const tr = document.createElement("tr");
    tr.className = `reach-${q.reach}` + (q.index === selectedProposed ? " selected" : "");
    tr.title = q.message;
    for (const v of [`P${q.index + 1}`, fmt(q.position_wobj_mm[0], 1), fmt(q.position_wobj_mm[1], 1),
      q.kind, q.reach]) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
    tr.addEventListener("click", () => {
      selectedProposed = q.index;
      for (const other of tbody.children) other.classList.toggle("selected", other === tr);
    });
    tbody.appendChild(tr);
  }
  if (!p.points.some((q) => q.index === selectedProposed)) selectedProposed = null;
}

// The pointing settings say whether anything is proposed: the proposal itself is asked for
// only then (no 404 on every guide-point event while there is none).
async function refreshProposal() {
  const pointing = await api("GET", "/guide-points/pointing", undefined, { quiet: true });
  showPointing(pointing);
  if (!pointing.proposal_points) {
    showProposal(null);
    return;
  }
  try {
    showProposal(await api("GET", "/guide-points/proposal", undefined, { quiet: true }));
  } catch (err) {
    if (err.status === 404) showProposal(null);  // dropped meanwhile (a cell change)
  }
}

async function proposeTyped() {
  clearMessage();
  showProposal(await api("POST", "/guide-points/propose", { point_mm: pointMm() }));
}

async function teachTyped() {
  clearMessage();
  const taught = await api("POST", "/guide-points/from-surface", { point_mm: pointMm() });
  await refreshGuides();
  pollState();
  if (taught.notice) showMessage(`G${taught.guide_point.index + 1}: ${taught.notice}`, "info");
}

async function acceptProposal() {
  const start = await api("POST", "/guide-points/proposal/accept", {});
  const bar = $("proposal-progress");
  bar.classList.remove("hidden");
  $("proposal-accept").disabled = true;
  try {
    const job = await followJob(start.job_id, (j) => { bar.value = fraction(j.progress); });
    if (jobFailed(job)) showMessage(`accept the proposal: ${job.error || job.status}`);
    else {
      const guides = await api("GET", "/guide-points");
      showGuides(guides);
    }
  } finally {
    bar.classList.add("hidden");
    await refreshProposal();
  }
}

async function deleteProposed() {
  if (selectedProposed === null) {
    showMessage("select a proposed point in the list first");
    return;
  }
  showProposal(await api("DELETE", `/guide-points/proposal/points/${selectedProposed}`));
}

async function discardProposal() {
  await api("DELETE", "/guide-points/proposal");
  showProposal(null);
}

// The CAD-only program beside the learned one (post-processing's answer).
// The two programs' colours in the 3D scene (app/gui/colors.py COMPARISON_COLORS): the rows'
// swatches are the scene's legend.
const COMPARISON_COLORS = { learned: "rgb(0, 160, 110)", cad_only: "rgb(170, 60, 220)" };

function showCadComparison(r) {
  const c = r && r.cad_comparison;
  for (const id of ["compare-table", "compare-note", "compare-actions"]) {
    $(id).classList.toggle("hidden", !c);
  }
  if (!c) return;
  const rows = [["learned", "learned", c.learned], ["cad_only", "CAD-only", c.cad_only]];
  if (c.cad_only_uncalibrated) {  // what the work object's calibration bought (not drawn)
    rows.push([null, "CAD-only, as placed (not calibrated)", c.cad_only_uncalibrated]);
  }
  const trs = rows.map(([key, name, s]) => {
    const tr = document.createElement("tr");
    const [x, y] = s.worst_at_wobj_mm;
    const first = document.createElement("td");
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    if (key) {
      swatch.style.background = COMPARISON_COLORS[key];
      first.append(swatch);
    }
    first.append(document.createTextNode(name));
    tr.appendChild(first);
    for (const v of [fmt(s.max_deviation_mm, 3), fmt(s.rms_deviation_mm, 3),
      fmt(s.overcut_mm, 3), fmt(s.air_mm, 3), `(${fmt(x, 0)}, ${fmt(y, 0)})`]) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
    return tr;
  });
  $("compare-list").replaceChildren(...trs);
  $("compare-note").textContent = c.part_deviates_from_cad
    ? `Against the real wall. Real part: ${c.deviation}.`
    : "Against the wall (the part is its mesh: the CAD-only program is as good).";
}

const showPostprocessNow = showPostprocess;
// eslint-disable-next-line no-global-assign
showPostprocess = (r) => {
  showPostprocessNow(r);
  showCadComparison(r);
};

// The CAD-only program in the Export card's language (GET /api/export/cad-only/{language}).
async function downloadCadOnly() {
  await loadLanguages();
  const lang = exportLanguages.find((l) => l.name === $("export-language").value);
  if (!lang) throw new Error("this arm's controller runs none of the program languages");
  const file = lang.files[0];
  const q = new URLSearchParams({ file });
  const text = await api("GET", `/export/cad-only/${encodeURIComponent(lang.name)}?${q}`,
    undefined, { text: true });
  const url = URL.createObjectURL(new Blob([text], { type: "text/plain" }));
  const a = document.createElement("a");
  a.href = url;
  a.download = `cad_only_${file}`;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

async function goHome() {
  showMove(await api("POST", "/leadthrough/home", {}));
}

async function clearGuides() {
  await api("DELETE", "/guide-points");
  await refreshGuides();
}

// ---------------------------------------------------------------- the tool's view

async function refreshTool() {
  const v = await api("GET", "/leadthrough/tool", undefined, { quiet: true });
  // The gap to the wall at the tool's height; the nearest face when that is a floor.
  const wall = v.wall_gap_mm === null || v.wall_gap_mm === undefined ? "-" : fmt(v.wall_gap_mm, 2);
  $("tool-gap").textContent = v.nearest_face && v.nearest_face !== "wall"
    ? `${wall} (${v.nearest_face} ${fmt(v.gap_mm, 2)})` : wall;
  $("tool-force").textContent = fmt(v.force_magnitude_N, 1);
  $("tool-table").textContent = fmt(v.table_gap_mm, 1);
}

function scheduleTool() {
  if (toolTimer !== null) return;
  toolTimer = setTimeout(() => {
    toolTimer = null;
    refreshTool().catch(() => {});
  }, TOOL_PERIOD_MS);
}

// ---------------------------------------------------------------- keyboard

// Keys jog everywhere but in text fields; in a jog step field too (type the step, then
// press the arrow: the arrows would only nudge the number there).
function typing(target) {
  if (target && target.classList && target.classList.contains("jog-step")) return false;
  return target && ["INPUT", "SELECT", "TEXTAREA"].includes(target.tagName);
}

function onKey(ev) {
  if (typing(ev.target) || ev.ctrlKey || ev.altKey || ev.metaKey) return;
  const jogKey = KEY_JOGS[ev.key];
  if (jogKey) {
    ev.preventDefault();
    if (ev.repeat && moving) return;
    const factor = ev.shiftKey ? 10 : 1;
    exclusive(() => jogBy(jogKey[0], jogKey[1], factor)).catch(() => {});
    return;
  }
  if (ev.key === "g" || ev.key === "G" || (ev.key === "Enter" && ev.target === document.body)) {
    ev.preventDefault();
    if (!ev.repeat) recordGuide().catch(() => {});
  }
}

// ---------------------------------------------------------------- gamepad

let padRecordWasDown = false;

function pollGamepad() {
  const pads = navigator.getGamepads ? [...navigator.getGamepads()].filter(Boolean) : [];
  const pill = $("gamepad-status");
  pill.textContent = pads.length ? pads[0].id.slice(0, 24) : "no gamepad";
  pill.className = `pill ${pads.length ? "pill-on" : "pill-off"}`;
  if (!pads.length) return;
  const pad = pads[0];
  const a = (i) => (Math.abs(pad.axes[i] || 0) > GAMEPAD_DEADZONE ? pad.axes[i] : 0);
  // Left stick: X (right +) and Y (up +); right stick vertical: Z (up +).
  const v = { x: a(0), y: -a(1), z: -a(3) };
  const recordDown = Boolean(pad.buttons[0] && pad.buttons[0].pressed);
  if (recordDown && !padRecordWasDown) recordGuide().catch(() => {});
  padRecordWasDown = recordDown;
  const axis = ["x", "y", "z"].reduce((best, k) => (Math.abs(v[k]) > Math.abs(v[best]) ? k : best));
  if (!v[axis] || moving) return;
  // Velocity jog: the step one period covers at the stick's share of the jog speed.
  const speed = Math.max(0.5, Number($("jog-speed").value) * Math.abs(v[axis]));
  const step = Math.sign(v[axis]) * speed * (GAMEPAD_PERIOD_MS / 1000);
  exclusive(async () => {
    showMove(await api("POST", "/leadthrough/jog",
      { axis, step, frame: jogFrame(), speed }, { quiet: true }));
  }).catch(() => {});
}

// ---------------------------------------------------------------- server push

// An event sent while a motion ran may arrive after the motion's own answer: never show a pose
// older than the one shown (simulated time; a reset to Home goes back further than this).
const STALE_WINDOW_S = 2.0;
let shownTime = -Infinity;
const showStateNow = showState;
// eslint-disable-next-line no-global-assign
showState = (state) => {
  if (state && Number.isFinite(state.time_s)) shownTime = state.time_s;
  showStateNow(state);
};

function olderThanShown(state) {
  const t = state.time_s;
  return Number.isFinite(t) && t < shownTime && shownTime - t < STALE_WINDOW_S;
}

async function resync() {
  await Promise.allSettled([pollState(), refreshGuides(), loadSettings(), refreshTool()]);
}

function reloadScene() {
  const frame = $("viser-frame");
  if (frame.src && !frame.src.startsWith("about:")) {
    frame.src = frame.src;
    window.sceneReloads = (window.sceneReloads || 0) + 1;
  }
}

// A stream the browser gave up on (an answer other than an event stream, such as the 503 of a
// server shutting down, closes an EventSource for good) is opened again after this long.
const EVENTS_REOPEN_MS = 1000;

function connectEvents(lostBefore = false) {
  if (!window.EventSource) return;
  const source = new EventSource(`${API}/events`);
  let lost = lostBefore;
  source.onopen = () => {
    eventsLive = true;
    setConnected(true);
    if (lost) {
      // The server came back (a restart): its viser scene is a new one, reload it.
      reloadScene();
      resync();
    }
    lost = false;
  };
  source.onerror = () => {
    eventsLive = false;
    lost = true;
    setConnected(false);
    if (source.readyState === EventSource.CLOSED) {
      setTimeout(() => connectEvents(true), EVENTS_REOPEN_MS);
    }
  };
  source.addEventListener("robot", (e) => {
    const data = JSON.parse(e.data);
    if (data.state && !moving && !olderThanShown(data.state)) showState(data.state);
    scheduleTool();
  });
  for (const topic of ["guide_points", "cell", "project"]) {
    source.addEventListener(topic, () => {
      refreshGuides().catch(() => {});
      refreshProposal().catch(() => {});
      checkGuides({ quiet: true }).catch(() => {});
      pollState();
      scheduleTool();
    });
  }
  // What a cell change cleared (a machining choice the new controller cannot run), said once.
  source.addEventListener("cell", () => {
    api("GET", "/cell", undefined, { quiet: true }).then((cell) => {
      if (cell.note) showMessage(cell.note, "info");
    }).catch(() => {});
  });
  source.addEventListener("compliance", () => {
    api("GET", "/leadthrough/compliance", undefined, { quiet: true })
      .then(showCompliance).catch(() => {});
  });
  for (const topic of ["recording", "postprocess"]) {
    source.addEventListener(topic, () => {
      loadSettings().catch(() => {});
      pollState();
    });
  }
  window.robomachEvents = source;
  // Other cards listen on every stream opened (a reconnect makes a new one).
  for (const hook of window.robomachEventHooks || []) hook(source);
}

// ---------------------------------------------------------------- wiring

function initTeach() {
  $("jog-frame").addEventListener("change", showFrame);
  $("jog-frame").addEventListener(CHOICES_LOADED, showFrame);
  showFrame();
  for (const b of document.querySelectorAll("button.touch")) {
    b.addEventListener("click", () => exclusive(
      () => touchOff(b.dataset.axis, Number(b.dataset.sign))).catch(() => {}));
  }
  document.addEventListener("keydown", onKey);
  const guard = (fn) => () => fn().catch(() => {});
  for (const id of ["point-mode", "point-gap", "point-height"]) {
    $(id).addEventListener("change", guard(putPointing));
  }
  $("point-propose").addEventListener("click", guard(proposeTyped));
  $("point-teach").addEventListener("click", () => exclusive(teachTyped).catch(() => {}));
  $("proposal-accept").addEventListener("click", guard(acceptProposal));
  $("proposal-delete").addEventListener("click", guard(deleteProposed));
  $("proposal-discard").addEventListener("click", guard(discardProposal));
  $("jog-home").addEventListener("click", () => exclusive(goHome).catch(() => {}));
  $("cad-download").addEventListener("click", guard(downloadCadOnly));
  $("guide-clear").addEventListener("click", guard(clearGuides));
  refreshProposal().catch(() => {});
  // The click-mode menu is filled later (GET /api/choices): then show the session's mode.
  $("point-mode").addEventListener(CHOICES_LOADED, guard(refreshProposal));
  window.addEventListener("gamepadconnected", pollGamepad);
  setInterval(pollGamepad, GAMEPAD_PERIOD_MS);
  setInterval(() => {
    if (!eventsLive) refreshGuides().catch(() => {});
  }, GUIDE_FALLBACK_MS);
  connectEvents();
  refreshTool().catch(() => {});
  checkGuides({ quiet: true }).catch(() => {});
}

document.addEventListener("DOMContentLoaded", initTeach);
