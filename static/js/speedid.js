// Speed-table identification card (on the Friction-ID page, shown when the driver is a PTZ camera):
// start the job, follow its progress, cancel, plot the measured speed per step against the profile's.
import { $, esc, fmt, get, post } from "./api.js";
import { C, dots, line, makeChart, setData, watchSize } from "./charts.js";

let jobId = null;
let timer = null;

export function init() {
  makeChart($("plot-speedid"), {
    height: 300, xLabel: "speed step", yLabel: "speed (°/s)",
    series: [line("profile", C.muted), dots("measured +", C.actual), dots("measured −", C.target)],
  });
  watchSize($("plot-speedid"));
  $("sid-form").addEventListener("submit", start);
  $("sid-cancel").addEventListener("click", async () => {
    if (jobId) try { await post(`/jobs/${jobId}/cancel`); } catch (e) { $("sid-error").textContent = e.message; }
  });
}

// The card only when the service steers a PTZ camera (driver visca+udp:// or visca+tcp://).
export async function show() {
  try {
    const s = await get("/status");
    const camera = s.driver?.kind === "visca";
    $("sid-card").hidden = !camera;
    if (camera) $("sid-driver").textContent = `${s.driver.url} · profile ${s.driver.profile}`;
  } catch { /* the status error shows on the live page */ }
}

async function start(ev) {
  ev.preventDefault();
  $("sid-error").textContent = "";
  try {
    const job = await post("/jobs/speed-id", { axis: $("sid-axis").value, count: Number($("sid-count").value) });
    follow(job.id);
  } catch (e) { $("sid-error").textContent = e.message; }
}

function follow(id) {
  jobId = id;
  $("sid-cancel").disabled = false;
  clearInterval(timer);
  timer = setInterval(poll, 300);
  poll();
}

async function poll() {
  try {
    const j = await get(`/jobs/${jobId}`);
    $("sid-bar").style.width = `${(100 * j.progress).toFixed(0)}%`;
    $("sid-status").textContent = `Job ${j.id}: ${j.state} · ${(100 * j.progress).toFixed(0)} %${j.message && j.message !== j.state ? ` · ${j.message}` : ""}`;
    if (["done", "failed", "cancelled"].includes(j.state)) {
      clearInterval(timer);
      $("sid-cancel").disabled = true;
      if (j.state === "done") showResult(j.result);
      if (j.state === "failed") $("sid-error").textContent = j.message;
    }
  } catch (e) { clearInterval(timer); $("sid-error").textContent = e.message; }
}

function showResult(r) {
  const steps = [...new Set(r.table_deg_s.map((t) => t.step))].sort((a, b) => a - b);
  const at = (step, dir, key) => r.table_deg_s.find((t) => t.step === step && t.direction === dir)?.[key] ?? null;
  const profile = steps.map((k) => at(k, 1, "profile_deg_s") ?? at(k, -1, "profile_deg_s"));
  setData($("plot-speedid"), [steps, profile, steps.map((k) => at(k, 1, "measured_deg_s")),
    steps.map((k) => at(k, -1, "measured_deg_s"))]);
  const cell = (k, dir) => {
    const m = at(k, dir, "measured_deg_s");
    return m === null ? "<td class=\"muted\">skipped</td>" : `<td>${fmt(m, 3)} (${fmt(at(k, dir, "deviation_percent"), 1)} %)</td>`;
  };
  $("sid-table").innerHTML = `<tr><th>step</th><th>profile °/s</th><th>measured + °/s</th><th>measured − °/s</th></tr>`
    + steps.map((k, i) => `<tr><td>${k}</td><td>${fmt(profile[i], 3)}</td>${cell(k, 1)}${cell(k, -1)}</tr>`).join("")
    + `<tr><td colspan="4" class="muted">${esc(r.axis)} axis against the ${esc(r.profile)} profile, ${fmt(r.elapsed_s, 1)} s.
       ${r.notes.map(esc).join(" ")}</td></tr>`;
}
