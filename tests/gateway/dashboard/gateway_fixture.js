// The real gateway for the browser tests: `loopwire gateway` on a TOML with a simulated line
// (rtu:virtual) holding the three simulated controllers, its HTTP front on a port the kernel
// chooses (read back from the log), and a token file for writes.
const { spawn } = require("node:child_process");
const fs = require("node:fs");
const os = require("node:os");
const path = require("node:path");

const TOKEN = "dashboard-test-token";

function plantToml(tokenFile) {
  return `
[[lines]]
name = "plant"
link = "rtu:virtual?baud=19200&parity=none"
timeout = "500ms"
retries = 1
speed = 60

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "500ms"

[[lines.devices]]
name = "kiln"
device = "rampsoak@2"
poll = "500ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "500ms"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"
token_file = "${tokenFile}"
`;
}

// Resolves with the first match of PATTERN in the growing text of the process's output, or
// rejects after TIMEOUT ms naming what it waited for, with the output so far.
function waitForOutput(output, pattern, timeout, what) {
  return new Promise((resolve, reject) => {
    const deadline = Date.now() + timeout;
    const poll = () => {
      const match = output.text.match(pattern);
      if (match) return resolve(match);
      if (output.exited) return reject(new Error(`the gateway exited before ${what}:\n${output.text}`));
      if (Date.now() > deadline) return reject(new Error(`waited ${timeout} ms for ${what}; the gateway said:\n${output.text}`));
      setTimeout(poll, 25);
    };
    poll();
  });
}

async function startGateway() {
  const loopwire = process.env.LOOPWIRE;
  if (!loopwire) throw new Error("LOOPWIRE must name the loopwire program (dashboard_test.sh sets it)");
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), "loopwire-dashboard-"));
  const tokenFile = path.join(dir, "token");
  fs.writeFileSync(tokenFile, `${TOKEN}\n`, { mode: 0o600 });
  const config = path.join(dir, "plant.toml");
  fs.writeFileSync(config, plantToml(tokenFile));
  const env = { ...process.env, XDG_CONFIG_HOME: path.join(dir, "config") };
  const child = spawn(loopwire, ["gateway", "--config", config], { env, stdio: ["ignore", "pipe", "pipe"] });
  const output = { text: "", exited: false };
  child.stdout.on("data", (chunk) => { output.text += chunk; });
  child.stderr.on("data", (chunk) => { output.text += chunk; });
  child.on("exit", () => { output.exited = true; });
  const match = await waitForOutput(output, /HTTP[^\n]*?(?:port |:)(\d{2,5})\b/, 15_000, "its HTTP port in the log");
  const base = `http://127.0.0.1:${match[1]}`;
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
