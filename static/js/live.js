// Live page: telemetry plots, status, tracking, click-to-point, jog pad, presets, 3D view.
import { $, del, esc, fmt, get, post, put, savedKey, toast } from "./api.js";
import { C, line, makeChart, minSpan, setData, watchSize } from "./charts.js";
import { describeCapture } from "./audio.js";

const WINDOW_S = 10;
const MAX_POINTS = 4000;
const buf = { t: [], pan: [], panT: [], tilt: [], tiltT: [] };
let paused = false;
let ws = null;
let frames = 0;
let lastFrame = null;
let limits = { pan: 90, tilt: 45 };
let session;
window.console3dat_live = { get lastFrame() { return lastFrame; }, get frames() { return frames; } };

export function init(s) {
  session = s;
  const panEl = $("plot-pan"), tiltEl = $("plot-tilt");
  const scales = { scales: { x: { time: false }, y: { range: minSpan(4) } } };
  makeChart(panEl, { height: 190, xLabel: "time (s)", yLabel: "pan °", opts: scales, series: [line("pan", C.actual), line("pan target", C.target, { dash: [6, 4] })] });
  makeChart(tiltEl, { height: 190, xLabel: "time (s)", yLabel: "tilt °", opts: scales, series: [line("tilt", C.actual), line("tilt target", C.target, { dash: [6, 4] })] });
  watchSize(panEl); watchSize(tiltEl);
  for (const el of [panEl, tiltEl]) el.addEventListener("dblclick", () => { zoomed = false; redraw(true); });
  $("pause").addEventListener("click", () => { paused = !paused; $("pause").textContent = paused ? "Resume" : "Pause"; });
  $("unzoom").addEventListener("click", () => { zoomed = false; redraw(true); });
  for (const el of [panEl, tiltEl]) el.addEventListener("mouseup", () => { zoomed = true; });
  $("tracking-toggle").addEventListener("change", onTracking);
  $("clear-faults").addEventListener("click", async () => {
    try { await post("/faults/clear"); toast("Faults cleared, drive enabled"); refreshStatus(); } catch (e) { toast(e.message, true); }
  });
  $("takeover").addEventListener("click", async () => {
    try { await post("/control?force=true"); toast("You hold manual control"); refreshStatus(); } catch (e) { toast(e.message, true); }
  });
  $("release").addEventListener("click", async () => {
    try { await del("/pointing"); toast("Manual control released"); } catch (e) { toast(e.message, true); }
  });
  $("point-form").addEventListener("submit", (ev) => { ev.preventDefault(); pointAt(+$("point-pan").value, +$("point-tilt").value); });
  $("preset-form").addEventListener("submit", storePreset);
  setupField();
  setupJog();
  connect();
  refreshStatus();
  setInterval(refreshStatus, 500);
  setInterval(() => { if (!paused) redraw(false); }, 100);
  let counted = 0, since = performance.now();
  setInterval(() => {
    const now = performance.now();
    $("conn-rate").textContent = `${Math.round((1000 * (frames - counted)) / (now - since))} Hz`;
    counted = frames; since = now;
  }, 1000);
  loadPresets();
  setTimeout(setupViewer, 800);  // let the console draw first; the 3D view's bundle is heavy
}

export function show() {}

let zoomed = false;
function redraw(reset) {
  const data = [buf.t, buf.pan, buf.panT, buf.tilt, buf.tiltT];
  if (zoomed && !reset) return;
  setData($("plot-pan"), [data[0], data[1], data[2]]);
  setData($("plot-tilt"), [data[0], data[3], data[4]]);
}

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  ws = new WebSocket(`${proto}://${location.host}/api/v1/telemetry`);
  ws.onopen = () => ws.send(JSON.stringify({ key: savedKey() }));
  ws.onmessage = (ev) => {
    const f = JSON.parse(ev.data);
    if (f.type !== "frame") { $("conn-dot").className = "dot on"; return; }
    frames++;
    lastFrame = f;
    if (!paused) push(f);
    showFrame(f);
  };
  ws.onclose = () => { $("conn-dot").className = "dot off"; setTimeout(connect, 1500); };
}

function push(f) {
  buf.t.push(f.t_s); buf.pan.push(f.pan_deg); buf.panT.push(f.pan_target_deg);
  buf.tilt.push(f.tilt_deg); buf.tiltT.push(f.tilt_target_deg);
  const t0 = f.t_s - WINDOW_S;
  let cut = 0;
  while (cut < buf.t.length && (buf.t[cut] < t0 || buf.t.length - cut > MAX_POINTS)) cut++;
  if (cut) for (const k of Object.keys(buf)) buf[k].splice(0, cut);
}

let lastShown = 0;
function showFrame(f) {
  const now = performance.now();
  if (now - lastShown < 50) return;
  lastShown = now;
  $("pan-val").textContent = fmt(f.pan_deg, 1);
  $("tilt-val").textContent = fmt(f.tilt_deg, 1);
  $("pan-tgt").textContent = fmt(f.pan_target_deg, 1);
  $("tilt-tgt").textContent = fmt(f.tilt_target_deg, 1);
  $("estimate").textContent = f.estimate_azimuth_deg == null ? "no speech" :
    `az ${fmt(f.estimate_azimuth_deg, 1)}°` + (f.estimate_elevation_deg == null ? "" : `, el ${fmt(f.estimate_elevation_deg, 1)}°`);
  placeField(f);
}

function describeDriver(d) {
  if (!d || d.kind === "sim") return "simulated rig";
  const parts = [d.profile ? `${d.url} (${d.profile})` : d.url, d.state];
  if (d.board) parts.push(d.board);
  if (d.board_limits) parts.push(d.board_limits);  // "limits enforced by the board" / "... by the host only"
  if (d.achieved_rate_hz != null) parts.push(`${fmt(d.achieved_rate_hz, 0)} Hz`);
  if (d.rtt_ms_median != null) parts.push(`RTT ${fmt(d.rtt_ms_median, 0)} ms`);
  if (d.retransmits) parts.push(`${d.retransmits} resent`);
  const lim = d.camera_limits;
  if (lim && lim.state === "set") parts.push("camera limits set");
  else if (lim) parts.push(`camera limits ${lim.state}: host guard only`);
  return parts.join(" · ");
}

async function refreshStatus() {
  try {
    const s = await get("/status");
    limits = s.limits_deg;
    $("mode").textContent = s.mode;
    $("talker").textContent = s.active_talker || "–";
    const cap = s.audio_capture;
    $("audio").textContent = cap ? describeCapture(cap) : s.audio === "ready" ? "simulated meeting (room model → localizer → talker tracker)" : s.audio;
    $("audio").style.color = cap && cap.state === "fault" ? "var(--bad)" : "";
    const talkers = s.talkers || [];
    const now = talkers.find((t) => t.speaking);
    $("talkers").textContent = talkers.length ? `${talkers.length} followed · ` + (now ? `talker ${now.talker_id + 1} at ${fmt(now.azimuth_deg, 0)}° speaking` : "nobody speaking")
      + " · " + talkers.map((t) => `${t.talker_id + 1}: ${fmt(t.azimuth_deg, 0)}°`).join(", ") : "–";
    $("driver").textContent = describeDriver(s.driver);
    $("faults").firstChild.textContent = s.faults.length ? `${s.faults.join(", ")} ` : "none ";
    $("faults").style.color = s.faults.length ? "var(--bad)" : "";
    $("clear-faults").hidden = !(s.faults.length && session.can("engineer"));
    $("holder").textContent = s.control_holder ? `${s.control_holder.name} (${s.control_holder.held_s} s)` : "nobody";
    const other = s.control_holder && s.control_holder.name !== session.name;
    $("takeover").hidden = !(other && session.can("engineer"));
    const t = $("tracking-toggle");
    if (document.activeElement !== t) t.checked = s.tracking;
    document.body.dataset.mode = s.mode;
    if (s.viewer) $("viewer-state").textContent =
      `3D view shows pan ${fmt(s.viewer.pan_deg, 1)}°, tilt ${fmt(s.viewer.tilt_deg, 1)}° · ${s.viewer.clients} viewer(s) · share URL ${s.viewer.share_url_enabled ? "ENABLED" : "disabled"}`;
    window.console3dat_status = s;
  } catch (e) { /* shown by the connection dot */ }
}

async function onTracking(ev) {
  const enabled = ev.target.checked;
  try {
    const r = await put("/tracking", { enabled });
    toast(`Tracking ${r.tracking ? "on" : "off"}`);
  } catch (e) { ev.target.checked = !enabled; toast(e.message, true); }
  refreshStatus();
}

async function pointAt(pan, tilt) {
  $("point-error").textContent = "";
  try {
    await put("/pointing", { pan_deg: pan, tilt_deg: tilt });
    $("point-pan").value = pan.toFixed(1); $("point-tilt").value = tilt.toFixed(1);
  } catch (e) {
    $("point-error").textContent = e.body?.limit_deg !== undefined ? `${e.message} (limit ±${e.body.limit_deg}°)` : e.message;
  }
  refreshStatus();
}

// Click-to-point field: x = pan (left = +pan, as seen from behind the camera), y = tilt (up = +).
function setupField() {
  const svg = $("point-field");
  const g = svg.querySelector(".field-grid");
  let html = "";
  for (let p = -90; p <= 90; p += 30) html += `<line x1="${-p}" y1="-45" x2="${-p}" y2="45" class="${p === 0 ? "axis" : ""}"/><text x="${-p + 1}" y="43">${p}</text>`;
  for (let t = -45; t <= 45; t += 15) html += `<line x1="-90" y1="${-t}" x2="90" y2="${-t}" class="${t === 0 ? "axis" : ""}"/>`;
  g.innerHTML = html;
  svg.addEventListener("click", (ev) => {
    const pt = svg.createSVGPoint();
    pt.x = ev.clientX; pt.y = ev.clientY;
    const p = pt.matrixTransform(svg.getScreenCTM().inverse());
    const pan = Math.max(-limits.pan, Math.min(limits.pan, -p.x));
    const tilt = Math.max(-limits.tilt, Math.min(limits.tilt, -p.y));
    pointAt(Math.round(pan * 10) / 10, Math.round(tilt * 10) / 10);
  });
}

function placeField(f) {
  const a = $("pf-actual"), t = $("pf-target"), e = $("pf-estimate");
  a.setAttribute("cx", -f.pan_deg); a.setAttribute("cy", -f.tilt_deg);
  t.setAttribute("transform", `translate(${-f.pan_target_deg} ${-f.tilt_target_deg})`);
  if (f.estimate_azimuth_deg == null) e.setAttribute("visibility", "hidden");
  else { e.setAttribute("visibility", "visible"); e.setAttribute("cx", -f.estimate_azimuth_deg); e.setAttribute("cy", -(f.estimate_elevation_deg || 0)); }
}

// Jog: press sends a rate and repeats every 150 ms; release (or leaving the button) stops.
// Arrow keys do the same while no text field has the focus.
const jogTimers = {};
function jogPress(axis, dir, button) {
  const key = `${axis}${dir}`;
  if (jogTimers[key]) return;
  button?.classList.add("held");
  const send = () => put(`/jog/${axis}`, { rate_deg_s: +$("jog-speed").value * dir })
    .catch((e) => { jogRelease(axis, dir, button); toast(e.message, true); });
  send();
  jogTimers[key] = setInterval(send, 150);
}
function jogRelease(axis, dir, button) {
  const key = `${axis}${dir}`;
  if (!jogTimers[key]) return;
  clearInterval(jogTimers[key]); delete jogTimers[key];
  button?.classList.remove("held");
  del(`/jog/${axis}`).catch(() => {});
}

const ARROWS = { ArrowLeft: ["pan", 1], ArrowRight: ["pan", -1], ArrowUp: ["tilt", 1], ArrowDown: ["tilt", -1] };
function setupJog() {
  for (const b of document.querySelectorAll(".jogbtn")) {
    const axis = b.dataset.axis, dir = +b.dataset.dir;
    b.addEventListener("pointerdown", (ev) => { ev.preventDefault(); jogPress(axis, dir, b); });
    for (const up of ["pointerup", "pointerleave", "pointercancel"]) b.addEventListener(up, () => jogRelease(axis, dir, b));
  }
  const onLive = () => !$("page-live").hidden && !["INPUT", "SELECT", "TEXTAREA"].includes(document.activeElement?.tagName);
  const btn = (axis, dir) => document.querySelector(`.jogbtn[data-axis="${axis}"][data-dir="${dir}"]`);
  document.addEventListener("keydown", (ev) => {
    const a = ARROWS[ev.key];
    if (!a || !onLive() || ev.repeat) return;
    ev.preventDefault();
    jogPress(a[0], a[1], btn(a[0], a[1]));
  });
  document.addEventListener("keyup", (ev) => {
    const a = ARROWS[ev.key];
    if (a) jogRelease(a[0], a[1], btn(a[0], a[1]));
  });
  window.addEventListener("blur", () => { for (const k of Object.keys(ARROWS)) jogRelease(ARROWS[k][0], ARROWS[k][1], btn(ARROWS[k][0], ARROWS[k][1])); });
}

async function loadPresets() {
  try {
    const list = await get("/presets");
    $("preset-list").innerHTML = list.length ? list.map((p) => `<li><span><b>${esc(p.name)}</b>
      <span class="meta">pan ${fmt(p.pan_deg)}°, tilt ${fmt(p.tilt_deg)}°</span></span>
      <span><button class="small" data-recall="${esc(p.name)}">Go</button>
      <button class="small ghost" data-delete="${esc(p.name)}" title="delete">✕</button></span></li>`).join("")
      : `<li class="muted">No presets yet.</li>`;
    for (const b of document.querySelectorAll("[data-recall]")) b.onclick = async () => {
      try { await post(`/presets/${encodeURIComponent(b.dataset.recall)}/recall`); toast(`Going to ${b.dataset.recall}`); }
      catch (e) { toast(e.message, true); }
    };
    for (const b of document.querySelectorAll("[data-delete]")) b.onclick = async () => {
      try { await del(`/presets/${encodeURIComponent(b.dataset.delete)}`); loadPresets(); } catch (e) { toast(e.message, true); }
    };
  } catch (e) { toast(e.message, true); }
}

async function storePreset(ev) {
  ev.preventDefault();
  const name = $("preset-name").value.trim();
  try { await put(`/presets/${encodeURIComponent(name)}`, {}); $("preset-name").value = ""; toast(`Stored ${name}`); loadPresets(); }
  catch (e) { toast(e.message, true); }
}

async function setupViewer() {
  try {
    const v = await get("/viewer");
    if (!v.enabled) { $("viewer-box").innerHTML = `<p class="muted">${esc(v.note)}</p>`; return; }
    // The view comes through the console (same origin, works behind TLS): this call sets the
    // view-session cookie that the iframe and its WebSocket carry (they cannot send the key).
    const session = await post("/view/session");
    const url = session.url;
    $("viewer-box").innerHTML = `<iframe title="3D view of the rig" src="${url}" loading="lazy"></iframe>`;
    $("viewer-link").href = url;
  } catch (e) { $("viewer-box").innerHTML = `<p class="muted">${esc(e.message)}</p>`; }
}
