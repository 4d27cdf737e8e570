// Friction-ID page: start a job, follow its progress, cancel, plot torque against velocity.
import { $, esc, fmt, get, post, toast } from "./api.js";
import { C, dots, line, makeChart, setData, watchSize } from "./charts.js";

let jobId = null;
let timer = null;

export function init() {
  makeChart($("plot-friction"), {
    height: 380, xLabel: "velocity (rad/s)", yLabel: "torque (N·m)",
    series: [dots("measured", C.actual), line("fitted friction", C.target)],
  });
  watchSize($("plot-friction"));
  $("fric-form").addEventListener("submit", start);
  $("fric-cancel").addEventListener("click", async () => {
    if (jobId) try { await post(`/jobs/${jobId}/cancel`); } catch (e) { toast(e.message, true); }
  });
}

export function show() {}

export async function start(ev, source) {
  ev?.preventDefault();
  $("fric-error").textContent = "";
  try {
    const job = await post("/jobs/friction-id", { axis: $("fric-axis").value, source: source || $("fric-source").value });
    follow(job.id);
  } catch (e) { $("fric-error").textContent = e.message; }
}
window.console3dat_friction = { start };

function follow(id) {
  jobId = id;
  $("fric-cancel").disabled = false;
  clearInterval(timer);
  timer = setInterval(poll, 300);
  poll();
}

async function poll() {
  try {
    const j = await get(`/jobs/${jobId}`);
    $("fric-bar").style.width = `${(100 * j.progress).toFixed(0)}%`;
    $("fric-status").textContent = `Job ${j.id}: ${j.state} · ${(100 * j.progress).toFixed(0)} %${j.message ? ` · ${j.message}` : ""}`;
    if (["done", "failed", "cancelled"].includes(j.state)) {
      clearInterval(timer);
      $("fric-cancel").disabled = true;
      if (j.state === "done") showResult(j.result);
      if (j.state === "failed") $("fric-error").textContent = j.message;
    }
  } catch (e) { clearInterval(timer); $("fric-error").textContent = e.message; }
}

function pick(obj, ...names) { for (const n of names) if (obj && obj[n] !== undefined) return obj[n]; return undefined; }

function showResult(r) {
  const pts = pick(r, "points") || [];
  let v = pick(r, "velocity_rad_s", "omega_rad_s") || pts.map((p) => pick(p, "velocity_rad_s", "omega_rad_s"));
  let tq = pick(r, "torque_nm") || pts.map((p) => p.torque_nm);
  const order = v.map((_, i) => i).sort((a, b) => v[a] - v[b]);
  v = order.map((i) => v[i]); tq = order.map((i) => tq[i]);
  const params = pick(r, "params") || {};
  const fc = pick(params, "coulomb.torque") ?? 0, b = pick(params, "viscous.b") ?? 0;
  const fcn = pick(params, "coulomb_asymmetry.negative") ?? fc, bn = pick(params, "viscous_asymmetry.negative") ?? b;
  const fitted = v.map((w) => (w > 0 ? fc + b * w : w < 0 ? -fcn + bn * w : null));
  setData($("plot-friction"), [v, tq, fitted]);
  const stderr = pick(r, "stderr") || {};
  const truth = pick(r, "true_params") || {};
  $("fric-params").innerHTML = `<tr><th>Parameter</th><th>Identified</th><th>± std. error</th>${Object.keys(truth).length ? "<th>Rig (truth)</th>" : ""}</tr>` +
    Object.entries(params).map(([k, val]) => `<tr><td>${esc(k)}</td><td>${Number(val).toPrecision(4)}</td>
      <td>${stderr[k] !== undefined ? Number(stderr[k]).toPrecision(2) : "–"}</td>${Object.keys(truth).length ? `<td>${truth[k] !== undefined ? Number(truth[k]).toPrecision(4) : "–"}</td>` : ""}</tr>`).join("");
}
