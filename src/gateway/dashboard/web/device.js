// A device page: its key values, a trend, and every parameter grouped as `loopwire describe`
// groups them, live, with a write form on each writable one; above them its recent changes (the
// audit of writes to it, changes.js).
import { loadDevice, deviceNamed, onChange, loadDevices } from "./store.js";
import { writeParameter, listHistoryGateways, canWrite, currentSession } from "./api.js";
import { escapeHtml, readingHtml, ageText, alarmReasons, deviceStatusClass, deviceStatusWord, statusChipClass, valueText } from "./format.js";
import { keyParameters } from "./keys.js";
import { Trend } from "./trend.js";
import { ChangesList } from "./changes.js";
import { openTokenDialog, deviceSubtitle } from "./ui.js";

const RANGES = [["5 min", 300], ["15 min", 900], ["1 h", 3600], ["6 h", 21600], ["24 h", 86400]];
const CHART_ICON = '<svg viewBox="0 0 24 24" aria-hidden="true"><path d="M3 17l5-6 4 4 8-10" fill="none" stroke="currentColor" stroke-width="2" stroke-linecap="round" stroke-linejoin="round"/><path d="M3 21h18" stroke="currentColor" stroke-width="2" stroke-linecap="round"/></svg>';

function chartKey(device) {
  return `loopwire.chart.${device}`;
}

function boundText(bound) {
  if (bound === null || bound === undefined) return "";
  if (typeof bound === "object") return bound.parameter ? bound.parameter.replaceAll("_", " ") : JSON.stringify(bound);
  return String(bound);
}

function rangeText(entry) {
  const low = boundText(entry.min);
  const high = boundText(entry.max);
  // range_counts: the fixed limits are display counts, scaled by the current decimal point.
  const unit = entry.range_counts ? " (display counts)" : entry.unit ? ` ${entry.unit}` : "";
  if (low && high) return `${low} … ${high}${unit}`;
  if (low) return `≥ ${low}${unit}`;
  if (high) return `≤ ${high}${unit}`;
  return "";
}

function labelList(entry) {
  const labels = entry.enum || entry.labels;
  if (!labels) return [];
  if (Array.isArray(labels)) return labels.map((l) => (typeof l === "object" ? l.label ?? l.text ?? l.name : l)).filter(Boolean);
  if (typeof labels === "object") return Object.values(labels);
  return [];
}

function isWritable(entry) {
  return entry.writable === true || entry.access === "rw" || entry.access === "w";
}

// Numbers can be plotted: a value read as a number, or one not read yet that has no labels.
function isNumeric(entry) {
  if (typeof entry.value === "number") return true;
  if (entry.value !== null && entry.value !== undefined) return false;
  return entry.readable !== false && !labelList(entry).length;
}

function groupsOf(device) {
  const groups = new Map();
  for (const entry of device.params.values()) {
    const group = entry.group || "other";
    if (!groups.has(group)) groups.set(group, []);
    groups.get(group).push(entry);
  }
  return groups;
}

function rowHtml(entry, charted) {
  const name = escapeHtml(entry.name);
  const mnemonic = entry.mnemonic ? `<span class="mnemonic">${escapeHtml(entry.mnemonic)}</span>` : "";
  const range = rangeText(entry);
  const chart = isNumeric(entry)
    ? `<button type="button" class="chart-toggle" data-action="chart" aria-pressed="${charted}" title="Show ${name} on the trend">${CHART_ICON}<span class="visually-hidden">Trend ${name}</span></button>`
    : "";
  const write = isWritable(entry) && canWrite() ? `<button type="button" class="button small" data-action="edit" aria-expanded="false">Change</button>` : "";
  return `<tr class="param-row" data-param="${name}">
      <td class="name-cell"><div class="param-name">${escapeHtml(entry.name.replaceAll("_", " "))}${mnemonic}${range ? `<span class="range">${escapeHtml(range)}</span>` : ""}</div></td>
      <td class="value-cell"><span class="param-value"></span></td>
      <td class="status-cell"></td>
      <td class="param-age num"></td>
      <td class="param-actions">${chart}${write}</td>
    </tr>`;
}

function fillRow(row, entry, now) {
  const status = entry.status || "";
  row.dataset.status = entry.time ? status : "";
  const value = row.querySelector(".param-value");
  const html = entry.time || entry.text ? readingHtml(entry) : `<span class="none">${notReadWords(entry)}</span>`;
  if (value.innerHTML !== html) {
    const changed = value.innerHTML !== "";
    value.innerHTML = html;
    if (changed) {
      row.classList.remove("flash");
      void row.offsetWidth;  // restarts the animation
      row.classList.add("flash");
    }
  }
  const reasons = alarmReasons(entry);
  row.dataset.alarm = reasons.length && !(entry.status && entry.status !== "ok") ? "true" : "false";
  const statusCell = row.querySelector(".status-cell");
  const chips = [];
  if (status && status !== "ok" && entry.time) chips.push(`<span class="chip ${statusChipClass(status)}" title="${escapeHtml(entry.error || "")}">${escapeHtml(status)}</span>`);
  for (const reason of reasons) if (!reason.includes(":")) chips.push(`<span class="chip bad">${escapeHtml(reason)}</span>`);
  const chipHtml = chips.join(" ");
  if (statusCell.innerHTML !== chipHtml) statusCell.innerHTML = chipHtml;
  row.querySelector(".param-age").textContent = entry.time ? ageText(entry.time, now) : "";
}

function notReadWords(entry) {
  if (entry.readable === false) return "write-only";
  if (entry.status === "waiting") return "waiting for the first poll";
  if (entry.status && entry.status !== "not-polled" && entry.status !== "ok") return escapeHtml(entry.status);
  return "not polled";
}

function writeFormHtml(entry) {
  const labels = labelList(entry);
  const id = `write-${entry.name}`;
  const current = valueText(entry);
  const control = labels.length
    ? `<select id="${escapeHtml(id)}" name="value">${labels.map((l) => `<option${l === current ? " selected" : ""}>${escapeHtml(l)}</option>`).join("")}</select>`
    : `<input id="${escapeHtml(id)}" name="value" inputmode="decimal" autocomplete="off" value="${escapeHtml(current)}" aria-describedby="${escapeHtml(id)}-hint">`;
  const range = rangeText(entry);
  return `<tr class="write-row" data-write="${escapeHtml(entry.name)}"><td colspan="5">
      <form class="write-form" novalidate>
        <label class="visually-hidden" for="${escapeHtml(id)}">New value of ${escapeHtml(entry.name)}</label>
        ${control}
        <span class="hint" id="${escapeHtml(id)}-hint">${escapeHtml(entry.unit || "")}${range ? ` · ${escapeHtml(range)}` : ""}</span>
        <button type="submit" class="button primary small">Write</button>
        <button type="button" class="button subtle small" data-action="cancel">Cancel</button>
        <div class="write-result" role="status" aria-live="polite"></div>
      </form>
    </td></tr>`;
}

function writtenText(answer, parameter, typed, unit) {
  const written = answer && answer.written;
  let text = typed;
  if (written && typeof written === "object" && parameter in written) {
    const value = written[parameter];
    text = typeof value === "object" && value !== null ? value.text ?? JSON.stringify(value) : String(value);
  }
  return `Written: ${text}${unit && !String(text).endsWith(unit) ? ` ${unit}` : ""}`;
}

// When this gateway forwards its history to a historian that others share, the picker offers
// their histories too: this gateway first (its own history and live values), then the others.
async function offerGateways(picker) {
  const answer = await listHistoryGateways();
  if (!answer || !Array.isArray(answer.gateways)) return;
  const others = answer.gateways.filter((gateway) => gateway !== answer.this);
  if (!others.length) return;
  const own = answer.this ? `${answer.this} (this gateway)` : "this gateway";
  picker.innerHTML = [`<option value="">${escapeHtml(own)}</option>`,
    ...others.map((gateway) => `<option value="${escapeHtml(gateway)}">${escapeHtml(gateway)}</option>`)].join("");
  picker.hidden = false;
}

export function showDevice(view, name) {
  view.innerHTML = `
    <div class="page-head device-head">
      <div>
        <div class="title-row"><h1>${escapeHtml(name)}</h1><span class="pill device-status"></span></div>
        <div class="sub device-sub"></div>
      </div>
    </div>
    <div class="device-error" role="status"></div>
    <section class="device-keys" aria-label="Key values"></section>
    <section class="panel" aria-labelledby="trend-title">
      <div class="panel-head">
        <h2 id="trend-title">Trend</h2>
        <div class="trend-tools">
          <div class="segmented" role="group" aria-label="Time range">
            ${RANGES.map(([label, seconds]) => `<button type="button" data-range="${seconds}" aria-pressed="${seconds === 300}">${label}</button>`).join("")}
          </div>
          <button type="button" class="button small" data-action="live" hidden>Back to live</button>
          <select class="trend-gateway" aria-label="History of gateway" hidden></select>
        </div>
      </div>
      <div class="panel-body">
        <div class="trend-chart" id="trend" aria-label="Trend chart"></div>
        <div class="trend-note" id="trend-note"></div>
      </div>
    </section>
    <section class="panel" aria-labelledby="changes-title">
      <div class="panel-head"><h2 id="changes-title">Changes</h2></div>
      <div class="device-changes"><div class="panel-body"><div class="notice">Loading changes…</div></div></div>
    </section>
    <section class="panel" aria-labelledby="params-title">
      <div class="panel-head">
        <h2 id="params-title">Parameters <span class="count params-count"></span></h2>
        <div class="param-tools"><input class="search" type="search" placeholder="Filter parameters" aria-label="Filter parameters"></div>
      </div>
      <div class="param-groups"><div class="panel-body"><div class="notice">Loading parameters…</div></div></div>
    </section>`;

  const statusPill = view.querySelector(".device-status");
  const sub = view.querySelector(".device-sub");
  const errorLine = view.querySelector(".device-error");
  const keysBox = view.querySelector(".device-keys");
  const groupsBox = view.querySelector(".param-groups");
  const search = view.querySelector(".search");
  const liveButton = view.querySelector('[data-action="live"]');
  const chartBox = view.querySelector("#trend");
  const trend = new Trend(chartBox, view.querySelector("#trend-note"), name);
  const changes = new ChangesList(view.querySelector(".device-changes"), name);
  let charted = null;  // names on the trend, in order
  let closed = false;
  let frame = 0;
  const pending = new Set();

  const rowFor = (param) => groupsBox.querySelector(`tr.param-row[data-param="${CSS.escape(param)}"]`);

  function renderHead(device) {
    statusPill.className = `pill device-status ${deviceStatusClass(device.status)}`;
    statusPill.textContent = deviceStatusWord(device.status);
    sub.textContent = deviceSubtitle(device);
    errorLine.textContent = device.status && device.status !== "ok" ? device.error || "" : "";
  }

  function renderKeys(device) {
    const keys = keyParameters(device);
    keysBox.innerHTML = keys.map(({ label, name: param }) => {
      const entry = device.params.get(param);
      return `<div class="key-value" data-param="${escapeHtml(param)}" data-status="${escapeHtml(entry?.time ? entry.status || "" : "")}">
          <div class="label"><span>${escapeHtml(label || param)}</span><span class="param">${escapeHtml(label ? param.replaceAll("_", " ") : "")}</span></div>
          <div class="reading">${readingHtml(entry)}</div></div>`;
    }).join("");
  }

  function trendParameters(device) {
    return charted.map((param) => {
      const entry = device.params.get(param) || {};
      const key = keyParameters(device).find((k) => k.name === param);
      return { name: param, unit: entry.unit || "", decimals: Number.isInteger(entry.decimals) ? entry.decimals : undefined, label: key?.label || "" };
    });
  }

  function chooseCharted(device) {
    try {
      const stored = JSON.parse(localStorage.getItem(chartKey(name)) || "null");
      if (Array.isArray(stored)) {
        const known = stored.filter((p) => device.params.has(p));
        if (known.length) return known;
      }
    } catch { /* nothing stored */ }
    return keyParameters(device).map((k) => k.name).filter((p) => isNumeric(device.params.get(p) || {}));
  }

  function renderGroups(device) {
    const groups = groupsOf(device);
    view.querySelector(".params-count").textContent = `(${device.params.size})`;
    groupsBox.innerHTML = [...groups].map(([group, entries]) => `
      <details class="group" open data-group="${escapeHtml(group)}">
        <summary>${escapeHtml(group)} <span class="count">${entries.length}</span></summary>
        <table class="params">
          <colgroup><col class="col-name"><col class="col-value"><col class="col-status"><col class="col-age"><col class="col-actions"></colgroup>
          <thead><tr><th>Parameter</th><th>Value</th><th><span class="visually-hidden">Status</span></th><th>Age</th><th><span class="visually-hidden">Actions</span></th></tr></thead>
          <tbody>${entries.map((e) => rowHtml(e, charted.includes(e.name))).join("")}</tbody>
        </table>
      </details>`).join("") || '<div class="panel-body"><div class="notice">This device has no parameters.</div></div>';
    const now = Date.now();
    for (const entry of device.params.values()) {
      const row = rowFor(entry.name);
      if (row) fillRow(row, entry, now);
    }
  }

  function flush() {
    frame = 0;
    const device = deviceNamed(name);
    if (!device) return;
    renderHead(device);
    renderKeys(device);
    const now = Date.now();
    for (const param of pending) {
      const row = rowFor(param);
      const entry = device.params.get(param);
      if (row && entry) fillRow(row, entry, now);
    }
    pending.clear();
    trend.update();
  }

  function schedule(param) {
    if (param) pending.add(param);
    if (!frame) frame = requestAnimationFrame(flush);
  }

  async function openEditor(row) {
    const param = row.dataset.param;
    const existing = groupsBox.querySelector(`tr.write-row[data-write="${CSS.escape(param)}"]`);
    const button = row.querySelector('[data-action="edit"]');
    if (existing) {
      existing.remove();
      button.setAttribute("aria-expanded", "false");
      return;
    }
    const entry = deviceNamed(name).params.get(param);
    row.insertAdjacentHTML("afterend", writeFormHtml(entry));
    button.setAttribute("aria-expanded", "true");
    const editor = row.nextElementSibling;
    const field = editor.querySelector("input, select");
    field.focus();
    if (field.select) field.select();
  }

  async function submitWrite(form) {
    const editor = form.closest("tr.write-row");
    const param = editor.dataset.write;
    const field = form.querySelector("input, select");
    const result = form.querySelector(".write-result");
    const submit = form.querySelector('button[type="submit"]');
    const typed = field.value.trim();
    if (!typed) {
      result.className = "write-result error";
      result.textContent = "Type a value to write.";
      return;
    }
    const entry = deviceNamed(name).params.get(param) || {};
    submit.disabled = true;
    result.className = "write-result";
    result.textContent = "Writing…";
    try {
      const answer = await writeParameter(name, param, typed);
      result.className = "write-result ok";
      result.textContent = writtenText(answer, param, typed, entry.unit);
      changes.written();
    } catch (error) {
      if (error.status !== 401) changes.written();  // a refusal is audited too
      result.className = "write-result error";
      if (error.status === 401 && currentSession() === null && document.getElementById("login-dialog").dataset.users === "true") {
        result.textContent = `Refused: ${error.message}. Log in and write again.`;
        document.getElementById("login-dialog").showModal();
      } else if (error.status === 401) {
        result.textContent = `Refused: ${error.message}. Set the gateway's access token (key button, top right) and write again.`;
        openTokenDialog();
      } else {
        result.textContent = `Refused: ${error.message}`;
      }
    } finally {
      submit.disabled = false;
    }
  }

  groupsBox.addEventListener("click", (event) => {
    const button = event.target.closest("button[data-action]");
    if (!button) return;
    const row = button.closest("tr");
    if (button.dataset.action === "edit") openEditor(row);
    else if (button.dataset.action === "cancel") {
      const paramRow = row.previousElementSibling;
      row.remove();
      paramRow?.querySelector('[data-action="edit"]')?.setAttribute("aria-expanded", "false");
    } else if (button.dataset.action === "chart") {
      const param = row.dataset.param;
      charted = charted.includes(param) ? charted.filter((p) => p !== param) : [...charted, param];
      button.setAttribute("aria-pressed", String(charted.includes(param)));
      try { localStorage.setItem(chartKey(name), JSON.stringify(charted)); } catch { /* this page only */ }
      trend.setParameters(trendParameters(deviceNamed(name)));
    }
  });
  groupsBox.addEventListener("submit", (event) => {
    event.preventDefault();
    submitWrite(event.target);
  });

  view.querySelectorAll("[data-range]").forEach((button) => button.addEventListener("click", () => {
    view.querySelectorAll("[data-range]").forEach((b) => b.setAttribute("aria-pressed", String(b === button)));
    trend.setRange(Number(button.dataset.range));
  }));
  liveButton.addEventListener("click", () => trend.followLive());
  const gatewayPicker = view.querySelector(".trend-gateway");
  gatewayPicker.addEventListener("change", () => trend.setGateway(gatewayPicker.value));
  offerGateways(gatewayPicker);
  const zoomWatch = setInterval(() => { liveButton.hidden = !trend.zoomed; }, 250);

  search.addEventListener("input", () => {
    const words = search.value.trim().toLowerCase();
    for (const group of groupsBox.querySelectorAll(".group")) {
      let shown = 0;
      for (const row of group.querySelectorAll("tr.param-row")) {
        const entry = deviceNamed(name)?.params.get(row.dataset.param) || {};
        const hay = `${entry.name} ${entry.mnemonic || ""} ${group.dataset.group}`.toLowerCase().replaceAll("_", " ");
        const match = !words || hay.includes(words) || (entry.name || "").includes(words);
        row.hidden = !match;
        const editor = row.nextElementSibling;
        if (editor && editor.classList.contains("write-row")) editor.hidden = !match;
        if (match) shown++;
      }
      group.hidden = shown === 0;
    }
  });

  const ready = (device) => {
    if (closed) return;
    renderHead(device);
    renderKeys(device);
    charted = chooseCharted(device);
    renderGroups(device);
    trend.setParameters(trendParameters(device));
  };
  const known = deviceNamed(name);
  const loading = known ? Promise.resolve() : loadDevices();
  loading.then(() => loadDevice(name, { refresh: true })).then(ready).catch((error) => {
    if (closed) return;
    const message = error.status === 404 ? `The gateway has no device named "${name}".` : `Could not load ${name}: ${error.message}`;
    groupsBox.innerHTML = `<div class="panel-body"><div class="notice error">${escapeHtml(message)}</div></div>`;
    errorLine.textContent = message;
  });

  const stop = onChange((change) => {
    if (change.device !== name || !charted) return;
    if (change.kind === "value") schedule(change.parameter);
    else schedule(null);
  });
  const ticker = setInterval(() => {
    const device = deviceNamed(name);
    if (!device || !charted) return;
    const now = Date.now();
    for (const row of groupsBox.querySelectorAll("tr.param-row")) {
      const entry = device.params.get(row.dataset.param);
      if (entry?.time) row.querySelector(".param-age").textContent = ageText(entry.time, now);
    }
    trend.update();  // the window slides even between samples
  }, 1000);

  return () => {
    closed = true;
    stop();
    clearInterval(ticker);
    clearInterval(zoomWatch);
    if (frame) cancelAnimationFrame(frame);
    trend.destroy();
    changes.destroy();
  };
}
