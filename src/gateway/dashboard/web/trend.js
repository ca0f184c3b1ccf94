// A device's trend: uPlot over the values seen live since the page opened, preceded by the
// gateway's recorded history when it keeps one. Drag to zoom, double-click (or "Live") to go
// back to following the process; the range buttons choose how far back the window reaches.
import { getHistory } from "./api.js";
import { samplesOf } from "./store.js";
import { currentTheme } from "./ui.js";

const PALETTE = ["--series-1", "--series-2", "--series-3", "--series-4", "--series-5", "--series-6"];
const HISTORY_POINTS = 600;

function cssVar(name) {
  return getComputedStyle(document.documentElement).getPropertyValue(name).trim();
}

function formatNumber(value, decimals) {
  if (value === null || value === undefined || Number.isNaN(value)) return "—";
  return Number.isInteger(decimals) ? value.toFixed(decimals) : String(Math.round(value * 1000) / 1000);
}

// History answers come as a list of series, or wrapped in {series: [...]}.
function seriesList(answer) {
  if (!answer) return [];
  if (Array.isArray(answer)) return answer;
  if (Array.isArray(answer.series)) return answer.series;
  return [];
}

function bucketTime(bucket) {
  const start = bucket.time ?? bucket.start;
  if (typeof start === "number") return start > 1e12 ? start : start * 1000;
  return Date.parse(start);
}

// A recorded series as points in time order: each bucket's mean, and a null where each gap
// begins (a time without a value: no reply, a special state). A bucket that starts inside a gap
// takes its point where the gap ends, so no value is drawn inside it. The series' `before`, the
// value in force at the query's `from` (recorded before it), is a point at its own time, so the
// line starts at the window's left edge (windowColumn); it is left out when a bucket starts no
// later (a wide bucket, rounded down to its minute, already starts the line). Without one, or
// with a gap open at `from`, the line starts at the first point, or stays broken.
export function historyPoints(series) {
  const gaps = (series.gaps || []).map((gap) => ({ from: Date.parse(gap.from), to: gap.to ? Date.parse(gap.to) : Infinity }));
  const points = [];
  for (const bucket of series.buckets || []) {
    let time = bucketTime(bucket);
    if (!Number.isFinite(time) || typeof bucket.mean !== "number") continue;
    const inside = gaps.find((gap) => time >= gap.from && time < gap.to);
    if (inside) {
      if (!Number.isFinite(inside.to)) continue;
      time = inside.to;
    }
    points.push([time, bucket.mean]);
  }
  const before = series.before;
  if (before && typeof before.value === "number") {
    const time = bucketTime(before);
    if (Number.isFinite(time) && !points.some((p) => p[0] <= time)) points.push([time, before.value]);
  }
  for (const gap of gaps) if (Number.isFinite(gap.from)) points.push([gap.from, null]);
  // At one time a value wins over a gap's start: the value is what came after it.
  points.sort((a, b) => a[0] - b[0] || (a[1] === null) - (b[1] === null));
  return { t: points.map((p) => p[0]), v: points.map((p) => p[1]) };
}

// The columns uPlot draws, from each parameter's points (Map time -> value or null): one row
// per time any of them has, and `now`. Values are recorded on change, so a parameter's value
// holds until its next point: each column carries its last value forward (a null, a gap, too).
export function alignColumns(columns, now) {
  const times = [...new Set(columns.flatMap((c) => [...c.keys()]))].filter((t) => t <= now);
  times.push(now);
  const sorted = [...new Set(times)].sort((a, b) => a - b);
  const aligned = columns.map((column) => {
    let last = null;
    return sorted.map((t) => {
      if (column.has(t)) last = column.get(t);
      return last;
    });
  });
  return [sorted, aligned];
}

// One parameter's points in the window from `from` on (Map time -> value or null): the recorded
// ones (`past`, historyPoints) up to the first live one, then the live ones. The value in force
// at the window's start (the last point before it, recorded or live: a value, or a gap's null)
// is its first point, at `from`, so a value that held since before the window is drawn from
// its left edge, and a gap open there stays a gap.
export function windowColumn(past, live, from) {
  const firstLive = live.t.length ? live.t[0] : Infinity;
  const points = new Map();
  let before;
  for (let i = 0; i < past.t.length && past.t[i] < from; i++) before = past.v[i];
  for (let i = 0; i < live.t.length && live.t[i] < from; i++) before = live.v[i];
  if (before !== undefined) points.set(from, before);
  for (let i = 0; i < past.t.length; i++) if (past.t[i] >= from && past.t[i] < firstLive) points.set(past.t[i], past.v[i]);
  for (let i = 0; i < live.t.length; i++) if (live.t[i] >= from) points.set(live.t[i], live.v[i]);
  return points;
}

export class Trend {
  constructor(container, note, deviceName) {
    this.container = container;
    this.note = note;
    this.device = deviceName;
    this.parameters = [];       // [{ name, unit, decimals, label }]
    this.rangeSeconds = 5 * 60;
    this.zoomed = false;
    this.gateway = "";          // whose history: "" this gateway's, or another's from the historian
    this.history = new Map();   // parameter -> { t: [ms], v: [] }
    this.historyState = "unknown";
    this.plot = null;
    this.frame = 0;
    this.historyRequest = 0;
    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(container);
    this.onTheme = () => this.rebuild();
    window.addEventListener("themechange", this.onTheme);
  }

  destroy() {
    this.resizeObserver.disconnect();
    window.removeEventListener("themechange", this.onTheme);
    if (this.frame) cancelAnimationFrame(this.frame);
    if (this.plot) this.plot.destroy();
    this.plot = null;
  }

  setParameters(parameters) {
    const before = this.parameters.map((p) => p.name).join(",");
    this.parameters = parameters;
    if (parameters.map((p) => p.name).join(",") !== before) {
      this.rebuild();
      this.loadHistory();
    }
  }

  setRange(seconds) {
    this.rangeSeconds = seconds;
    this.zoomed = false;
    this.loadHistory();
    this.update();
  }

  // Another gateway's history (its device of the same name), or "" for this one's. The live
  // values are this gateway's, so they join only this gateway's history.
  setGateway(gateway) {
    this.gateway = gateway;
    this.loadHistory();
    this.update();
  }

  followLive() {
    this.zoomed = false;
    this.update();
  }

  async loadHistory() {
    const request = ++this.historyRequest;
    const names = this.parameters.map((p) => p.name);
    if (!names.length) return;
    const to = new Date();
    const from = new Date(to.getTime() - this.rangeSeconds * 1000);
    try {
      const answer = await getHistory(this.device, names, from, to, HISTORY_POINTS, this.gateway);
      if (request !== this.historyRequest) return;
      this.history.clear();
      if (answer === null) {
        this.historyState = "absent";
      } else {
        this.historyState = "loaded";
        for (const series of seriesList(answer)) this.history.set(series.parameter, historyPoints(series));
      }
    } catch (error) {
      if (request !== this.historyRequest) return;
      this.historyState = `failed: ${error.message}`;
    }
    this.describe();
    this.update();
  }

  describe() {
    if (!this.note) return;
    if (this.historyState === "absent") this.note.textContent = "No history is recorded: the trend shows the values received since this page opened.";
    else if (this.historyState === "loaded" && this.gateway) this.note.textContent = `Recorded history of gateway ${this.gateway} (no live values: they are this gateway's).`;
    else if (this.historyState === "loaded") this.note.textContent = "Recorded history, then live values.";
    else if (this.historyState.startsWith("failed")) this.note.textContent = `History could not be loaded (${this.historyState.slice(8)}): live values only.`;
    else this.note.textContent = "";
  }

  // The aligned columns uPlot draws: times in seconds, then one column per parameter.
  data() {
    const now = Date.now();
    const from = now - this.rangeSeconds * 1000;
    const columns = this.parameters.map((p) => {
      const live = this.gateway ? { t: [], v: [] } : samplesOf(this.device, p.name);
      const past = this.history.get(p.name) || { t: [], v: [] };
      return windowColumn(past, live, from);
    });
    if (!columns.some((c) => c.size)) return [[], ...columns.map(() => [])];
    // The newest point received (the columns reach on to now, where nothing was received).
    this.lastSample = Math.max(...columns.flatMap((c) => [...c.keys()]));
    const [times, aligned] = alignColumns(columns, now);
    return [times.map((t) => t / 1000), ...aligned];
  }

  height() {
    return window.matchMedia("(max-width: 640px)").matches ? 220 : 300;
  }

  rebuild() {
    if (this.plot) this.plot.destroy();
    this.plot = null;
    this.container.innerHTML = "";
    if (!this.parameters.length) {
      this.container.innerHTML = '<div class="trend-empty">Choose parameters to plot with the chart buttons below.</div>';
      return;
    }
    if (typeof window.uPlot !== "function") {
      this.container.innerHTML = '<div class="trend-empty">The chart library did not load.</div>';
      return;
    }
    const text = cssVar("--text-2");
    const grid = cssVar("--grid");
    const units = [...new Set(this.parameters.map((p) => p.unit || ""))];
    const scales = { x: { time: true } };
    for (const unit of units) scales[unit || "value"] = { auto: true };
    const axis = (unit, side) => ({
      scale: unit || "value",
      side,
      label: unit || undefined,
      labelSize: unit ? 18 : 0,
      stroke: text,
      grid: { stroke: grid, width: 1, show: side === 3 },
      ticks: { stroke: grid, width: 1 },
      size: 56,
    });
    const axes = [{ stroke: text, grid: { stroke: grid, width: 1 }, ticks: { stroke: grid, width: 1 } }];
    units.slice(0, 2).forEach((unit, i) => axes.push(axis(unit, i === 0 ? 3 : 1)));
    const series = [{}];
    this.parameters.forEach((p, i) => {
      series.push({
        label: p.label ? `${p.label} (${p.name})` : p.name,
        scale: p.unit || "value",
        stroke: cssVar(PALETTE[i % PALETTE.length]),
        width: 2,
        // Steps, not slopes: a value recorded on change held until the next one; and no line
        // across a gap (a null), where the device gave no value.
        spanGaps: false,
        paths: window.uPlot.paths?.stepped ? window.uPlot.paths.stepped({ align: 1 }) : undefined,
        points: { show: false },
        value: (u, v) => (v === null || v === undefined ? "—" : `${formatNumber(v, p.decimals)}${p.unit ? ` ${p.unit}` : ""}`),
      });
    });
    const trend = this;
    const options = {
      width: Math.max(200, this.container.clientWidth),
      height: this.height(),
      scales,
      axes,
      series,
      legend: { live: true },
      cursor: {
        drag: { x: true, y: false, setScale: true },
        bind: {
          dblclick: () => () => { trend.followLive(); return null; },
        },
      },
      hooks: {
        setSelect: [(u) => { if (u.select.width > 0) trend.zoomed = true; }],
      },
    };
    this.plot = new window.uPlot(options, this.data(), this.container);
    this.container.dataset.theme = currentTheme();
    this.update();
  }

  resize() {
    if (!this.plot) return;
    const width = Math.max(200, this.container.clientWidth);
    if (width !== this.plot.width || this.height() !== this.plot.height) this.plot.setSize({ width, height: this.height() });
  }

  // Redraws on the next frame: many events of one poll become one redraw.
  update() {
    if (this.frame) return;
    this.frame = requestAnimationFrame(() => {
      this.frame = 0;
      this.draw();
    });
  }

  draw() {
    if (!this.plot) return;
    const data = this.data();
    this.plot.setData(data, false);
    if (!this.zoomed) {
      const now = Date.now() / 1000;
      this.plot.setScale("x", { min: now - this.rangeSeconds, max: now });
    }
    const times = data[0];
    this.container.dataset.points = String(times.length);
    this.container.dataset.lastTime = times.length ? String(this.lastSample / 1000) : "";
    this.container.dataset.lastValues = data.slice(1).map((column) => {
      for (let i = column.length - 1; i >= 0; i--) if (column[i] !== null) return column[i];
      return "";
    }).join(",");
    this.container.dataset.zoomed = String(this.zoomed);
    // The parameters drawn, in the order of the columns below, for tests and tools.
    this.container.dataset.series = this.parameters.map((p) => p.name).join(",");
    // Where each column's line breaks (a run of nulls after a value), for tests and tools.
    this.container.dataset.gaps = data.slice(1).map((column) => {
      let gaps = 0;
      for (let i = 1; i < column.length; i++) if (column[i] === null && column[i - 1] !== null) gaps++;
      return gaps;
    }).join(",");
  }
}
