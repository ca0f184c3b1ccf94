// What the dashboard knows: the devices, every parameter's last value, and the numeric samples
// seen since the page opened, with the times there was none (the trend's live part). Fed by GET /api/devices and the
// /api/events stream, whose first events are the full picture.
import { listDevices, getDevice } from "./api.js";
import { parseTime, numericValue } from "./format.js";

// A day at one sample a second per parameter; older samples go first.
const MAX_SAMPLES = 86400;

const devices = new Map();      // name -> { name, device, line, unit, status, profile, error, params: Map }
const details = new Map();      // name -> Promise of GET /api/devices/NAME
const samples = new Map();      // "device\u0000parameter" -> { t: [ms], v: [number, or null for no value] }
const listeners = new Set();
const connectionListeners = new Set();
let connection = "connecting";
let source = null;

function key(device, parameter) {
  return `${device}\u0000${parameter}`;
}

function deviceEntry(name) {
  let entry = devices.get(name);
  if (!entry) {
    entry = { name, status: "", error: "", params: new Map(), time: null };
    devices.set(name, entry);
  }
  return entry;
}

function notify(change) {
  for (const listener of listeners) {
    try { listener(change); } catch (error) { console.error(error); }
  }
}

export function onChange(listener) {
  listeners.add(listener);
  return () => listeners.delete(listener);
}

export function onConnection(listener) {
  connectionListeners.add(listener);
  listener(connection);
  return () => connectionListeners.delete(listener);
}

function setConnection(state) {
  connection = state;
  for (const listener of connectionListeners) listener(state);
}

export function allDevices() {
  return [...devices.values()];
}

export function deviceNamed(name) {
  return devices.get(name);
}

export function parameterValue(device, parameter) {
  return devices.get(device)?.params.get(parameter);
}

export function samplesOf(device, parameter) {
  return samples.get(key(device, parameter)) || { t: [], v: [] };
}

function recordSample(device, parameter, time, value) {
  const k = key(device, parameter);
  let series = samples.get(k);
  if (!series) {
    series = { t: [], v: [] };
    samples.set(k, series);
  }
  const last = series.t.length ? series.t[series.t.length - 1] : -Infinity;
  if (time < last) return;
  if (time === last) {
    series.v[series.v.length - 1] = value;
    return;
  }
  series.t.push(time);
  series.v.push(value);
  if (series.t.length > MAX_SAMPLES) {
    const drop = series.t.length - MAX_SAMPLES;
    series.t.splice(0, drop);
    series.v.splice(0, drop);
  }
}

// Merges one parameter's entry from GET /api/devices/NAME or an event.
function applyParameter(deviceName, update) {
  const device = deviceEntry(deviceName);
  const previous = device.params.get(update.name) || {};
  const merged = { ...previous, ...update };
  if (!merged.unit && previous.unit) merged.unit = previous.unit;
  device.params.set(update.name, merged);
  const number = numericValue(merged);
  // No value (no reply, a special state, line down) is a gap the trend does not draw across.
  const absent = merged.value === null || merged.value === undefined;
  if (merged.time && (number !== null || absent)) recordSample(deviceName, update.name, merged.time, number);
  return merged;
}

export async function loadDevices() {
  const list = await listDevices();
  const rows = Array.isArray(list) ? list : list.devices || [];
  for (const row of rows) {
    const device = deviceEntry(row.name);
    Object.assign(device, row, { params: device.params });
  }
  notify({ kind: "devices" });
  return allDevices();
}

// The device's description and values (cached): its parameters with groups, units, limits.
export function loadDevice(name, { refresh = false } = {}) {
  if (!refresh && details.has(name)) return details.get(name);
  const promise = getDevice(name).then((detail) => {
    const device = deviceEntry(name);
    const { parameters, ...rest } = detail;
    Object.assign(device, rest, { params: device.params });
    device.detail = detail;
    for (const parameter of parameters || []) {
      const time = parseTime(parameter.time) ?? (typeof parameter.age === "number" ? Date.now() - parameter.age * 1000 : null);
      const update = { ...parameter };
      if (time !== null) update.time = time;
      // An event newer than this answer wins over it.
      const known = device.params.get(parameter.name);
      if (known && known.time && update.time && known.time > update.time) {
        device.params.set(parameter.name, { ...update, ...pickLive(known) });
      } else {
        applyParameter(name, update);
      }
    }
    notify({ kind: "device", device: name });
    return device;
  });
  details.set(name, promise);
  promise.catch(() => details.delete(name));
  return promise;
}

function pickLive(entry) {
  const { value, text, status, error, time } = entry;
  return { value, text, status, error, time };
}

function handleEvent(data) {
  if (!data || !data.device) return;
  const time = parseTime(data.time) ?? Date.now();
  // "stale" tells no value: the last one read stays on show, greyed, with the age it really
  // has, and the device's "updated" time stays that of its last poll.
  const stale = data.status === "stale" && (data.value === null || data.value === undefined);
  if (!data.parameter) {
    const device = deviceEntry(data.device);
    device.status = data.status || device.status;
    device.error = data.error || "";
    if (!stale) device.time = time;
    notify({ kind: "status", device: data.device });
    return;
  }
  const device = deviceEntry(data.device);
  const previous = device.params.get(data.parameter);
  const kept = stale && previous && previous.time;
  if (!stale) device.time = time;
  const entry = applyParameter(data.device, {
    name: data.parameter,
    value: kept ? previous.value : data.value ?? null,
    text: kept ? previous.text : data.text ?? "",
    unit: data.unit ?? previous?.unit ?? "",
    status: data.status || "ok",
    error: data.error || "",
    time: kept ? previous.time : time,
  });
  // A stale value stays on show with its real age, but the trend's line ends where it went stale.
  if (kept) recordSample(data.device, data.parameter, time, null);
  notify({ kind: "value", device: data.device, parameter: data.parameter, entry });
}

// One stream for the whole page; the browser reconnects by itself after a drop, and the
// gateway sends the full picture again on each connection.
export function connectEvents() {
  if (source && source.readyState !== EventSource.CLOSED) return;  // one refused before a login is opened again
  source = new EventSource("/api/events");
  source.onopen = () => setConnection("live");
  source.onerror = () => setConnection(source.readyState === EventSource.CLOSED ? "lost" : "connecting");
  const receive = (event) => {
    try { handleEvent(JSON.parse(event.data)); } catch (error) { console.warn("unreadable event", error); }
  };
  source.onmessage = receive;
  for (const name of ["value", "change", "status"]) source.addEventListener(name, receive);
}
