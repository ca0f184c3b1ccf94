#!/usr/bin/env bash
# The dashboard's browser tests (dashboard.spec.js) with Playwright on Debian's Chromium,
# against the real gateway: skipped (exit 77) when Chromium or the npm packages are missing.
#   dashboard_test.sh path/to/loopwire ARTEFACT_DIR
set -u
loopwire=${1:?usage: dashboard_test.sh path/to/loopwire ARTEFACT_DIR}
artifacts=${2:?usage: dashboard_test.sh path/to/loopwire ARTEFACT_DIR}
here=$(cd "$(dirname "$0")" && pwd)
top=$(cd "$here/../../.." && pwd)
chromium=${LOOPWIRE_CHROMIUM:-/usr/bin/chromium}

if [ ! -x "$chromium" ]; then
  echo "SKIP: $chromium is missing (Debian's chromium package; scripts/setup installs it)"
  exit 77
fi
if [ ! -d "$top/node_modules/@playwright/test" ]; then
  echo "SKIP: $top/node_modules/@playwright/test is missing (run scripts/setup, or npm ci in $top)"
  exit 77
fi
command -v node >/dev/null || { echo "SKIP: node is missing (Debian's nodejs package; scripts/setup installs it)"; exit 77; }

mkdir -p "$artifacts"
rm -f "$artifacts"/*.png
cd "$top"
export LOOPWIRE="$loopwire" LOOPWIRE_ARTIFACTS="$artifacts" LOOPWIRE_CHROMIUM="$chromium"
# No telemetry, no browser download, no update check: nothing leaves the machine.
export PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 PLAYWRIGHT_BROWSERS_PATH=0 CI=1
timeout 170 node "$top/node_modules/@playwright/test/cli.js" test --config "$here/playwright.config.js"
status=$?
[ "$status" -eq 0 ] && echo "screenshots: $(ls "$artifacts"/*.png 2>/dev/null | tr '\n' ' ')"
exit "$status"
