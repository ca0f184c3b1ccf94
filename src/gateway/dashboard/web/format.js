// How values read: numbers with the parameter's decimals and always their unit, ages in words,
// and which values make an alarm.

export function escapeHtml(text) {
  return String(text ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}

// The value's text as the gateway wrote it (it knows decimals and labels); a number formatted
// here only when no text came.
export function valueText(entry) {
  if (!entry) return "";
  if (entry.text !== undefined && entry.text !== null && entry.text !== "") return String(entry.text);
  const v = entry.value;
  if (v === null || v === undefined) return "";
  if (typeof v === "number") {
    const decimals = Number.isInteger(entry.decimals) ? entry.decimals : undefined;
    return decimals === undefined ? String(v) : v.toFixed(decimals);
  }
  if (typeof v === "object") {
    const on = Object.entries(v).filter(([, bit]) => bit).map(([name]) => name);
    return on.length ? on.join("+") : "none";
  }
  return String(v);
}

// "ok" and "unknown-label" are values to show; anything else ("under-range", "no-reply", ...)
// is a state that replaces or qualifies the value.
export function isSpecialStatus(status) {
  return Boolean(status) && status !== "ok";
}

// HTML for a value with its unit: "137.0 °C"; the status word when there is no value.
export function readingHtml(entry, { emptyText = "—" } = {}) {
  const text = valueText(entry);
  if (!text) {
    const word = entry && entry.status && entry.status !== "ok" ? entry.status : emptyText;
    return `<span class="none">${escapeHtml(word)}</span>`;
  }
  const unit = entry.unit ? `<span class="unit">${escapeHtml(entry.unit)}</span>` : "";
  return `<span class="num">${escapeHtml(text)}</span>${unit}`;
}

export function ageText(time, now = Date.now()) {
  if (!time) return "";
  const seconds = Math.max(0, Math.round((now - time) / 1000));
  if (seconds < 2) return "just now";
  if (seconds < 60) return `${seconds} s ago`;
  const minutes = Math.round(seconds / 60);
  if (minutes < 60) return `${minutes} min ago`;
  const hours = Math.round(minutes / 60);
  if (hours < 48) return `${hours} h ago`;
  return `${Math.round(hours / 24)} d ago`;
}

// A time from the API: ISO text, or seconds or milliseconds since the epoch.
export function parseTime(time) {
  if (time === undefined || time === null || time === "") return null;
  if (typeof time === "number") return time > 1e12 ? time : time * 1000;
  const parsed = Date.parse(time);
  return Number.isNaN(parsed) ? null : parsed;
}

// Statuses that say nothing is wrong with the value itself (or that it was not read at all).
const QUIET_STATUSES = ["ok", "unknown-label", "no-reply", "line-down", "error", "waiting", "not-polled", "stale", ""];

const ALARM_WORDS = /alarm|error|fail|fault|break|overload|trip/i;

// Why a parameter's value is an alarm, or "" when it is not one: a bit-field bit named like an
// alarm that is on, an alarm parameter whose label says on, or a special state such as
// out-of-range.
export function alarmReasons(entry) {
  if (!entry) return [];
  const reasons = [];
  const v = entry.value;
  if (v && typeof v === "object") {
    for (const [bit, on] of Object.entries(v)) if (on && ALARM_WORDS.test(bit)) reasons.push(bit.replaceAll("_", " "));
  } else if (typeof v === "string" && ALARM_WORDS.test(entry.name || "") && /^(on|active|alarm|yes|tripped)$/i.test(v)) {
    reasons.push((entry.name || "").replaceAll("_", " "));
  }
  if (entry.status && !QUIET_STATUSES.includes(entry.status)) {
    reasons.push(`${(entry.name || "").replaceAll("_", " ")}: ${entry.status}`);
  }
  return reasons;
}

// "stale": the device's poll is overdue, so its last values may no longer be its own (the
// gateway's value cache says so once the poll is two intervals late); shown apart from both
// "ok" and the failures, greyed, with the last values kept and their age growing.
export function deviceStatusClass(status) {
  if (status === "ok") return "ok";
  if (status === "partial") return "warn";
  if (status === "stale") return "stale";
  if (!status || status === "waiting") return "";
  return "bad";
}

export function deviceStatusWord(status) {
  if (status === "ok") return "online";
  if (status === "no-reply") return "offline";
  if (status === "line-down") return "line down";
  if (status === "partial") return "partial";
  if (status === "stale") return "stale: not polled";
  if (status === "wrong-device") return "wrong device";
  return status || "waiting";
}

// The chip of a value's status: failures red, stale grey, special states amber.
export function statusChipClass(status) {
  if (status === "no-reply" || status === "line-down" || status === "error") return "bad";
  if (status === "stale") return "stale";
  return "warn";
}

export function numericValue(entry) {
  return entry && typeof entry.value === "number" && Number.isFinite(entry.value) ? entry.value : null;
}
