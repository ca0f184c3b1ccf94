// The real gateway for the browser tests: `loopwire gateway` on a TOML with a simulated line
// (rtu:virtual) holding the three simulated controllers, its HTTP front on a port the kernel
// chooses, and a token file for writes.
const { spawn } = require("node:child_process");
const net = require("node:net");
const fs = require("node:fs");
const os = require("node:os");
const path = require("node:path");

const TOKEN = "dashboard-test-token";

function plantToml(tokenFile, httpPort) {
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

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:${httpPort}"
token_file = "${tokenFile}"
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
      const response = await fetch(`${base}/api/devices`);
      if (response.ok) return;
    } catch { /* not listening yet */ }
    if (Date.now() > deadline) throw new Error(`waited ${timeout} ms for the gateway's HTTP API at ${base}; it said:\n${output.text}`);
    await new Promise((resolve) => setTimeout(resolve, 50));
  }
}

async function startGateway() {
  const loopwire = process.env.LOOPWIRE;
  if (!loopwire) throw new Error("LOOPWIRE must name the loopwire program (dashboard_test.sh sets it)");
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), "loopwire-dashboard-"));
  const tokenFile = path.join(dir, "token");
  fs.writeFileSync(tokenFile, `${TOKEN}\n`, { mode: 0o600 });
  const config = path.join(dir, "plant.toml");
  const httpPort = await freePort();
  fs.writeFileSync(config, plantToml(tokenFile, httpPort));
  const env = { ...process.env, XDG_CONFIG_HOME: path.join(dir, "config") };
  const child = spawn(loopwire, ["gateway", "--config", config], { env, stdio: ["ignore", "pipe", "pipe"] });
  const output = { text: "", exited: false };
  child.stdout.on("data", (chunk) => { output.text += chunk; });
  child.stderr.on("data", (chunk) => { output.text += chunk; });
  child.on("exit", () => { output.exited = true; });
  const base = `http://127.0.0.1:${httpPort}`;
  await waitForApi(base, output, 15_000);
  return {
    base,
    token: TOKEN,
    output,
    async stop() {
      if (!output.exited) {
        child.kill("SIGTERM");
        await new Promise((resolve) => {
          const timer = setTimeout(() => { child.kill("SIGKILL"); resolve(); }, 5_000);
          child.on("exit", () => { clearTimeout(timer); resolve(); });
          if (output.exited) { clearTimeout(timer); resolve(); }
        });
      }
      fs.rmSync(dir, { recursive: true, force: true });
    },
  };
}

module.exports = { startGateway };
