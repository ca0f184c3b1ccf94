// A device page's "Changes": the device's recent rows of the audit of writes (GET /api/audit),
// newest first: when, who (the front and its peer), the parameter, old → new and the outcome.
// Asked again after each write from this page and every few seconds, so a write through MQTT,
// Sparkplug or the Modbus TCP front shows too. Without [history] the gateway keeps no audit
// rows (404): the list says so once and is asked no more.
import { getJson } from "./api.js";
import { escapeHtml, ageText, parseTime } from "./format.js";

const SHOWN = 10;  // the last few: GET /api/audit and `loopwire audit` have them all
const REFRESH_MS = 5000;

function whoText(record) {
  const user = record.user ? ` (${record.user})` : "";
  return `${record.front}${record.peer ? ` ${record.peer}` : ""}${user}`;
}

function whatText(record) {
  // A raw Modbus write names registers and has no old value: "function 6 address 717 count 1 = 1600".
  if (record.parameter.startsWith("function ")) return { parameter: record.parameter, change: `= ${record.new_value}` };
  return { parameter: record.parameter.replaceAll("_", " "), change: `${record.old_value || "?"} → ${record.new_value}` };
}

function rowHtml(record, now) {
  const time = parseTime(record.time);
  const { parameter, change } = whatText(record);
  const refused = record.outcome !== "confirmed";
  return `<tr class="change-row" data-outcome="${refused ? "refused" : "confirmed"}">
      <td class="change-time num" title="${escapeHtml(record.time)}">${escapeHtml(ageText(time, now))}</td>
      <td class="change-who">${escapeHtml(whoText(record))}</td>
      <td class="change-parameter">${escapeHtml(parameter)}</td>
      <td class="change-values">${escapeHtml(change)}</td>
      <td class="change-outcome"><span class="chip ${refused ? "bad" : "ok"}">${escapeHtml(record.outcome)}</span></td>
    </tr>`;
}

export class ChangesList {
  constructor(box, device) {
    this.box = box;
    this.device = device;
    this.records = [];
    this.kept = true;  // false: the gateway keeps no audit (no [history])
    this.asking = null;
    this.timer = setInterval(() => this.refresh(), REFRESH_MS);
    this.refresh();
  }

  async refresh() {
    if (!this.kept || this.asking) return this.asking;
    const query = new URLSearchParams({ device: this.device, from: "-24h", limit: String(SHOWN) });
    this.asking = getJson(`/api/audit?${query}`).then((answer) => {
      this.records = Array.isArray(answer.records) ? answer.records : [];
      this.render();
    }).catch((error) => {
      if (error.status === 404) this.kept = false;
      this.box.innerHTML = `<div class="notice">${escapeHtml(error.status === 404
        ? "Changes are kept with the history: add a [history] table to the gateway's configuration."
        : `Could not load the changes: ${error.message}`)}</div>`;
    }).finally(() => { this.asking = null; });
    return this.asking;
  }

  // After a write from this page: its row is in the history file within a second (the store
  // commits every 0.5 s), so the list is asked again until it has one more row, a few times.
  async written() {
    const before = this.records[0]?.time;
    for (let i = 0; i < 6 && this.kept; i++) {
      await this.refresh();
      if (this.records[0]?.time !== before) return;
      await new Promise((resolve) => setTimeout(resolve, 500));
    }
  }

  render() {
    if (!this.records.length) {
      this.box.innerHTML = '<div class="notice">No writes to this device in the last 24 hours.</div>';
      return;
    }
    const now = Date.now();
    this.box.innerHTML = `<table class="changes">
        <colgroup><col class="col-time"><col class="col-who"><col class="col-parameter"><col class="col-values"><col class="col-outcome"></colgroup>
        <thead><tr><th>When</th><th>Who</th><th>Parameter</th><th>Old → new</th><th>Outcome</th></tr></thead>
        <tbody>${this.records.map((record) => rowHtml(record, now)).join("")}</tbody>
      </table>`;
  }

  destroy() {
    clearInterval(this.timer);
    this.kept = false;
  }
}
