// The gateway's HTTP API as the dashboard uses it: JSON reads, the login session, writes with
// the session's CSRF token or the bearer token kept in this browser, and the history query
// (absent when the gateway records no history).

const TOKEN_KEY = "loopwire.token";

// The login this browser holds ({ user, role, csrf }), null when none: the gateway has no users
// (GET /api/session answers 404) or nobody logged in. The session itself is an HttpOnly cookie
// the page never sees; the CSRF token goes with every write, which a page of another site
// cannot read and so cannot send.
let session = null;
const unauthorizedListeners = new Set();

export function currentSession() { return session; }

// Whether this browser may try writes: everyone but a logged-in viewer (the gateway decides).
export function canWrite() { return !session || session.role !== "viewer"; }

// Called with no arguments whenever the API answers 401 (the login dialog opens).
export function onUnauthorized(listener) { unauthorizedListeners.add(listener); }

// GET /api/session: { user, role, csrf }, or { none: true, openReads } when nobody is logged in,
// or null when the gateway has no users.
export async function loadSession() {
  const response = await fetch("/api/session", { headers: { Accept: "application/json" }, cache: "no-store" });
  if (response.status === 404) { session = null; return null; }
  const body = await response.json().catch(() => ({}));
  if (!response.ok) { session = null; return { none: true, openReads: body.open_reads === true }; }
  session = body;
  return session;
}

export async function login(user, password) {
  const response = await fetch("/api/login", {
    method: "POST", headers: { "Content-Type": "application/json", Accept: "application/json" },
    body: JSON.stringify({ user, password }),
  });
  if (!response.ok) throw new ApiError(response.status, await errorWords(response));
  session = await response.json();
  return session;
}

export async function logout() {
  const headers = { Accept: "application/json" };
  if (session && session.csrf) headers["X-CSRF-Token"] = session.csrf;
  await fetch("/api/logout", { method: "POST", headers }).catch(() => {});
  session = null;
}

export function storedToken() {
  try { return localStorage.getItem(TOKEN_KEY) || ""; } catch { return ""; }
}

export function storeToken(token) {
  try {
    if (token) localStorage.setItem(TOKEN_KEY, token);
    else localStorage.removeItem(TOKEN_KEY);
  } catch { /* storage disabled: the token lasts this page only */ }
}

// The words a failed response carries ({"error": "..."}), or its status line.
async function errorWords(response) {
  try {
    const body = await response.json();
    if (body && typeof body.error === "string" && body.error) return body.error;
  } catch { /* not JSON */ }
  return `${response.status} ${response.statusText || "error"}`.trim();
}

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

export async function getJson(path) {
  let response;
  try {
    response = await fetch(path, { headers: { Accept: "application/json" }, cache: "no-store" });
  } catch (error) {
    throw new ApiError(0, `the gateway did not answer (${error.message})`);
  }
  if (response.status === 401) unauthorizedListeners.forEach((listener) => listener());
  if (!response.ok) throw new ApiError(response.status, await errorWords(response));
  return response.json();
}

export function listDevices() {
  return getJson("/api/devices");
}

export function getDevice(name) {
  return getJson(`/api/devices/${encodeURIComponent(name)}`);
}

// Writes one parameter as text ("150", "remote"); resolves to the gateway's answer, rejects
// with ApiError carrying the device's or the gateway's refusal in words.
export async function writeParameter(device, parameter, text) {
  const headers = { "Content-Type": "application/json", Accept: "application/json" };
  if (session && session.csrf) {
    headers["X-CSRF-Token"] = session.csrf;
  } else {
    const token = storedToken();
    if (token) headers.Authorization = `Bearer ${token}`;
  }
  let response;
  try {
    response = await fetch(`/api/devices/${encodeURIComponent(device)}/write`, {
      method: "POST", headers, body: JSON.stringify({ [parameter]: text }),
    });
  } catch (error) {
    throw new ApiError(0, `the gateway did not answer (${error.message})`);
  }
  if (!response.ok) throw new ApiError(response.status, await errorWords(response));
  return response.json();
}

// Downsampled history, or null when the gateway keeps none (404). `gateway`: another gateway's,
// from the historian they share; empty: this gateway's own.
export async function getHistory(device, parameters, from, to, points, gateway = "") {
  const query = new URLSearchParams({
    device, parameters: parameters.join(","), from: from.toISOString(), to: to.toISOString(), points: String(points),
  });
  if (gateway) query.set("gateway", gateway);
  try {
    return await getJson(`/api/history?${query}`);
  } catch (error) {
    if (error.status === 404) return null;
    throw error;
  }
}

// The gateways whose history the shared historian holds ({ this, gateways }), or null when this
// gateway forwards its history nowhere (404) or the historian cannot say now.
export async function listHistoryGateways() {
  try {
    return await getJson("/api/history/gateways");
  } catch {
    return null;
  }
}
