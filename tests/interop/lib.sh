# shellcheck shell=bash
# Shared by the bash interop scripts (sourced, not run). Provides a temporary directory, cleanup
# of background processes on every way out, and waiting / checking helpers.
#
# Background peers are bounded twice: the EXIT trap kills them, and each has a lifetime of its
# own (`timeout`, `loopwire simulate --duration`), because CTest's timeout kills a test with
# SIGKILL, which runs no trap.

set -euo pipefail

# Upper bound on the life of any background peer: above a test's few seconds, below CTest's 60.
readonly PEER_LIFETIME=45

WORK_DIR=$(mktemp -d "${TMPDIR:-/tmp}/loopwire-interop.XXXXXX")
BACKGROUND_PIDS=()

cleanup() {
    local status=$?
    local pid
    for pid in "${BACKGROUND_PIDS[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${BACKGROUND_PIDS[@]}"; do
        wait "$pid" 2>/dev/null || true
    done
    if [[ $status -ne 0 ]]; then
        # The peers' logs are the evidence of a failure: show them before they go.
        local log
        for log in "$WORK_DIR"/*.log; do
            [[ -e $log ]] || continue
            echo "--- $(basename "$log") ---" >&2
            cat "$log" >&2
        done
    fi
    rm -rf "$WORK_DIR"
    exit "$status"
}
trap cleanup EXIT
# Turn signals into a normal exit so the EXIT trap runs.
trap 'exit 143' TERM INT HUP

# start_background LOG COMMAND... : runs COMMAND in the background with stdout and stderr in
# $WORK_DIR/LOG; its PID is recorded for cleanup and left in $LAST_PID.
start_background() {
    local log=$1
    shift
    "$@" >"$WORK_DIR/$log" 2>&1 &
    LAST_PID=$!
    BACKGROUND_PIDS+=("$LAST_PID")
}

fail() {
    echo "FAIL: $*" >&2
    exit 1
}

# wait_for_path PATH [SECONDS]
wait_for_path() {
    local path=$1 limit=${2:-5}
    local deadline=$((SECONDS + limit))
    until [[ -e $path ]]; do
        ((SECONDS <= deadline)) || fail "$path did not appear within ${limit} s"
        sleep 0.02
    done
}

# wait_for_log LOG REGEX [SECONDS] : waits until $WORK_DIR/LOG has a line matching the extended
# REGEX, and prints its first capture group (sed -E syntax: \1).
wait_for_log() {
    local log=$WORK_DIR/$1 regex=$2 limit=${3:-5}
    local deadline=$((SECONDS + limit)) found
    while true; do
        found=$(sed -nE "s/.*${regex}.*/\\1/p" "$log" 2>/dev/null | head -n 1)
        [[ -n $found ]] && { echo "$found"; return 0; }
        ((SECONDS <= deadline)) || fail "$(basename "$log") did not show /${regex}/ within ${limit} s"
        sleep 0.02
    done
}

# socat_pair A B : a connected pseudo-terminal pair with links at the two paths.
socat_pair() {
    start_background socat.log timeout "$PEER_LIFETIME" socat \
        "pty,raw,echo=0,link=$1" "pty,raw,echo=0,link=$2"
    wait_for_path "$1"
    wait_for_path "$2"
}

# expect_equal ACTUAL EXPECTED WHAT
expect_equal() {
    [[ $1 == "$2" ]] || fail "$3: expected '$2', got '$1'"
    if ((${#1} > 160)); then echo "ok: $3 = ${1:0:140} ..."; else echo "ok: $3 = $1"; fi
}
