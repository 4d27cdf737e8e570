// Gain tuning: edit an axis' gains, preview margins and the predicted step response, then apply.
import { $, esc, fmt, get, post, put, toast } from "./api.js";
import { C, line, makeChart, setData, watchSize } from "./charts.js";

let current = null;
let previewOk = false;
let session;

export function init(s) {
  session = s;
  makeChart($("plot-step"), { height: 260, xLabel: "time (s)", yLabel: "angle °",
    series: [line("current gains", "#8a96a6"), line("candidate", C.actual), line("step", C.target, { dash: [4, 4] })] });
  watchSize($("plot-step"));
  $("tune-axis").addEventListener("change", load);
  $("tune-preview").addEventListener("click", preview);
  $("tune-apply").addEventListener("click", apply);
  $("tune-reset").addEventListener("click", load);
  $("tune-step").addEventListener("change", preview);
  $("gain-form").addEventListener("input", () => { previewOk = false; $("tune-apply").disabled = true; });
  $("tune-apply").title = session.can("engineer") ? "" : "needs the engineer role";
}

export function show() { load(); }

const axis = () => $("tune-axis").value;

async function load() {
  $("tune-error").textContent = "";
  try {
    const g = await get(`/axes/${axis()}/gains`);
    current = g;
    $("tune-type").textContent = `${g.gains.type} · phase-margin floor ${g.min_phase_margin_deg}°`;
    $("gain-form").innerHTML = Object.entries(g.gains).filter(([k]) => k !== "type").map(([k, v]) =>
      `<label for="g-${k}">${esc(k)}</label><input id="g-${k}" data-name="${esc(k)}" type="number" step="any"
        value="${shown(v)}" data-shown="${shown(v)}">`).join("");
    showMargins(g.margins, g.min_phase_margin_deg);
    await preview();
  } catch (e) { $("tune-error").textContent = e.message; }
}

const shown = (v) => String(Number(Number(v).toPrecision(6)));

// Only the fields a person edited (the form shows 6 significant digits of the exact values).
function changes() {
  const out = {};
  for (const inp of $("gain-form").querySelectorAll("input")) {
    if (inp.value !== "" && inp.value !== inp.dataset.shown) out[inp.dataset.name] = Number(inp.value);
  }
  return out;
}

async function preview() {
  $("tune-error").textContent = "";
  try {
    const raw = $("tune-step").value === "raw";
    const amp = raw ? 5 : 30;
    const r = await post(`/axes/${axis()}/gains/preview`,
      { gains: changes(), amplitude_deg: amp, duration_s: raw ? 0.6 : 1.5, shaped: !raw });
    const cur = r.current_step, cand = r.step;
    const t = cand.t_s;
    const curY = t.map((_, i) => cur.angle_deg[i] ?? null);
    setData($("plot-step"), [t, curY, cand.angle_deg, t.map(() => amp)]);
    showMargins(r.margins, r.min_phase_margin_deg, cand);
    previewOk = r.margins.acceptable;
    $("tune-apply").disabled = !previewOk || !session.can("engineer");
  } catch (e) { $("tune-error").textContent = e.message; }
}

function showMargins(m, floor, step) {
  const pmOk = m.phase_margin_deg !== null && m.phase_margin_deg >= floor;
  const cells = [
    ["Phase margin", `${fmt(m.phase_margin_deg)}°`, pmOk],
    ["Gain margin", m.gain_margin_db === null ? "∞" : `${fmt(m.gain_margin_db)} dB`, true],
    ["Crossover", `${fmt(m.crossover_hz, 2)} Hz`, true],
    ["Closed loop", m.stable ? "stable" : "UNSTABLE", m.stable],
  ];
  if (step && step.overshoot_percent !== undefined) cells.push(["Overshoot", `${fmt(step.overshoot_percent)} %`, step.overshoot_percent <= 2]);
  if (step && step.rise_time_s !== undefined) cells.push(["Rise time", `${fmt(step.rise_time_s, 3)} s`, true]);
  $("margins").innerHTML = cells.map(([k, v, ok]) => `<div class="metric ${ok ? "good" : "bad"}"><div class="k">${k}</div><div class="v">${v}</div></div>`).join("")
    + `<div class="metric ${m.acceptable ? "good" : "bad"}"><div class="k">Verdict</div><div class="v">${m.acceptable ? "safe to apply" : "would be refused"}</div></div>`;
}

async function apply() {
  $("tune-error").textContent = "";
  try {
    await put(`/axes/${axis()}/gains`, { gains: changes() });
    toast(`Gains applied to ${axis()}`);
    load();
  } catch (e) {
    const m = e.body?.margins;
    $("tune-error").textContent = e.message + (m ? ` — phase margin ${fmt(m.phase_margin_deg)}°, gain margin ${fmt(m.gain_margin_db)} dB` : "");
  }
}
