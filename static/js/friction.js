// Friction-ID page: start a job, follow its progress, cancel, plot torque against velocity.
import { $, esc, fmt, get, post, toast } from "./api.js";
import { C, dots, line, makeChart, setData, watchSize } from "./charts.js";
import { jobCard } from "./jobs.js";
import * as speedid from "./speedid.js";

let card = null;

export function init() {
  makeChart($("plot-friction"), {
    height: 380, xLabel: "velocity (rad/s)", yLabel: "torque (N·m)",
    series: [dots("measured", C.actual), line("fitted friction", C.target)],
  });
  watchSize($("plot-friction"));
  $("fric-form").addEventListener("submit", start);
  card = jobCard("fric", showResult, (msg) => toast(msg, true));
  speedid.init();
}

// The live rig's sweep is offered when the service drives a DC rig over a serial controller.
export async function show() {
  speedid.show();
  try {
    const s = await get("/status");
    const serial = s.driver?.kind === "serial";
    $("fric-live").hidden = !serial;
    $("fric-live").textContent = serial ? `this rig (${s.driver.url}), taken over while it runs` : "";
    if (!serial && $("fric-source").value === "live") $("fric-source").value = "rig";
  } catch { /* the status error shows on the live page */ }
}

export async function start(ev, source) {
  ev?.preventDefault();
  $("fric-error").textContent = "";
  try {
    const job = await post("/jobs/friction-id", { axis: $("fric-axis").value, source: source || $("fric-source").value });
    card.follow(job.id);
  } catch (e) { $("fric-error").textContent = e.message; }
}
window.console3dat_friction = { start };

function showResult(r) {
  const v = r.plot.velocity_rad_s, tq = r.plot.torque_nm;
  const order = v.map((_, i) => i).sort((a, b) => v[a] - v[b]);
  const vs = order.map((i) => v[i]), ts = order.map((i) => tq[i]);
  // Break the lines at rest: Coulomb friction jumps there, nothing was measured in between.
  const cut = vs.findIndex((w) => w > 0);
  if (cut > 0) { vs.splice(cut, 0, 0); ts.splice(cut, 0, null); }
  const pos = r.positive, neg = r.negative;
  // Each direction's line, torque = viscous·ω ± Coulomb, drawn over the measured velocities.
  const fitted = vs.map((w) => (w > 0 ? pos.coulomb_nm + pos.viscous_nm_s_per_rad * w
    : w < 0 ? -neg.coulomb_nm + neg.viscous_nm_s_per_rad * w : null));
  setData($("plot-friction"), [vs, ts, fitted]);
  const row = (name, unit, p, n, pse, nse) => `<tr><td>${name}</td><td>${Number(p).toPrecision(4)} ± ${Number(pse).toPrecision(2)}</td>
    <td>${Number(n).toPrecision(4)} ± ${Number(nse).toPrecision(2)}</td><td>${unit}</td></tr>`;
  $("fric-params").innerHTML = `<tr><th></th><th>positive direction</th><th>negative direction</th><th>unit</th></tr>`
    + row("Coulomb friction", "N·m", pos.coulomb_nm, neg.coulomb_nm, pos.coulomb_se, neg.coulomb_se)
    + row("Viscous friction", "N·m·s/rad", pos.viscous_nm_s_per_rad, neg.viscous_nm_s_per_rad, pos.viscous_se, neg.viscous_se)
    + `<tr><td>Break-away</td><td>${fmt(1000 * r.breakaway_nm.positive, 1)} mN·m</td><td>${fmt(1000 * r.breakaway_nm.negative, 1)} mN·m</td><td></td></tr>`
    + `<tr><td colspan="4" class="muted">${r.shows_stiction ? "Break-away needs clearly more torque than Coulomb friction: stiction." : "No stiction: break-away matches the Coulomb intercept."}
       ${r.points.length} constant-voltage runs, ${fmt(r.simulated_s, 0)} s on the rig. Model parameters: ${Object.entries(r.params).map(([k, x]) => `${esc(k)} = ${Number(x).toPrecision(4)}`).join(", ")}</td></tr>`;
}
