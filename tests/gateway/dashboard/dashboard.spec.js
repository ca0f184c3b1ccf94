// The dashboard in a real browser against a real gateway and its simulated devices: the
// overview shows every device with values and units, a trend follows the moving process, the
// write form changes a device and shows a refusal in words, and screenshots are kept.
const { test, expect } = require("@playwright/test");
const path = require("node:path");
const { startGateway } = require("./gateway_fixture.js");

const artifacts = process.env.LOOPWIRE_ARTIFACTS || "test-results";
const PHONE = { width: 390, height: 844 };
let gateway;

async function api(request, method, url, body) {
  const response = await request.fetch(`${gateway.base}${url}`, {
    method,
    headers: { Authorization: `Bearer ${gateway.token}`, "Content-Type": "application/json" },
    data: body ? JSON.stringify(body) : undefined,
  });
  return { status: response.status(), body: await response.json().catch(() => null) };
}

async function parameter(request, device, name) {
  const { status, body } = await api(request, "GET", `/api/devices/${device}`);
  expect(status).toBe(200);
  return body.parameters.find((p) => p.name === name);
}

test.describe.configure({ mode: "serial" });

test.beforeAll(async ({ request }) => {
  gateway = await startGateway();
  // Set points that make the process move (each simulated controller starts cold; the oven's
  // is far enough above ambient to keep it rising through the whole run); the AC20
  // takes writes only in remote (its manual, Note 5), so that goes first.
  for (const [device, values] of [["furnace", { local_remote: "remote" }], ["furnace", { main_set_point: "1.00" }],
    ["kiln", { set_value: "180.0" }], ["oven", { set_point: "800" }]]) {
    const answer = await api(request, "POST", `/api/devices/${device}/write`, values);
    expect(answer.status, `writing ${JSON.stringify(values)} to ${device}: ${JSON.stringify(answer.body)}`).toBe(200);
  }
});

test.afterAll(async () => {
  if (gateway) await gateway.stop();
});

test("the overview shows the three simulated devices with values and units", async ({ page, request }) => {
  await page.goto(gateway.base);
  const cards = page.locator("article.card");
  await expect(cards).toHaveCount(3);
  for (const name of ["furnace", "kiln", "oven"]) {
    const card = page.locator(`article.card[data-device="${name}"]`);
    await expect(card.locator(".card-title")).toHaveText(name);
    await expect(card.locator(".device-status")).toHaveText("online", { timeout: 10_000 });
    // PV, SP and OUT (the profile's aliases), each a number with the unit the API gives it.
    const tiles = card.locator(".key-value[data-param]");
    await expect(tiles).toHaveCount(3);
    for (const tile of await tiles.all()) {
      const param = await tile.getAttribute("data-param");
      const { unit } = await parameter(request, name, param);
      await expect(tile.locator(".reading .num"), `${name} ${param}`).toHaveText(/\d/, { timeout: 10_000 });
      if (unit) await expect(tile.locator(".reading .unit"), `${name} ${param}`).toHaveText(unit);
    }
  }
  await expect(page.locator('article.card[data-device="oven"] .key-value[data-param="output_power"] .unit')).toHaveText("%");
  await page.screenshot({ path: path.join(artifacts, "overview-desktop.png"), fullPage: true });
  await page.setViewportSize(PHONE);
  await expect(cards.first()).toBeVisible();
  const width = await page.evaluate(() => document.documentElement.scrollWidth);
  expect(width, "the overview fits a phone's width without scrolling sideways").toBeLessThanOrEqual(PHONE.width);
  await page.screenshot({ path: path.join(artifacts, "overview-phone.png"), fullPage: true });
});

// How much slower the gateway under test is than a release build: sanitizer builds set it
// (tests/gateway/CMakeLists.txt), so a promise kept in wall time is checked against its own build.
const SLOWDOWN = Number(process.env.LOOPWIRE_SLOWDOWN || "1");

test("a trend updates within 2 s as the process moves", async ({ page }) => {
  await page.goto(`${gateway.base}/#/devices/oven`);
  const chart = page.locator("#trend");
  await expect(chart.locator("canvas")).toBeVisible();
  await expect(chart).toHaveAttribute("data-last-time", /\d/, { timeout: 5_000 });
  const before = { time: await chart.getAttribute("data-last-time"), values: await chart.getAttribute("data-last-values") };
  await expect.poll(async () => chart.getAttribute("data-last-time"), { timeout: 2_000 * SLOWDOWN, message: "a new sample on the trend" })
    .not.toBe(before.time);
  // The measured value (the first series) moves towards the set point.
  await expect.poll(async () => (await chart.getAttribute("data-last-values")).split(",")[0], { timeout: 2_000 * SLOWDOWN, message: "the measured value moving" })
    .not.toBe(before.values.split(",")[0]);
});

// Recorded values are changes: each holds until the next, so the trend draws steps, and a time
// without a value (the history's gaps: no reply, a special state) breaks the line instead of
// being bridged by a slope. The history here is an answer given to the page (the test gateway
// records none): 100 °C, a step to 180 °C, an outage of two minutes, then 25 °C.
test("the trend draws recorded values as steps and breaks its line over a gap", async ({ page }) => {
  const now = Date.now();
  const iso = (ms) => new Date(ms).toISOString();
  const bucket = (ms, value) => ({ time: iso(ms), min: value, max: value, mean: value, count: 1 });
  await page.route("**/api/history?**", (route) => route.fulfill({
    json: {
      device: "oven",
      series: [{
        parameter: "measured_value", unit: "°C",
        buckets: [bucket(now - 240_000, 100), bucket(now - 200_000, 180), bucket(now - 120_000, 999), bucket(now - 60_000, 25)],
        gaps: [{ from: iso(now - 180_000), to: iso(now - 60_000) }],
      }],
    },
  }));
  await page.goto(`${gateway.base}/#/devices/oven`);
  const chart = page.locator("#trend");
  await expect(chart.locator("canvas")).toBeVisible();
  // The measured value (the first series) breaks once: over the outage, not between samples.
  await expect(chart).toHaveAttribute("data-gaps", /^1(,|$)/, { timeout: 10_000 });

  // The same, step by step, through the page's own module.
  const drawn = await page.evaluate(async (start) => {
    const { historyPoints, alignColumns } = await import("/assets/trend.js");
    const iso = (ms) => new Date(ms).toISOString();
    const points = historyPoints({
      buckets: [{ time: iso(start), mean: 100 }, { time: iso(start + 40_000), mean: 180 }, { time: iso(start + 120_000), mean: 999 },
        { time: iso(start + 180_000), mean: 25 }],
      gaps: [{ from: iso(start + 60_000), to: iso(start + 180_000) }],
    });
    const column = new Map(points.t.map((t, i) => [t, points.v[i]]));
    const [times, [values]] = alignColumns([column], start + 200_000);
    return { times: times.map((t) => (t - start) / 1000), values };
  }, now - 240_000);
  // 100 holds until the step to 180, which holds until the gap; the bucket inside the gap draws
  // nothing there; 25 from the gap's end, held to now.
  expect(drawn.times).toEqual([0, 40, 60, 180, 200]);
  expect(drawn.values).toEqual([100, 180, null, 25, 25]);
});

// A gateway whose history goes to a historian other gateways share can show their history: the
// trend's picker lists them (this gateway first), the history request names the one chosen, and
// the note says that live values, which are this gateway's, are left out. The historian's
// answers are given to the page (the test gateway forwards to none).
test("the trend shows another gateway's history when one is picked", async ({ page }) => {
  await page.route("**/api/history/gateways", (route) => route.fulfill({ json: { this: "north", gateways: ["north", "south", "west"] } }));
  const asked = [];
  await page.route("**/api/history?**", (route) => {
    asked.push(new URL(route.request().url()).searchParams.get("gateway"));
    return route.fulfill({ json: { device: "oven", series: [] } });
  });
  await page.goto(`${gateway.base}/#/devices/oven`);
  const picker = page.getByLabel("History of gateway");
  await expect(picker).toBeVisible({ timeout: 10_000 });
  await expect(picker.locator("option")).toHaveText(["north (this gateway)", "south", "west"]);
  await picker.selectOption("south");
  await expect.poll(() => asked.at(-1)).toBe("south");
  await expect(page.locator("#trend-note")).toHaveText(/Recorded history of gateway south \(no live values/);
  await picker.selectOption("");
  await expect.poll(() => asked.at(-1)).toBe(null);
  await expect(page.locator("#trend-note")).toHaveText("Recorded history, then live values.");
});

test("without a shared historian there is no choice of gateway", async ({ page }) => {
  const answered = page.waitForResponse("**/api/history/gateways");
  await page.goto(`${gateway.base}/#/devices/oven`);
  expect((await answered).status()).toBe(404);
  await expect(page.locator("#trend canvas")).toBeVisible({ timeout: 10_000 });
  await expect(page.getByLabel("History of gateway")).toBeHidden();
});

test("a write from the form changes the device, and a refused write shows the reason", async ({ page, request }) => {
  await page.addInitScript((token) => localStorage.setItem("loopwire.token", token), gateway.token);
  await page.goto(`${gateway.base}/#/devices/oven`);
  const row = page.locator('tr.param-row[data-param="set_point"]');
  await expect(row.locator(".param-value .num")).toHaveText(/\d/, { timeout: 10_000 });
  await row.getByRole("button", { name: "Change" }).click();
  const form = page.locator('tr.write-row[data-write="set_point"] form');
  await form.locator("input").fill("750");
  await form.getByRole("button", { name: "Write" }).click();
  await expect(form.locator(".write-result")).toHaveText(/Written: 750/);
  await expect.poll(async () => (await parameter(request, "oven", "set_point")).text, { timeout: 5_000 }).toMatch(/^750(\.0+)?$/);
  await expect(row.locator(".param-value")).toContainText("750", { timeout: 5_000 });

  await form.locator("input").fill("99999");
  await form.getByRole("button", { name: "Write" }).click();
  const refusal = form.locator(".write-result");
  await expect(refusal).toHaveClass(/error/);
  await expect(refusal).toContainText(/Refused: .*(range|maximum|above|most|limit)/i);
  expect((await parameter(request, "oven", "set_point")).text).toMatch(/^750(\.0+)?$/);

  await page.screenshot({ path: path.join(artifacts, "device-desktop.png"), fullPage: false });
  await page.setViewportSize(PHONE);
  await page.evaluate(() => window.scrollTo(0, 0));
  await expect(page.locator("#trend canvas")).toBeVisible();
  const width = await page.evaluate(() => document.documentElement.scrollWidth);
  expect(width, "the device page fits a phone's width without scrolling sideways").toBeLessThanOrEqual(PHONE.width);
  await page.screenshot({ path: path.join(artifacts, "device-phone.png"), fullPage: false });
});

test("without the token a write is refused and says what to do", async ({ page }) => {
  await page.goto(`${gateway.base}/#/devices/kiln`);
  const row = page.locator('tr.param-row[data-param="set_value"]');
  await row.getByRole("button", { name: "Change" }).click();
  const form = page.locator('tr.write-row[data-write="set_value"] form');
  await form.locator("input").fill("170");
  await form.getByRole("button", { name: "Write" }).click();
  await expect(form.locator(".write-result")).toContainText(/Refused: .*token/i);
  await expect(page.locator("#token-dialog")).toBeVisible();
});
