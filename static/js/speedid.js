// Speed-table identification card (on the Friction-ID page, shown when the driver is a PTZ camera):
// start the job, follow its progress, cancel, plot the measured speed per step against the profile's.
import { $, esc, fmt, get, post } from "./api.js";
import { C, dots, line, makeChart, setData, watchSize } from "./charts.js";
import { jobCard } from "./jobs.js";

let card = null;

export function init() {
  makeChart($("plot-speedid"), {
    height: 300, xLabel: "speed step", yLabel: "speed (°/s)",
    series: [line("profile", C.muted), dots("measured +", C.actual), dots("measured −", C.target)],
  });
  watchSize($("plot-speedid"));
  $("sid-form").addEventListener("submit", start);
  card = jobCard("sid", showResult);
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
    card.follow(job.id);
  } catch (e) { $("sid-error").textContent = e.message; }
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
