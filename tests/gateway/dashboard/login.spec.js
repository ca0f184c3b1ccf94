// Logins on the dashboard in a real browser against a real gateway with a users file and
// open_reads = "none": an operator logs in and writes a set point, which the audit credits to
// them; a viewer sees no write control and a forced write is refused; a POST carrying the
// session cookie but not the CSRF token (what another site's form would send) is refused;
// logging out ends the session.
const { test, expect } = require("@playwright/test");
const path = require("node:path");
const { startGateway } = require("./gateway_fixture.js");

const artifacts = process.env.LOOPWIRE_ARTIFACTS || "test-results";

let gateway;

test.describe.configure({ mode: "serial" });

test.beforeAll(async () => {
  gateway = await startGateway({ users: [["olga", "operator", "olga-password-1"], ["victor", "viewer", "victor-password-1"]] });
});

test.afterAll(async () => {
  if (gateway) await gateway.stop();
});

async function logIn(page, user, password) {
  const dialog = page.locator("#login-dialog");
  await expect(dialog).toBeVisible({ timeout: 10_000 });
  await dialog.getByLabel("User").fill(user);
  await dialog.getByLabel("Password").fill(password);
  await dialog.getByRole("button", { name: "Log in" }).click();
  await expect(dialog).toBeHidden({ timeout: 10_000 });
  await expect(page.locator("#user-name")).toHaveText(user);
}

// A write from the page's own context with the session cookie, and the CSRF header or not.
function forcedWrite(page, body, withCsrf) {
  return page.evaluate(async ({ body, withCsrf }) => {
    const headers = { "Content-Type": "application/json" };
    if (withCsrf) {
      const session = await (await fetch("/api/session")).json();
      headers["X-CSRF-Token"] = session.csrf;
    }
    const response = await fetch("/api/devices/oven/write", { method: "POST", headers, body: JSON.stringify(body) });
    return { status: response.status, body: await response.json() };
  }, { body, withCsrf });
}

test("an operator logs in, writes a set point, and the audit names them", async ({ page, request }) => {
  await page.goto(`${gateway.base}/#/devices/oven`);
  await expect(page.locator("#login-dialog")).toBeVisible({ timeout: 10_000 });
  await page.screenshot({ path: path.join(artifacts, "login-desktop.png"), fullPage: false });
  await logIn(page, "olga", "olga-password-1");
  await expect(page.locator("#user-role")).toHaveText("operator");
  const row = page.locator('tr.param-row[data-param="set_point"]');
  await expect(row.locator(".param-value .num")).toHaveText(/\d/, { timeout: 10_000 });
  await row.getByRole("button", { name: "Change" }).click();
  const form = page.locator('tr.write-row[data-write="set_point"] form');
  await form.locator("input").fill("640");
  await form.getByRole("button", { name: "Write" }).click();
  await expect(form.locator(".write-result")).toHaveText(/Written: 640/, { timeout: 10_000 });
  await expect.poll(async () => {
    const audit = await request.get(`${gateway.base}/api/audit?device=oven`, { headers: { Authorization: `Bearer ${gateway.token}` } });
    const { records } = await audit.json();
    const mine = records.find((record) => record.parameter === "set_point" && /640/.test(record.new_value));
    return mine ? `${mine.user} ${mine.outcome}` : "none yet";
  }, { timeout: 10_000 }).toBe("olga confirmed");
});

test("a POST with the session cookie but without the CSRF token is refused", async ({ page }) => {
  await page.goto(`${gateway.base}/#/devices/oven`);
  await logIn(page, "olga", "olga-password-1");
  const refused = await forcedWrite(page, { set_point: 650 }, false);
  expect(refused.status).toBe(403);
  expect(refused.body.error).toContain("X-CSRF-Token");
  const accepted = await forcedWrite(page, { set_point: 641 }, true);
  expect(accepted.status, JSON.stringify(accepted.body)).toBe(200);
});

test("a viewer sees no write control, a forced write is refused, and logout ends the session", async ({ page }) => {
  await page.goto(`${gateway.base}/#/devices/oven`);
  await logIn(page, "victor", "victor-password-1");
  await expect(page.locator("#user-role")).toHaveText("viewer");
  const row = page.locator('tr.param-row[data-param="set_point"]');
  await expect(row.locator(".param-value .num")).toHaveText(/\d/, { timeout: 10_000 });
  await expect(page.locator('[data-action="edit"]')).toHaveCount(0);
  const forced = await forcedWrite(page, { set_point: 660 }, true);
  expect(forced.status).toBe(403);
  expect(forced.body.error).toContain("viewer");

  await page.getByRole("button", { name: "Log out" }).click();
  await expect(page.locator("#login-dialog")).toBeVisible({ timeout: 10_000 });
  const after = await page.evaluate(async () => (await fetch("/api/devices")).status);
  expect(after).toBe(401);
});
