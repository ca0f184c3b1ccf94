// The real gateway for the browser tests: `loopwire gateway` on a TOML with a simulated line
// (rtu:virtual) holding three simulated controllers, a second line on a pseudo-terminal served
// by `loopwire simulate` (a TC10 the tests can cut off by killing its simulator, and bring back),
// its history recorded in an SQLite file, its HTTP front on a port the kernel chooses, and a
// token file for writes.
const { spawn, spawnSync } = require("node:child_process");
const net = require("node:net");
const fs = require("node:fs");
const os = require("node:os");
const path = require("node:path");

const TOKEN = "dashboard-test-token";

function plantToml(tokenFile, httpPort, benchPty, historyFile, usersFile) {
  return `
[[lines]]
name = "plant"
link = "rtu:virtual?baud=19200&parity=none"
timeout = "500ms"
retries = 1
speed = 10

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "500ms"
parameters = ["carbon_potential", "main_set_point", "main_output_value"]

[[lines.devices]]
name = "kiln"
device = "rampsoak@2"
poll = "500ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "500ms"
parameters = ["measured_value", "set_point", "output_power", "alarm_status"]

[[lines]]
name = "bench"
link = "rtu:${benchPty}?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "dryer"
device = "tc10@4"
poll = "500ms"
parameters = ["measured_value", "set_point", "output_power", "set_point_low_limit", "set_point_high_limit"]

[history]
database = "${historyFile}"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:${httpPort}"
token_file = "${tokenFile}"
${usersFile ? `users_file = "${usersFile}"\nopen_reads = "none"` : ""}
`;
}

// A port the kernel chose for a listener closed at once: free for the gateway's HTTP front
// (the gateway logs only its Modbus TCP port).
function freePort() {
  return new Promise((resolve, reject) => {
    const server = net.createServer();
    server.once("error", reject);
    server.listen(0, "127.0.0.1", () => {
      const { port } = server.address();
      server.close(() => resolve(port));
    });
  });
}

// Until GET /api/devices answers 200, or rejects after TIMEOUT ms with the gateway's output.
async function waitForApi(base, output, timeout) {
  const deadline = Date.now() + timeout;
  for (;;) {
    if (output.exited) throw new Error(`the gateway exited before its HTTP API answered:\n${output.text}`);
    try {
      const response = await fetch(`${base}/api/devices`, { headers: { Authorization: `Bearer ${TOKEN}` } });
      if (response.ok) return;
    } catch { /* not listening yet */ }
    if (Date.now() > deadline) throw new Error(`waited ${timeout} ms for the gateway's HTTP API at ${base}; it said:\n${output.text}`);
    await new Promise((resolve) => setTimeout(resolve, 50));
  }
}

async function waitForPath(file, output, timeout) {
  const deadline = Date.now() + timeout;
  while (!fs.existsSync(file)) {
    if (output.exited) throw new Error(`the simulator exited before it made ${file}:\n${output.text}`);
    if (Date.now() > deadline) throw new Error(`waited ${timeout} ms for ${file}; the simulator said:\n${output.text}`);
    await new Promise((resolve) => setTimeout(resolve, 20));
  }
}

function started(program, args, env) {
  const child = spawn(program, args, { env, stdio: ["ignore", "pipe", "pipe"] });
  const output = { text: "", exited: false };
  child.stdout.on("data", (chunk) => { output.text += chunk; });
  child.stderr.on("data", (chunk) => { output.text += chunk; });
  child.on("exit", () => { output.exited = true; });
  return { child, output };
}

// Until CHILD has exited: SIGTERM, then SIGKILL after 5 s (or SIGNAL at once).
function ended({ child, output }, signal = "SIGTERM") {
  return new Promise((resolve) => {
    if (output.exited) return resolve();
    const timer = setTimeout(() => child.kill("SIGKILL"), 5_000);
    child.on("exit", () => { clearTimeout(timer); resolve(); });
    child.kill(signal);
  });
}

// `loopwire simulate` serving the bench line's TC10 on a pseudo-terminal at PTY, its
// non-volatile memory (set point, limits) in STATE so that it survives being killed.
async function startSimulator(loopwire, pty, state, env) {
  const simulator = started(loopwire, ["simulate", "--link", "rtu:/unused?baud=19200&parity=none", "--pty", pty,
    "--device", "tc10@4", "--speed", "10", "--state", state], env);
  await waitForPath(pty, simulator.output, 10_000);
  return simulator;
}

// A users file made as a person makes one, with `loopwire passwd` (the password on stdin):
// USERS is [[name, role, password], ...].
function writeUsers(loopwire, file, users) {
  for (const [name, role, password] of users) {
    const made = spawnSync(loopwire, ["passwd", file, name, "--role", role], { input: `${password}\n`, encoding: "utf8" });
    if (made.status !== 0) throw new Error(`loopwire passwd ${name}: ${made.stderr}`);
  }
}

// With `users` ([[name, role, password], ...]) the gateway has a users file and nothing is read
// without a login (open_reads = "none").
async function startGateway({ users } = {}) {
  const loopwire = process.env.LOOPWIRE;
  if (!loopwire) throw new Error("LOOPWIRE must name the loopwire program (dashboard_test.sh sets it)");
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), "loopwire-dashboard-"));
  const tokenFile = path.join(dir, "token");
  fs.writeFileSync(tokenFile, `${TOKEN}\n`, { mode: 0o600 });
  const config = path.join(dir, "plant.toml");
  const httpPort = await freePort();
  const benchPty = path.join(dir, "ttyBench");
  const benchState = path.join(dir, "bench.state");
  let usersFile = "";
  if (users) {
    usersFile = path.join(dir, "users");
    writeUsers(loopwire, usersFile, users);
  }
  fs.writeFileSync(config, plantToml(tokenFile, httpPort, benchPty, path.join(dir, "history.db"), usersFile));
  const env = { ...process.env, XDG_CONFIG_HOME: path.join(dir, "config") };
  let simulator = await startSimulator(loopwire, benchPty, benchState, env);
  const gateway = started(loopwire, ["gateway", "--config", config], env);
  const { output } = gateway;
  const base = `http://127.0.0.1:${httpPort}`;
  try {
    await waitForApi(base, output, 15_000);
  } catch (error) {
    await ended(gateway);
    await ended(simulator);
    throw error;
  }
  return {
    base,
    token: TOKEN,
    output,
    // The bench line cut off as a pulled USB-RS485 adapter cuts it: its simulator killed
    // (SIGKILL), so the pseudo-terminal hangs up, and its link removed as udev removes an
    // adapter's (left behind, it would name whatever terminal takes the number next).
    async breakBenchLine() {
      await ended(simulator, "SIGKILL");
      fs.rmSync(benchPty, { force: true });
    },
    // The bench line's device back on the same path, holding what it held.
    async restoreBenchLine() {
      simulator = await startSimulator(loopwire, benchPty, benchState, env);
    },
    async stop() {
      await ended(gateway);
      await ended(simulator);
      fs.rmSync(dir, { recursive: true, force: true });
    },
  };
}

module.exports = { startGateway };
