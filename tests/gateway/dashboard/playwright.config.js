// Playwright for the dashboard's browser tests (dashboard_test.sh runs it): Debian's Chromium
// (Playwright's own browser downloads are not used), one worker, artefacts in the build folder.
const { defineConfig } = require("@playwright/test");

const artifacts = process.env.LOOPWIRE_ARTIFACTS || "test-results";

module.exports = defineConfig({
  testDir: __dirname,
  testMatch: /.*\.spec\.js$/,
  outputDir: `${artifacts}/playwright`,
  timeout: 30_000,
  expect: { timeout: 5_000 },
  workers: 1,
  retries: 0,
  reporter: [["list"]],
  use: {
    browserName: "chromium",
    headless: true,
    launchOptions: { executablePath: process.env.LOOPWIRE_CHROMIUM || "/usr/bin/chromium", args: ["--no-sandbox", "--disable-dev-shm-usage"] },
    viewport: { width: 1280, height: 860 },
    trace: "off",
    screenshot: "only-on-failure",
  },
});
