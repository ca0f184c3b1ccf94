// The dashboard's shell: the theme toggle, the token dialog, the live indicator, and a hash
// router between the overview (#/) and a device page (#/devices/NAME).
import { storedToken, storeToken, loadSession, login, logout, onUnauthorized } from "./api.js";
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

// The login: the user and a logout in the header; the dialog when the API answers 401 and the
// gateway has users. After a login or logout the view is drawn again (write controls follow the
// role).
function showUser(session) {
  const user = document.getElementById("user");
  const loginButton = document.getElementById("login-button");
  const dialog = document.getElementById("login-dialog");
  user.hidden = !(session && session.user);
  loginButton.hidden = !(dialog.dataset.users === "true" && !(session && session.user));
  if (session && session.user) {
    document.getElementById("user-name").textContent = session.user;
    document.getElementById("user-role").textContent = session.role;
  }
}

async function setupSession() {
  const dialog = document.getElementById("login-dialog");
  const error = document.getElementById("login-error");
  const openLogin = () => {
    if (dialog.dataset.users !== "true" || dialog.open) return;
    error.textContent = "";
    dialog.showModal();
    document.getElementById("login-user").focus();
  };
  document.getElementById("login-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    try {
      const session = await login(document.getElementById("login-user").value, document.getElementById("login-password").value);
      document.getElementById("login-password").value = "";
      dialog.close();
      showUser(session);
      connectEvents();
      route();
    } catch (failure) {
      error.textContent = failure.message;
    }
  });
  document.getElementById("logout-button").addEventListener("click", async () => {
    await logout();
    showUser(null);
    route();
    const state = await loadSession().catch(() => null);
    if (state && state.none && !state.openReads) openLogin();
  });
  document.getElementById("login-button").addEventListener("click", openLogin);
  onUnauthorized(openLogin);
  let state = null;
  try { state = await loadSession(); } catch { /* the gateway did not answer: the views say so */ }
  dialog.dataset.users = state ? "true" : "false";
  showUser(state);
  if (state && state.none && !state.openReads) openLogin();
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
window.addEventListener("hashchange", route);
// The session first: a view drawn before it would show write controls a viewer does not have.
setupSession().finally(() => {
  connectEvents();
  route();
});
