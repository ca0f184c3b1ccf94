// The overview: one card per device with its status, its key values with units and its alarms.
import { loadDevices, loadDevice, allDevices, deviceNamed, onChange } from "./store.js";
import { escapeHtml, readingHtml, ageText, alarmReasons, deviceStatusClass, deviceStatusWord } from "./format.js";
import { keyParameters } from "./keys.js";
import { deviceSubtitle } from "./ui.js";

function cardHtml(device) {
  const href = `#/devices/${encodeURIComponent(device.name)}`;
  const model = deviceSubtitle(device);
  return `
  <article class="card" data-device="${escapeHtml(device.name)}" aria-labelledby="card-${escapeHtml(device.name)}">
    <div class="card-head">
      <div>
        <h2 class="card-title" id="card-${escapeHtml(device.name)}"><a href="${href}">${escapeHtml(device.name)}</a></h2>
        <div class="card-sub">${escapeHtml(model)}</div>
      </div>
      <span class="pill device-status"></span>
    </div>
    <div class="card-body">
      <div class="key-values"></div>
      <div class="alarms" aria-label="Alarms"></div>
      <div class="card-error" role="status"></div>
    </div>
    <div class="card-foot"><span class="card-age num"></span><a href="${href}">Details →</a></div>
  </article>`;
}

function renderCard(card, device) {
  const status = card.querySelector(".device-status");
  status.className = `pill device-status ${deviceStatusClass(device.status)}`;
  status.textContent = deviceStatusWord(device.status);

  const keys = keyParameters(device);
  const tiles = card.querySelector(".key-values");
  tiles.innerHTML = keys.length
    ? keys.map(({ label, name }) => {
      const entry = device.params.get(name);
      return `<div class="key-value" data-param="${escapeHtml(name)}" data-status="${escapeHtml(entry?.time ? entry.status || "" : "")}">
          <div class="label"><span>${escapeHtml(label || name)}</span><span class="param" title="${escapeHtml(name)}">${escapeHtml(label ? name.replaceAll("_", " ") : "")}</span></div>
          <div class="reading">${readingHtml(entry)}</div>
        </div>`;
    }).join("")
    : '<div class="key-value"><div class="label"><span>Values</span></div><div class="reading"><span class="none">waiting for the first poll</span></div></div>';

  const alarms = [];
  if (device.status && device.status !== "ok") {
    alarms.push({ text: deviceStatusWord(device.status), level: device.status === "stale" ? "stale" : "bad" });
  }
  for (const entry of device.params.values()) {
    for (const reason of alarmReasons(entry)) alarms.push({ text: reason, level: entry.status && entry.status !== "ok" ? "warn" : "bad" });
  }
  card.querySelector(".alarms").innerHTML = alarms.slice(0, 8)
    .map((a) => `<span class="chip ${a.level}">${escapeHtml(a.text)}</span>`).join("")
    + (alarms.length > 8 ? `<span class="chip">+${alarms.length - 8} more</span>` : "");
  card.dataset.alarm = alarms.length ? "true" : "false";
  card.querySelector(".card-error").textContent = device.status !== "ok" ? device.error || "" : "";
  updateAge(card, device);
}

function updateAge(card, device) {
  const age = card.querySelector(".card-age");
  age.textContent = device.time ? `updated ${ageText(device.time)}` : "no sample yet";
}

function summaryHtml(devices, alarmed) {
  const online = devices.filter((d) => d.status === "ok").length;
  return `<span class="pill ok">${online} of ${devices.length} online</span>`
    + (alarmed ? `<span class="pill bad">${alarmed} with alarms</span>` : "");
}

export function showOverview(view) {
  view.innerHTML = `
    <div class="page-head">
      <div><h1>Devices</h1><div class="sub">Every controller the gateway polls, live.</div></div>
      <div class="summary" id="summary"></div>
    </div>
    <section class="cards" id="cards" aria-label="Devices"><div class="notice">Loading devices…</div></section>`;
  const cards = view.querySelector("#cards");
  const summary = view.querySelector("#summary");
  const pending = new Set();
  let frame = 0;
  let closed = false;

  const cardFor = (name) => cards.querySelector(`.card[data-device="${CSS.escape(name)}"]`);
  const flush = () => {
    frame = 0;
    for (const name of pending) {
      const card = cardFor(name);
      const device = deviceNamed(name);
      if (card && device) renderCard(card, device);
    }
    pending.clear();
    summary.innerHTML = summaryHtml(allDevices(), cards.querySelectorAll(".card[data-alarm=\"true\"]").length);
  };
  const schedule = (name) => {
    pending.add(name);
    if (!frame) frame = requestAnimationFrame(flush);
  };

  const build = () => {
    const devices = allDevices();
    if (!devices.length) {
      cards.innerHTML = '<div class="notice">The gateway serves no devices: add some under [[lines.devices]] in its configuration.</div>';
      return;
    }
    cards.innerHTML = devices.map(cardHtml).join("");
    for (const device of devices) {
      renderCard(cardFor(device.name), device);
      loadDevice(device.name).then(() => !closed && schedule(device.name)).catch(() => {});
    }
    summary.innerHTML = summaryHtml(devices, cards.querySelectorAll(".card[data-alarm=\"true\"]").length);
  };

  loadDevices().then(() => { if (!closed) build(); }).catch((error) => {
    if (!closed) cards.innerHTML = `<div class="notice error">Could not list the devices: ${escapeHtml(error.message)}</div>`;
  });

  const stop = onChange((change) => {
    if (change.kind === "devices") return;
    if (change.device) schedule(change.device);
  });
  const ticker = setInterval(() => {
    for (const device of allDevices()) {
      const card = cardFor(device.name);
      if (card) updateAge(card, device);
    }
  }, 1000);
  return () => {
    closed = true;
    stop();
    clearInterval(ticker);
    if (frame) cancelAnimationFrame(frame);
  };
}
