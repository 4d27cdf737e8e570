// Practice rig page: start, run experiments (recorded as workbench measurements), friction
// sweep, reveal the hidden effect and compare fitted with true parameters.
import { $, esc, fmt, get, post, toast } from "./api.js";

let session;

export function init(s) {
  session = s;
  $("practice-new").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    try { await post("/practice", { axis: $("practice-axis").value }); $("reveal-box").innerHTML = ""; toast("New practice rig: one effect is hidden"); load(); }
    catch (e) { $("practice-error").textContent = e.message; }
  });
  $("practice-exp").addEventListener("submit", runExperiment);
  $("exp-friction").addEventListener("click", () => {
    document.querySelector('#tabs button[data-tab="friction"]').click();
    $("fric-source").value = "practice";
    window.console3dat_friction.start(null, "practice");
  });
  $("practice-reveal").addEventListener("click", reveal);
}

export function show() { load(); }

async function load() {
  $("practice-error").textContent = "";
  const st = await get("/practice");
  if (!st.active) { $("practice-state").textContent = "No practice rig yet."; $("practice-meas").innerHTML = ""; return; }
  $("practice-state").textContent = `Practice rig on the ${st.axis} axis · hidden effect: ${st.revealed ? st.truth.effects.join(", ") : "secret"}`;
  $("practice-axis").value = st.axis;
  $("fric-axis").value = st.axis;
  const list = await get("/workbench/measurements");
  const mine = list.filter((m) => st.measurements.includes(m.id));
  $("practice-meas").innerHTML = mine.map((m) => `<li><span><b>${esc(m.name)}</b><span class="meta"> #${m.id}</span></span>
    <button class="small" data-open="${m.id}">Open in workbench</button></li>`).join("");
  for (const b of document.querySelectorAll("[data-open]")) b.onclick = () => openInWorkbench(+b.dataset.open);
}

async function openInWorkbench(id) {
  document.querySelector('#tabs button[data-tab="workbench"]').click();
  await window.console3dat_workbench.selectMeasurement(id);
}

async function runExperiment(ev) {
  ev.preventDefault();
  $("practice-error").textContent = "";
  $("practice-busy").hidden = false;
  try {
    const rec = await post("/practice/experiments", { kind: $("exp-kind").value, duration_s: +$("exp-duration").value });
    toast(`Recorded ${rec.name}`);
    await load();
  } catch (e) { $("practice-error").textContent = e.message; }
  finally { $("practice-busy").hidden = true; }
}

async function reveal() {
  if (!confirm("Reveal the hidden effect? The exercise is over once you look.")) return;
  try {
    const r = await post("/practice/reveal");
    const rows = r.params.filter((p) => r.truth.effects.some((e) => p.param.startsWith(e + ".")) || ["inertia.J", "viscous.b", "coulomb.torque"].includes(p.param));
    $("reveal-box").innerHTML = `<p class="state-line">Hidden: ${esc(r.truth.effects.join(", "))}.
      ${r.compared_version ? `Your latest model (${esc(r.compared_effects.join(", ") || "base")}) found it: ${r.truth.effects.every((e) => r.compared_effects.includes(e)) ? "yes" : "no"}.` : "No model fitted yet."}</p>
      <table class="table"><tr><th>Parameter</th><th>True</th><th>Fitted</th><th>Error</th></tr>` +
      rows.map((p) => `<tr><td>${esc(p.param)}</td><td>${Number(p.true).toPrecision(4)}</td><td>${p.fitted === null || p.fitted === undefined ? "–" : Number(p.fitted).toPrecision(4)}</td>
      <td>${p.error_percent === null || p.error_percent === undefined ? "–" : `${fmt(p.error_percent, 1)} %`}</td></tr>`).join("") + "</table>";
    load();
  } catch (e) { $("practice-error").textContent = e.message; }
}
