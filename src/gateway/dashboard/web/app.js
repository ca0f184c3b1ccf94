// The dashboard's shell: the theme toggle, the token dialog, the live indicator, and a hash
// router between the overview (#/) and a device page (#/devices/NAME).
import { storedToken, storeToken } from "./api.js";
import { connectEvents, onConnection } from "./store.js";
import { showOverview } from "./overview.js";
import { showDevice } from "./device.js";
import { escapeHtml } from "./format.js";
import { currentTheme, openTokenDialog } from "./ui.js";

const view = document.getElementById("view");
const crumbs = document.getElementById("crumbs");
let leaveView = null;

function setupTheme() {
  document.getElementById("theme-button").addEventListener("click", () => {
    const next = currentTheme() === "dark" ? "light" : "dark";
    document.documentElement.dataset.theme = next;
    try { localStorage.setItem("loopwire.theme", next); } catch { /* this page only */ }
    window.dispatchEvent(new CustomEvent("themechange"));
  });
  window.matchMedia("(prefers-color-scheme: dark)").addEventListener("change", () => {
    if (!document.documentElement.dataset.theme) window.dispatchEvent(new CustomEvent("themechange"));
  });
}

function setupToken() {
  const button = document.getElementById("token-button");
  const dialog = document.getElementById("token-dialog");
  const input = document.getElementById("token-input");
  const mark = () => { button.dataset.set = storedToken() ? "true" : "false"; };
  mark();
  button.addEventListener("click", openTokenDialog);
  document.getElementById("token-form").addEventListener("submit", () => { storeToken(input.value.trim()); mark(); });
  document.getElementById("token-clear").addEventListener("click", () => { storeToken(""); input.value = ""; mark(); dialog.close(); });
}

function setupLive() {
  const live = document.getElementById("live");
  const text = live.querySelector(".live-text");
  onConnection((state) => {
    live.dataset.state = state;
    text.textContent = { live: "live", connecting: "connecting", lost: "disconnected" }[state] || state;
    live.title = state === "live" ? "Receiving live values" : "Waiting for the gateway's live values";
  });
}

function setCrumbs(parts) {
  crumbs.innerHTML = parts.map((part, i) => {
    const sep = i ? '<span class="sep">/</span>' : "";
    return part.href ? `${sep}<a href="${part.href}">${escapeHtml(part.text)}</a>` : `${sep}<span class="here">${escapeHtml(part.text)}</span>`;
  }).join("");
}

function route() {
  if (leaveView) leaveView();
  leaveView = null;
  view.innerHTML = "";
  const hash = decodeURIComponent(location.hash.replace(/^#/, ""));
  const match = hash.match(/^\/devices\/(.+)$/);
  if (match) {
    const name = match[1];
    setCrumbs([{ text: "Devices", href: "#/" }, { text: name }]);
    document.title = `${name} · loopwire gateway`;
    leaveView = showDevice(view, name);
  } else {
    setCrumbs([{ text: "Devices" }]);
    document.title = "loopwire gateway";
    leaveView = showOverview(view);
  }
  window.scrollTo(0, 0);
}

setupTheme();
setupToken();
setupLive();
connectEvents();
window.addEventListener("hashchange", route);
route();
