// Audio page: the camera operator's policy (each setting with its meaning), the talkers the
// tracker has followed (a plot seen from above and a list), the sound card's state and devices.
import { $, del, esc, fmt, get, put, toast } from "./api.js";

let session;
let policy = null;
let timer = null;

export function init(s) {
  session = s;
  $("policy-apply").addEventListener("click", apply);
  $("policy-revert").addEventListener("click", () => { if (policy) drawForm(policy); });
  $("policy-reset").addEventListener("click", reset);
  $("policy-form").addEventListener("submit", (ev) => { ev.preventDefault(); apply(); });
  $("policy-form").addEventListener("input", (ev) => {
    const inp = ev.target;
    inp.classList.toggle("changed", inp.value !== inp.dataset.shown);
  });
  $("devices-refresh").addEventListener("click", listDevices);
  const engineer = session.can("engineer");
  for (const id of ["policy-apply", "policy-reset", "policy-revert"]) {
    $(id).disabled = !engineer;
    $(id).title = engineer ? "" : "needs the engineer role";
  }
  $("devices-refresh").hidden = !engineer;
  drawPlotFrame();
}

export function show() {
  loadPolicy();
  refresh();
  clearInterval(timer);
  timer = setInterval(() => { if (!$("page-audio").hidden) refresh(); }, 500);
}

async function loadPolicy() {
  $("policy-error").textContent = "";
  try { drawForm(await get("/audio/policy")); } catch (e) { $("policy-error").textContent = e.message; }
}

const UNIT = { s: " s", deg: "°", count: "" };
const rangeText = (f) => f.unit === "count" ? `${f.min}–${f.max} (whole number)` : `${f.min}–${f.max}${UNIT[f.unit]}`;

function drawForm(p) {
  policy = p;
  const source = { default: "built-in defaults", config: "from the config file", stored: "set here" }[p.source] || p.source;
  $("policy-source").textContent = `· ${source}`;
  const ro = session.can("engineer") ? "" : "disabled";
  $("policy-form").innerHTML = p.fields.map((f) => {
    const v = p.values[f.name];
    const step = f.unit === "count" ? 1 : "any";
    return `<label for="pol-${f.name}">${esc(f.name)}</label>
      <input id="pol-${f.name}" data-name="${esc(f.name)}" type="number" step="${step}" min="${f.min}" max="${f.max}"
        value="${v}" data-shown="${v}" ${ro}>
      <span class="range">${esc(rangeText(f))} · default ${f.default}${UNIT[f.unit]}</span>
      <p class="meaning">${esc(f.meaning[0].toUpperCase() + f.meaning.slice(1))}.</p>`;
  }).join("");
}

function changes() {
  const out = {};
  for (const inp of $("policy-form").querySelectorAll("input")) {
    if (inp.value !== inp.dataset.shown) out[inp.dataset.name] = inp.value === "" ? null : Number(inp.value);
  }
  return out;
}

async function apply() {
  $("policy-error").textContent = "";
  const body = changes();
  if (!Object.keys(body).length) { toast("Nothing changed"); return; }
  try {
    drawForm(await put("/audio/policy", body));
    toast(`Camera operator updated: ${Object.keys(body).join(", ")}`);
  } catch (e) {
    $("policy-error").textContent = e.message;
    if (e.body?.field) $(`pol-${e.body.field}`)?.focus();
  }
}

async function reset() {
  $("policy-error").textContent = "";
  try { drawForm(await del("/audio/policy")); toast("Back to the room's defaults"); }
  catch (e) { $("policy-error").textContent = e.message; }
}

// Seen from above: the camera at the centre, 0° straight ahead (up), +azimuth to the left.
function drawPlotFrame() {
  let html = "";
  for (const r of [33, 66, 100]) html += `<path class="ring" d="M ${-r} 0 A ${r} ${r} 0 0 1 ${r} 0"/>`;
  for (let a = -90; a <= 90; a += 30) {
    const x = -100 * Math.sin(a * Math.PI / 180), y = -100 * Math.cos(a * Math.PI / 180);
    html += `<line class="spoke" x1="0" y1="0" x2="${x}" y2="${y}"/><text x="${1.08 * x - 6}" y="${1.08 * y + 3}">${a}°</text>`;
  }
  html += `<rect x="-4" y="-3" width="8" height="6" fill="#282830"/><g id="talker-dots"></g>`;
  $("talker-plot").innerHTML = html;
}

function drawTalkers(talkers) {
  $("talker-dots").innerHTML = talkers.map((t) => {
    const a = t.azimuth_deg * Math.PI / 180;
    const x = -85 * Math.sin(a), y = -85 * Math.cos(a);
    return `<circle class="talker${t.speaking ? " speaking" : ""}" cx="${x}" cy="${y}" r="${t.speaking ? 8 : 6}"/>
      <text class="talker-label" x="${x - 3}" y="${y + 3}" fill="#fff">${t.talker_id + 1}</text>`;
  }).join("");
  $("talker-list").innerHTML = talkers.length ? talkers.map((t) => `<li class="${t.speaking ? "speaking" : ""}">
      <span><b>Talker ${t.talker_id + 1}</b> <span class="meta">at ${fmt(t.azimuth_deg, 0)}°${t.elevation_deg == null ? "" : `, ${fmt(t.elevation_deg, 0)}° up`}</span></span>
      <span class="meta">${t.speaking ? "speaking now" : t.last_spoken_ago_s == null ? "not heard yet" : `spoke ${ago(t.last_spoken_ago_s)} ago`} · talked ${fmt(t.speaking_s, 0)} s</span></li>`).join("")
    : `<li class="muted">Nobody yet: the tracker lists people once it has framed them.</li>`;
}

const ago = (s) => s < 60 ? `${fmt(s, 0)} s` : `${fmt(s / 60, 0)} min`;

export function describeCapture(c) {
  if (!c) return null;
  const rate = c.device_rate_hz ? `${fmt(c.device_rate_hz / 1000, 1)} kHz → ${fmt(c.pipeline_rate_hz / 1000, 0)} kHz` : "";
  const counts = `${c.overflows} overflow(s), ${c.dropped_blocks} dropped block(s), ${c.reconnects} reconnect(s)`;
  if (c.state === "fault") return `FAULT: ${c.fault}${c.retry_in_s != null ? ` (next try in ${fmt(c.retry_in_s, 1)} s)` : ""} · ${counts}`;
  return `${c.device} · ${rate} · mics on channels ${c.channel_map.join(", ")} · ${counts}`
    + (c.resample_cpu_ms_per_s != null ? ` · resampling ${fmt(c.resample_cpu_ms_per_s, 1)} ms/s` : "");
}

async function refresh() {
  try {
    const s = await get("/status");
    drawTalkers(s.talkers || []);
    const c = s.audio_capture;
    $("capture-state").textContent = describeCapture(c) || s.audio;
    $("capture-state").style.color = c && c.state === "fault" ? "var(--bad)" : "";
  } catch (e) { /* the connection dot shows it */ }
}

async function listDevices() {
  $("devices-error").textContent = "";
  try {
    const r = await get("/audio/devices");
    $("device-list").innerHTML = r.devices.length ? r.devices.map((d) => `<li><span><b>${esc(d.name)}</b>
        <span class="meta">#${d.index} · ${esc(d.host_api)}${d.default ? " · default" : ""}</span></span>
        <span class="meta">${d.max_input_channels} in · ${fmt(d.default_rate_hz / 1000, 1)} kHz</span></li>`).join("")
      : `<li class="muted">No input device${r.note ? `: ${esc(r.note)}` : ""}</li>`;
  } catch (e) { $("devices-error").textContent = e.message; }
}
