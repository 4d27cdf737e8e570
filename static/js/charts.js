// uPlot helpers: charts that follow their container's width; colours from the stylesheet.
const css = getComputedStyle(document.documentElement);
export const C = {
  actual: css.getPropertyValue("--actual").trim() || "#1f6feb",
  target: css.getPropertyValue("--target").trim() || "#d9480f",
  estimate: css.getPropertyValue("--estimate").trim() || "#2f9e44",
  muted: "#8a96a6",
  bound: "#c53030",
};

const charts = new Map();

export function makeChart(el, { series, height = 200, xLabel = "", yLabel = "", opts = {} }) {
  if (charts.has(el)) charts.get(el).destroy();
  el.innerHTML = "";
  const width = Math.max(200, el.clientWidth || el.parentElement.clientWidth || 600);
  const u = new uPlot({
    width, height,
    series: [{ label: xLabel || "x" }, ...series],
    axes: [
      { label: xLabel, stroke: "#5f6b7a", grid: { stroke: "#eef1f5" }, ticks: { stroke: "#dde3ea" } },
      { label: yLabel, stroke: "#5f6b7a", grid: { stroke: "#eef1f5" }, ticks: { stroke: "#dde3ea" }, size: 56 },
    ],
    scales: { x: { time: false } },
    legend: { live: true },
    cursor: { drag: { x: true, y: false, setScale: true } },
    ...opts,
  }, [[], ...series.map(() => [])], el);
  charts.set(el, u);
  return u;
}

export function setData(el, data, resetScales = true) {
  const u = charts.get(el);
  if (u) u.setData(data, resetScales);
}

export function chartOf(el) { return charts.get(el); }

// A y range at least ``span`` wide, so a flat trace sits mid-plot instead of on a 0..100 axis.
export function minSpan(span) {
  return (u, mn, mx) => {
    if (mn === null || mx === null) return [-span / 2, span / 2];
    const pad = Math.max(0, (span - (mx - mn)) / 2) + 0.05 * (mx - mn);
    return [mn - pad, mx + pad];
  };
}

export function line(label, stroke, extra = {}) {
  return { label, stroke, width: 1.6, points: { show: false }, ...extra };
}

export function dots(label, stroke) {
  return { label, stroke, width: 0, points: { show: true, size: 6, stroke, fill: stroke } };
}

export function bars(label, fill) {
  return { label, stroke: fill, fill, width: 1, paths: uPlot.paths.bars({ size: [0.6, 60] }), points: { show: false } };
}

const ro = new ResizeObserver((entries) => {
  for (const e of entries) {
    const u = charts.get(e.target);
    const w = Math.floor(e.contentRect.width);
    if (u && w > 50 && Math.abs(u.width - w) > 2) u.setSize({ width: w, height: u.height });
  }
});
export function watchSize(el) { ro.observe(el); }
