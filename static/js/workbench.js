// Workbench page: measurements, model vs measurement, residuals, error by regime, diagnosis
// cards with "add effect", and the fit by model version.
import { $, api, esc, fmt, get, post, put, toast } from "./api.js";
import { C, bars, line, makeChart, setData, watchSize } from "./charts.js";

let session;
let selected = null;      // measurement id
let versions = [];
let kinds = new Map();    // measurement id -> "dc" | "camera" (a PTZ camera log: t,speed_cmd,theta)
const isCamera = () => kinds.get(selected) === "camera";
let busy = false;

export function init(s) {
  session = s;
  makeChart($("plot-overlay"), { height: 230, xLabel: "time (s)", yLabel: "θ °", series: [line("measured", C.actual, { width: 2.4 }), line("model", C.target, { dash: [5, 3], width: 1.4 })] });
  makeChart($("plot-residual"), { height: 140, xLabel: "time (s)", yLabel: "residual °", series: [line("residual", "#6f42c1")] });
  makeChart($("plot-acf"), { height: 150, yLabel: "autocorr.", xLabel: "lag (s)",
    series: [line("residual autocorrelation", C.actual), line("right model: highest", C.bound, { dash: [4, 4], width: 1 }), line("right model: lowest", C.bound, { dash: [4, 4], width: 1 })] });
  makeChart($("plot-ccf"), { height: 150, yLabel: "cross-corr.", xLabel: "lag (s)",
    series: [line("input–residual", C.target), line("+bound", C.bound, { dash: [4, 4], width: 1 }), line("−bound", C.bound, { dash: [4, 4], width: 1 })] });
  makeChart($("plot-versions"), {
    height: 180, xLabel: "version", yLabel: "RMS error °",
    series: [bars("RMS error °", "#e8590c"), { label: "fit of increments %", stroke: C.actual, width: 2, scale: "fit", points: { show: true, size: 7 } }],
    opts: {
      axes: [
        { label: "version", stroke: "#5f6b7a", grid: { show: false }, incrs: [1], values: (u, vals) => vals.map((v) => `v${v}`) },
        { label: "RMS error °", stroke: "#e8590c", grid: { stroke: "#eef1f5" }, size: 56 },
        { scale: "fit", side: 1, label: "fit of increments %", stroke: C.actual, grid: { show: false }, size: 50 },
      ],
      scales: { x: { time: false, range: (u, mn, mx) => [mn - 0.6, mx + 0.6] }, y: { range: (u, mn, mx) => [0, mx * 1.1] } },
      cursor: { drag: { x: false, y: false } },
    },
  });
  for (const id of ["plot-overlay", "plot-residual", "plot-acf", "plot-ccf", "plot-versions"]) watchSize($(id));
  $("upload-form").addEventListener("submit", upload);
  $("wb-diagnose").addEventListener("click", () => diagnose());
  $("wb-fit").addEventListener("click", refit);
  $("wb-design").addEventListener("click", designOnModel);
  $("wb-mode").addEventListener("change", () => { if (selected) compare(shownVersion).catch((e) => { $("wb-error").textContent = e.message; }); });
}

export function show() { loadList(); }

export async function selectMeasurement(id) {
  selected = id;
  for (const li of document.querySelectorAll("#meas-list li")) li.classList.toggle("selected", +li.dataset.id === id);
  $("diag-cards").innerHTML = ""; $("diag-notes").innerHTML = ""; $("wb-verdict").textContent = ""; $("wb-error").textContent = "";
  const canEdit = session.can("engineer");
  // a camera log has versions of the camera model (compare, diagnose, fit, add effect); a
  // controller design is for a voltage-driven axis only
  $("wb-diagnose").disabled = !canEdit; $("wb-fit").disabled = !canEdit; $("wb-design").disabled = !canEdit || isCamera();
  await loadVersions();
  await compare();
}
window.console3dat_workbench = { selectMeasurement, get selected() { return selected; }, get versions() { return versions; } };

async function loadList() {
  try {
    const list = await get("/workbench/measurements");
    kinds = new Map(list.map((m) => [m.id, m.kind]));
    $("meas-list").innerHTML = list.length ? list.slice().reverse().map((m) => `<li data-id="${m.id}" class="${m.id === selected ? "selected" : ""}">
      <span><b>${esc(m.name)}</b><br><span class="meta">#${m.id} · ${m.kind === "camera" ? "camera log" : m.axis} · ${(m.n * m.dt_s).toFixed(1)} s at ${(1 / m.dt_s).toFixed(0)} Hz</span></span></li>`).join("")
      : `<li class="muted">No measurements yet: upload a CSV or record one on the practice rig.</li>`;
    for (const li of document.querySelectorAll("#meas-list li[data-id]")) li.onclick = () => selectMeasurement(+li.dataset.id);
  } catch (e) { toast(e.message, true); }
}

async function upload(ev) {
  ev.preventDefault();
  $("upload-error").textContent = "";
  const file = $("upload-file").files[0];
  if (!file) return;
  const form = new FormData();
  form.append("file", file);
  form.append("axis", $("upload-axis").value);
  if ($("upload-gain").value) form.append("gain", $("upload-gain").value);
  if ($("upload-effects").value.trim()) form.append("effects", $("upload-effects").value.trim());
  setBusy(true);
  try {
    const rec = await api("POST", "/workbench/measurements", undefined, { form });
    toast(`Uploaded ${rec.name}`);
    $("upload-file").value = "";
    await loadList();
    await selectMeasurement(rec.id);
    await diagnose();
  } catch (e) { $("upload-error").textContent = e.message; }
  finally { setBusy(false); }
}

function setBusy(on) { busy = on; $("wb-busy").hidden = !on; }

async function loadVersions() {
  versions = await get(`/workbench/measurements/${selected}/versions`);
  const x = versions.map((_, i) => i + 1);
  setData($("plot-versions"), [x, versions.map((v) => v.fit.rms_deg), versions.map((v) => v.fit.fit_percent_increment)]);
  $("version-list").innerHTML = versions.map((v, i) => `<li data-vid="${v.id}" title="show this version against the measurement"><span><b>v${i + 1}</b> ${esc(v.label)}<br>
    <span class="meta">${v.model.effects.length ? esc(v.model.effects.join(", ")) : "base model"}</span></span>
    <span class="meta">${fmt(v.fit.rms_deg, 4)}° · ${fmt(v.fit.fit_percent, 2)} %</span></li>`).join("");
  for (const li of document.querySelectorAll("#version-list li")) li.onclick = () => compare(+li.dataset.vid);
  showBudget(versions);
}

// The error budget of each version as a stacked bar (mean squares, % of v1's): the sensor's
// floor (quantization, noise), the rest of what a right model leaves (load disturbance, refit),
// what each added effect explained, and what is left for the model (tracker/workbench/budget.py).
const BUDGET_FIXED = [["quantization", "#adb5bd"], ["noise", "#ced4da"], ["load disturbance", "#dee2e6"]];
const EFFECT_COLOURS = ["#1c7ed6", "#37b24d", "#7048e8", "#f59f00", "#0ca678", "#d6336c", "#1098ad"];
function budgetSegments(b) {
  const sq = (d) => Math.sign(d) * d * d;
  return [["quantization", sq(b.quantization_deg)], ["noise", sq(b.noise_deg)], ["load disturbance", sq(b.disturbance_deg)],
    ...b.explained.map((e) => [`explained by ${e.change}`, sq(e.deg)]), ["left", sq(b.left_deg)]];
}
function showBudget(list) {
  const withB = list.map((v, i) => [i + 1, v.fit.budget]).filter(([, b]) => b);
  const box = $("wb-budget");
  if (!withB.length) { box.innerHTML = `<div class="muted">No error budget stored for these versions.</div>`; return; }
  const colours = new Map([...BUDGET_FIXED, ["left", "#e8590c"]]);
  const total = withB[0][1].rms_deg ** 2 || 1;
  // every bar against the newest version's floor: the floor belongs to the run (a wrong model's
  // residual test reads part of its own error as disturbance, so an early floor runs high)
  const fl = withB[withB.length - 1][1];
  const rebased = (b) => ({ ...b, quantization_deg: fl.quantization_deg, noise_deg: fl.noise_deg, disturbance_deg: fl.disturbance_deg,
    left_deg: Math.sqrt(Math.max(b.rms_deg ** 2 - fl.floor_deg ** 2, 0)) });
  const W = 360, H = 150, pad = 30, bw = Math.min(48, (W - pad) / withB.length * 0.6);
  let rects = "";
  withB.forEach(([n, b], i) => {
    const x = pad + (i + 0.5) * (W - pad) / withB.length - bw / 2;
    let y = H - 18;
    for (const [label, ms] of budgetSegments(rebased(b))) {
      if (!colours.has(label)) colours.set(label, EFFECT_COLOURS[(colours.size - 4) % EFFECT_COLOURS.length]);
      const h = Math.max(0, ms) / total * (H - 28);
      y -= h;
      rects += `<rect x="${x.toFixed(1)}" y="${y.toFixed(1)}" width="${bw.toFixed(1)}" height="${h.toFixed(1)}" fill="${colours.get(label)}" data-part="${esc(label)}"><title>v${n} ${esc(label)}: ${fmt(100 * ms / total, 1)} % of v1's squared error</title></rect>`;
    }
    rects += `<text x="${(x + bw / 2).toFixed(1)}" y="${H - 4}" text-anchor="middle" font-size="11" fill="#5f6b7a">v${n}</text>`;
  });
  const axis = [0, 50, 100].map((p) => `<text x="${pad - 4}" y="${(H - 18 - p / 100 * (H - 28) + 4).toFixed(1)}" text-anchor="end" font-size="10" fill="#5f6b7a">${p}%</text>`).join("");
  const last = withB[withB.length - 1][1];
  const done = last.at_floor
    ? `<b id="budget-verdict" data-at-floor="yes">At the floor: the error left (${fmt(last.rms_deg, 4)}°) is what a right model leaves on this run (floor ${fmt(last.floor_deg, 4)}°: sensor ${fmt(last.sensor_deg, 3)}°, load disturbance ${fmt(last.disturbance_deg, 3)}°). Done for this run.</b>`
    : `<b id="budget-verdict" data-at-floor="no">${fmt(last.left_deg, 3)}° RMS left above the floor of ${fmt(last.floor_deg, 4)}°: the model still misses something.</b>`;
  box.innerHTML = `<svg viewBox="0 0 ${W} ${H}" role="img" aria-label="error budget by version">${axis}${rects}</svg>
    <div class="legend">${[...colours].map(([k, c]) => `<span><i style="background:${c}"></i>${esc(k)}</span>`).join("")}</div>
    <div class="done">${done}</div>`;
}

let shownVersion = null;
async function compare(versionId) {
  shownVersion = versionId || null;
  const body = { mode: $("wb-mode").value };
  if (versionId) body.version_id = versionId;
  const m = await post(`/workbench/measurements/${selected}/compare`, body);
  const n = versions.findIndex((v) => v.id === m.version_id) + 1;
  const camModel = m.kind === "camera" ? ` — camera model: ${(m.model.effects || []).join(", ") || "linear speed table, no latency"}` : "";
  $("wb-title").textContent = m.version_id
    ? `Measurement #${selected}${m.kind === "camera" ? " (camera log)" : ""} vs ${m.version_label} (v${n})${camModel}`
    : `Measurement #${selected} (camera log) vs the base camera model${camModel}`;
  for (const li of document.querySelectorAll("#version-list li")) li.classList.toggle("selected", +li.dataset.vid === m.version_id);
  const s = m.series;
  setData($("plot-overlay"), [s.t_s, s.measured_deg, s.model_deg]);
  setData($("plot-residual"), [s.t_s, s.residual_deg]);
  $("wb-summary").innerHTML = [
    ["Fit", `${fmt(m.fit_percent, 2)} %`], ["Fit of increments", `${fmt(m.fit_percent_increment, 1)} %`],
    ["RMS error", `${fmt(m.rms_deg, 4)}°`], ["Horizon", m.horizon_s ? `${fmt(m.horizon_s * 1000, 0)} ms ahead` : "free run"],
    ...(m.kind === "camera" ? [["Quantization floor", `${fmt(m.quantization_floor_deg, 4)}°`]] : []),
  ].map(([k, v]) => `<div class="metric"><div class="k">${k}</div><div class="v">${v}</div></div>`).join("");
  showRegimes(m);
  if (m.kind === "camera") $("resid-note").textContent = "Camera log: the residual test is not run (error by regime above).";
  showResiduals(m.residual_analysis, m.residual_verdict);
  showParams(versions.find((v) => v.id === m.version_id));
}

// Every fitted parameter with its standard error; a flag and the experiment that pins it when
// this run does not (relative error above 10 % or a strong correlation: fit/uncertainty.py).
function showParams(v) {
  const rows = (v && v.fit && v.fit.certainty) || [];
  $("wb-params").innerHTML = rows.length ? `<table><tr><th>parameter</th><th>value</th><th>± stderr</th><th></th></tr>${rows.map((c) => `
    <tr class="${c.poorly_determined ? "poor" : ""}" title="${esc(c.poorly_determined ? `${c.reason}. To pin it: ${c.experiment || "a run that excites it more"}` : "well determined by this run")}">
    <td>${esc(c.name)}</td><td class="num">${Number(c.value).toPrecision(4)}</td>
    <td class="num">${Number(c.stderr).toPrecision(2)} (${c.relative_stderr === null ? "∞" : fmt(100 * c.relative_stderr, 1)} %)</td>
    <td>${c.poorly_determined ? `<span class="badge warn">poorly determined</span>` : ""}</td></tr>`).join("")}</table>
    ${rows.filter((c) => c.poorly_determined).map((c) => `<div class="muted">${esc(c.name)}: ${esc(c.reason)}. To pin it: ${esc(c.experiment || "a run that excites it more")}</div>`).join("")}` : "";
}

function showRegimes(m) {
  const rows = Object.entries(m.regimes || {}).map(([k, r]) => [k.replaceAll("_", " "), r.rms_deg, r.share_of_error_percent]);
  const bins = Object.entries(m.position_bins || {}).map(([k, r]) => [`θ ${k}`, r.rms_deg, r.share_of_error_percent]);
  const all = [...rows, ...bins].filter((r) => r[1] !== null && r[1] !== undefined);
  const max = Math.max(1e-12, ...all.map((r) => r[1]));
  const html = (list) => list.map(([k, v, share]) => `<div class="barrow" title="${fmt(share, 0)} % of the squared error">
    <span>${esc(k)}</span><span class="track"><span class="fill" style="display:block;width:${(100 * v / max).toFixed(1)}%"></span></span>
    <span class="num">${fmt(v, 4)}</span></div>`).join("");
  $("regime-bars").innerHTML = html(rows) + (bins.length ? `<h3>By position</h3>` + html(bins) : "");
}

// The residual test: the measured residual against what a right model leaves on this run
// (simulated replicas), overall and per regime. The autocorrelation is drawn inside the
// replicas' envelope; the ±2.58/√N white-noise bound is not drawn (k-step residuals are
// correlated by construction, so it would condemn a right model too).
function showResiduals(r, v) {
  if (!r || !r.autocorr_lags_s) return;
  const a = r.autocorr_lags_s;
  const hi = v && v.autocorr_band_high ? v.autocorr_band_high : a.map(() => r.autocorr_bound);
  const lo = v && v.autocorr_band_low ? v.autocorr_band_low : a.map(() => -r.autocorr_bound);
  setData($("plot-acf"), [a, r.autocorr, hi, lo]);
  const x = r.xcorr_lags_s, xb = r.xcorr_bound;
  setData($("plot-ccf"), [x, r.xcorr, x.map(() => xb), x.map(() => -xb)]);
  const note = $("resid-note");
  if (!v) {
    note.textContent = "Free simulation: no residual test (it judges the k-step prediction).";
    note.dataset.consistent = "";
    return;
  }
  note.dataset.consistent = v.consistent ? "yes" : "no";
  const rows = Object.entries(v.regimes || {}).map(([k, c]) => `<tr class="${c.ok ? "" : "above"}"><td>${esc(k.replaceAll("_", " "))}</td>
    <td class="num">${fmt(c.ratio, 2)}×</td><td>${c.ok ? "within band" : "ABOVE band"}</td></tr>`).join("");
  note.innerHTML = `<b id="resid-verdict">${v.consistent ? "Residual consistent with a right model" : "Model error left in the residual"}</b><br>${esc(v.explanation)}
    <table class="resid-regimes"><tr><th>regime</th><th>RMS ÷ right model</th><th></th></tr>${rows}</table>`;
}

export async function diagnose() {
  if (!selected) return;
  $("wb-error").textContent = "";
  setBusy(true);
  try {
    const d = await post(`/workbench/measurements/${selected}/diagnose`, {});
    $("wb-verdict").textContent = (d.kind === "camera" ? `Camera log: fit ${fmt(d.fit_percent, 2)} %, RMS ${fmt(d.rms_deg, 4)}°. ` : "")
      + (d.verdict ? `Most likely missing: ${d.verdict}` : "Nothing significant is missing: the model explains the data.")
      + (d.agreement ? ` ${d.agreement}` : "");
    const cands = d.candidates || [];
    $("diag-cards").innerHTML = cands.map((c, i) => `<div class="dcard ${c.effect === d.verdict ? "top" : ""} ${c.significant ? "" : "insignificant"}">
      <h3><span>${i + 1}. ${esc(c.effect)}</span><span class="badge ${c.significant ? "sig" : ""}">${c.significant ? "significant" : "not significant"}</span></h3>
      <div>fit would reach <span class="fit">${fmt(c.fit_percent, 2)} %</span></div>
      <div class="evidence">${esc(c.evidence || "")}</div>
      ${c.confused_with && c.confused_with.length ? `<div class="params">looks like ${esc(c.confused_with.join(", "))}${c.experiment ? ` — to tell apart: ${esc(c.experiment)}` : ""}</div>` : ""}
      <div class="params">${Object.entries(c.params || {}).map(([k, v]) => {
        const se = c.stderr && c.stderr[k];
        const poor = se && Math.abs(se) > 0.1 * Math.abs(v);
        return `${esc(k)} = ${Number(v).toPrecision(4)}${se ? ` ± ${Number(se).toPrecision(2)}` : ""}${poor ? ` <span class="badge warn" title="standard error above 10 % of the value${c.experiment ? `; to pin it: ${esc(c.experiment)}` : ""}">poorly determined</span>` : ""}`;
      }).join("<br>")}</div>
      <button class="small ${c.effect === d.verdict ? "primary" : ""}" data-add="${esc(c.effect)}" ${session.can("engineer") ? "" : "disabled"}>Add effect</button>
    </div>`).join("");
    $("diag-notes").innerHTML = (d.notes || []).map(esc).join("<br>");
    for (const b of document.querySelectorAll("[data-add]")) b.onclick = () => addEffect(b.dataset.add);
  } catch (e) { $("wb-error").textContent = e.message; }
  finally { setBusy(false); }
}

async function addEffect(effect) {
  if (busy) return;
  setBusy(true);
  $("wb-error").textContent = "";
  try {
    const v = await post(`/workbench/measurements/${selected}/add-effect`, { effect });
    toast(`Added ${effect}: RMS ${fmt(v.fit.rms_deg, 4)}°`);
    await loadVersions();
    await compare();
    setBusy(false);
    await diagnose();
  } catch (e) { $("wb-error").textContent = e.message; }
  finally { setBusy(false); }
}

async function refit() {
  setBusy(true);
  try {
    await post(`/workbench/measurements/${selected}/fit`, {});
    await loadVersions();
    await compare();
  } catch (e) { $("wb-error").textContent = e.message; }
  finally { setBusy(false); }
}

async function designOnModel() {
  const v = versions.find((x) => x.id === shownVersion) || versions[versions.length - 1];
  if (!v) return;
  $("wb-error").textContent = "";
  try {
    const g = await put(`/axes/${v.model.axis}/model`, { version_id: v.id });
    const check = g.model_check;
    const checked = check && check.judged
      ? `; predicts the last ${fmt(check.window_s)} s with ${fmt(check.candidate_rms_deg, 3)}° (limit ${fmt(check.limit_deg, 3)}°)`
      : check ? ` (not checked against recent motion: ${check.note})` : "";
    toast(`${v.model.axis} controller redesigned on ${v.label}: phase margin ${fmt(g.margins.phase_margin_deg)}°${checked}`);
  } catch (e) { $("wb-error").textContent = e.message; }
}
