// robomach teach pendant: the Work object card (issue 31). Uses pendant.js's api(), $(),
// fmt(), safe(), followJob(), fraction(), showMessage(), loadChoices() and applyChoices().
//  - Place: x, y, z [mm] and rx, ry, rz [deg] (robomach demo --wobj's numbers); while they are
//    typed the 3D scene draws the part there (PUT /api/cell/placement-preview: nothing applied),
//    "Place the part here" applies them (PUT /api/cell {"wobj_mm_deg"}: a cell change).
//  - Calibrate by touch: "Touch faces" makes a click on the part in the 3D scene touch the face
//    clicked (4, 3 and 2 touches on the top and two sides), or the example operator touches the
//    planned features; the touches with their residuals, the fit, Accept, Undo, Clear, Back.
"use strict";

const WOBJ_FIELDS = ["x", "y", "z", "rx", "ry", "rz"];
const PREVIEW_DELAY_MS = 150;  // typing a number: the scene follows once the keys pause
let previewTimer = null;
let calibrationJob = null;

function workObjectCard() {
  const card = document.createElement("fieldset");
  card.className = "card";
  card.id = "wobj-card";
  const position = (f) => `<label>${f} <input id="wobj-${f}" class="wobj" type="number" step="1" data-range="WOBJ_POSITION_MM"> mm</label>`;
  const turn = (f) => `<label>${f} <input id="wobj-${f}" class="wobj" type="number" step="0.5" data-range="WOBJ_ROTATION_DEG"> deg</label>`;
  const inputs = [...["x", "y", "z"].map(position), ...["rx", "ry", "rz"].map(turn)];
  card.innerHTML = `
    <legend>Work object <span id="wobj-calibrated" class="pill pill-on hidden">calibrated</span></legend>
    <div class="caption">Place the part (base frame; turns about the fixed x, then y, then z)</div>
    <div class="row">${inputs.slice(0, 3).join("")}</div>
    <div class="row">${inputs.slice(3).join("")}</div>
    <p id="wobj-note" class="small"></p>
    <div class="row">
      <button id="wobj-place" class="primary" disabled title="a cell change: the robot goes home, the guide points are cleared">Place the part here</button>
      <button id="wobj-back" disabled>Put it back</button>
    </div>
    <div class="caption">Calibrate by touch</div>
    <p class="small">The part may stand a few mm and a degree or two off its CAD. <b>Touch
      faces</b>, then click three faces of the part in the 3D scene: the top, a side and a side
      across it. The robot touches each where the frame needs it (4, 3 and 2 touches).</p>
    <div class="row">
      <label>Force <input id="calib-force" type="number" data-range="TOUCH_OFF_FORCE_N" step="0.5"> N</label>
      <button id="calib-mode">Touch faces</button>
      <button id="calib-auto" title="the example operator touches 3 points of the top face and 3 and 2 of two sides">Touch the planned features</button>
      <progress id="calib-progress" max="1" value="0" class="hidden"></progress>
    </div>
    <div class="scroll">
      <table class="list" id="calib-table">
        <thead><tr><th>#</th><th>face</th><th>F N</th><th>residual mm</th></tr></thead>
        <tbody id="calib-list"></tbody>
      </table>
    </div>
    <p id="calib-fit" class="small"></p>
    <div class="row">
      <button id="calib-accept" class="primary" disabled>Accept</button>
      <button id="calib-undo">Undo last touch</button>
      <button id="calib-clear">Clear</button>
      <button id="calib-remove" disabled title="the CAD back where it is placed">Back to the placement</button>
    </div>`;
  return card;
}

function wobjTyped() {
  return WOBJ_FIELDS.map((f) => Number($(`wobj-${f}`).value));
}

function showPlacement(p) {
  const tried = p.wobj_mm_deg;
  const shown = tried || p.placed_wobj_mm_deg;
  WOBJ_FIELDS.forEach((f, i) => {
    const el = $(`wobj-${f}`);
    if (document.activeElement !== el) el.value = Number(shown[i].toFixed(3));
  });
  const [x, y, z, rx, ry, rz] = p.placed_wobj_mm_deg;
  const placed = `Placed at (${fmt(x, 1)}, ${fmt(y, 1)}, ${fmt(z, 1)}) mm, turned ` +
    `(${fmt(rx, 1)}, ${fmt(ry, 1)}, ${fmt(rz, 1)}) deg.`;
  $("wobj-note").textContent = tried
    ? `${placed} Trying the numbers above: the 3D scene draws the part there.` : placed;
  $("wobj-place").disabled = $("wobj-back").disabled = !tried;
}

async function refreshPlacement() {
  showPlacement(await api("GET", "/cell/placement-preview", undefined, { quiet: true }));
}

// The scene follows the numbers as they are typed (nothing applied).
function tryPlacement() {
  clearTimeout(previewTimer);
  previewTimer = setTimeout(() => {
    api("PUT", "/cell/placement-preview", { wobj_mm_deg: wobjTyped() }).then(showPlacement)
      .catch(() => {});
  }, PREVIEW_DELAY_MS);
}

async function placePart() {
  await api("PUT", "/cell", { wobj_mm_deg: wobjTyped() });
  await refreshPlacement();
}

async function putBack() {
  showPlacement(await api("DELETE", "/cell/placement-preview"));
}

function showCalibration(c) {
  const tbody = $("calib-list");
  tbody.replaceChildren(...c.touches.map((t) => {
    const tr = document.createElement("tr");
    const res = t.residual_mm === null || t.residual_mm === undefined ? "-" : fmt(t.residual_mm, 3);
    for (const v of [`T${t.index + 1}`, t.face || t.feature || "-", fmt(t.force_N, 1), res]) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
    return tr;
  }));
  const fit = c.fit;
  $("calib-fit").textContent = fit
    ? `Fit: ${fit.message}.`
    : (c.touches.length ? `No fit yet: ${c.fit_error}` : `No touch yet: ${c.min_touches} at least fix the frame.`);
  $("calib-accept").disabled = !fit;
  $("calib-remove").disabled = !c.accepted;
  $("wobj-calibrated").classList.toggle("hidden", !c.accepted);
  if (document.activeElement !== $("calib-force")) $("calib-force").value = c.force_N;
}

async function refreshCalibration() {
  showCalibration(await api("GET", "/cell/calibration", undefined, { quiet: true }));
}

async function touchMode() {
  await api("PUT", "/guide-points/pointing", { click_mode: "touch" });
  showMessage("a click on the part in the 3D scene now touches the face clicked", "info");
}

async function autoCalibration() {
  const start = await api("POST", "/cell/calibration/auto", { force_N: Number($("calib-force").value) });
  calibrationJob = start.job_id;
  const bar = $("calib-progress");
  bar.classList.remove("hidden");
  $("calib-auto").disabled = true;
  try {
    const job = await followJob(calibrationJob, (j) => { bar.value = fraction(j.progress); });
    if (jobFailed(job)) showMessage(`touch the planned features: ${job.error || job.status}`);
  } finally {
    calibrationJob = null;
    bar.classList.add("hidden");
    $("calib-auto").disabled = false;
    await refreshCalibration();
  }
}

async function calibrationCall(method, path) {
  await api(method, path);
  await refreshCalibration();
}

async function initWorkObject() {
  const pendant = document.querySelector("section.pendant");
  const card = workObjectCard();
  pendant.insertBefore(card, $("jog-card"));
  await applyChoices(card).catch(() => {});
  for (const f of WOBJ_FIELDS) $(`wobj-${f}`).addEventListener("input", tryPlacement);
  $("wobj-place").addEventListener("click", safe(placePart));
  $("wobj-back").addEventListener("click", safe(putBack));
  $("calib-mode").addEventListener("click", safe(touchMode));
  $("calib-auto").addEventListener("click", safe(autoCalibration));
  $("calib-accept").addEventListener("click", safe(async () => {
    await calibrationCall("POST", "/cell/calibration/accept");
    // The touching is done: a click on the part proposes the wall again.
    const pointing = await api("GET", "/guide-points/pointing", undefined, { quiet: true });
    if (pointing.click_mode === "touch") {
      await api("PUT", "/guide-points/pointing", { click_mode: "propose" });
    }
  }));
  $("calib-undo").addEventListener("click", safe(() => calibrationCall("DELETE", "/cell/calibration/touches/last")));
  $("calib-clear").addEventListener("click", safe(() => calibrationCall("DELETE", "/cell/calibration/touches")));
  $("calib-remove").addEventListener("click", safe(() => calibrationCall("DELETE", "/cell/calibration")));
  const follow = () => {
    refreshPlacement().catch(() => {});
    refreshCalibration().catch(() => {});
  };
  follow();
  // The server's events (teach.js opens the streams): the placement tried or applied, a touch.
  const attach = (source) => {
    for (const topic of ["placement", "calibration", "cell", "project"]) {
      source.addEventListener(topic, follow);
    }
  };
  (window.robomachEventHooks = window.robomachEventHooks || []).push(attach);
  if (window.robomachEvents) attach(window.robomachEvents);
}

document.addEventListener("DOMContentLoaded", () => { initWorkObject().catch(() => {}); });
