# shellcheck shell=bash
# The one library every shell test sources (tests/**/*.sh, bench/*.sh). It provides:
#   - WORK_DIR, a scratch directory, and background processes (start_background), both cleaned
#     up on every way out; on a failure the logs in WORK_DIR are shown before they go;
#   - TCP servers on ports the kernel chose (start_tcp_server: the server binds port 0 and
#     names the port it got), so tests can run in parallel;
#   - waits with a deadline that fail the test loudly, naming what they waited for (wait_for...);
#   - checks that stop the test at once (fail, expect_equal) and checks that are tallied so one
#     run reports every failure (check, expect, count_pass, count_failure; finish ends the run).
#
# Background processes are bounded twice: the EXIT trap kills them, and each should have a
# lifetime of its own (`timeout`, `loopwire simulate --duration`), because CTest's timeout kills
# a test with SIGKILL, which runs no trap.
#
# Sourcing sets no shell options: a script that wants `set -euo pipefail` sets it itself.

WORK_DIR=$(mktemp -d "${TMPDIR:-/tmp}/loopwire-test.XXXXXX")
# loopwire loads profile files from the user's folder ($XDG_CONFIG_HOME/loopwire/profiles): the
# tests see none but their own, whatever the machine's user keeps there.
export XDG_CONFIG_HOME="$WORK_DIR/config"
BACKGROUND_PIDS=()
LAST_PID=
PORT=
passes=0
failures=0
# The test's own shell: fail() called inside $(...) must stop it, not just the subshell.
readonly TEST_SHELL_PID=$BASHPID

# Upper bound on the life of a background peer in the interop tests: above a test's few
# seconds, even in a sanitized build, below CTest's 240 (tests/interop/CMakeLists.txt).
readonly PEER_LIFETIME=200

test_lib_cleanup() {
    local status=$?
    local pid log
    for pid in "${BACKGROUND_PIDS[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${BACKGROUND_PIDS[@]}"; do
        wait "$pid" 2>/dev/null || true
    done
    if ((status != 0)); then
        # The background processes' logs are the evidence of a failure: show them before they go.
        for log in "$WORK_DIR"/*.log; do
            [[ -e $log ]] || continue
            echo "--- $(basename "$log") (last 60 lines) ---" >&2
            tail -n 60 "$log" >&2
        done
    fi
    rm -rf "$WORK_DIR"
    exit "$status"
}
trap test_lib_cleanup EXIT
# Turn signals into a normal exit so the EXIT trap runs.
trap 'exit 143' TERM INT HUP

# fail MESSAGE... : stops the test with MESSAGE, also when called inside $(...).
fail() {
    echo "FAIL: $*" >&2
    if [[ $BASHPID != "$TEST_SHELL_PID" ]]; then kill -TERM "$TEST_SHELL_PID" 2>/dev/null; fi
    exit 1
}

# start_background LOG COMMAND... : runs COMMAND in the background with stdout and stderr in
# $WORK_DIR/LOG; its PID is recorded for cleanup and left in LAST_PID.
start_background() {
    local log=$1
    shift
    # Emptied here, not only by the background redirection: a LOG used before (a benchmark's
    # rounds) would otherwise still show the previous run's lines to a wait that starts now.
    : >"$WORK_DIR/$log"
    "$@" >"$WORK_DIR/$log" 2>&1 &
    LAST_PID=$!
    BACKGROUND_PIDS+=("$LAST_PID")
}

# start_tcp_server LOG COMMAND... : starts a server that listens on port 0 and names the port
# the kernel gave it ("listening on port N") in LOG; leaves the port in PORT, the PID in LAST_PID.
start_tcp_server() {
    local log=$1
    start_background "$@"
    # shellcheck disable=SC2034  # read by the test that sources this file
    PORT=$(wait_for_log "$log" 'listening on port ([0-9]+)')
}

# free_port : a loopback TCP port the kernel had free a moment ago, for a program that cannot
# be given port 0 and name the port it got (mosquitto, PostgreSQL, a URL written in advance);
# the caller retries or fails loudly should another process take it in between.
free_port() {
    /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# wait_for SECONDS WHAT COMMAND... : runs COMMAND every 20 ms until it succeeds; if it has not
# within SECONDS, fails the test saying it waited for WHAT.
wait_for() {
    local limit=$1 what=$2
    shift 2
    local deadline=$((SECONDS + limit))
    until "$@"; do
        ((SECONDS < deadline)) || fail "waited ${limit} s for ${what}"
        sleep 0.02
    done
}

# wait_for_path PATH [SECONDS] : until PATH exists (10 s by default).
wait_for_path() {
    wait_for "${2:-10}" "$1 to appear" test -e "$1"
}

# wait_for_text FILE TEXT [SECONDS] : until FILE holds TEXT (a fixed string; 10 s by default).
wait_for_text() {
    wait_for "${3:-10}" "'$2' in $1" grep -qsF -- "$2" "$1"
}

# wait_for_log LOG REGEX [SECONDS] : until $WORK_DIR/LOG has a line matching the extended REGEX
# (10 s by default); prints the first capture group of the first such line (sed -E: \1).
wait_for_log() {
    local log=$WORK_DIR/$1 regex=$2
    wait_for "${3:-10}" "/${regex}/ in $1" grep -qsE -- "$regex" "$log"
    sed -nE "s/.*${regex}.*/\\1/p" "$log" | head -n 1
}

# start_mosquitto LIFETIME [CONFIG_LINE]... : a mosquitto broker (Debian's /usr/sbin/mosquitto) for
# LIFETIME seconds on a loopback port nothing listens on now, with the extra configuration lines
# given; returns once it runs, its port in MQTT_PORT and its log in $WORK_DIR/broker.log.
# mosquitto cannot be given port 0 and name the port it got, so the port is one the kernel had
# free a moment before; should another process take it in between, the broker says so and
# exits, and it is started again on a fresh port (a few times, then the test fails).
start_mosquitto() {
    local lifetime=$1 attempt
    shift
    for attempt in 1 2 3 4 5; do
        MQTT_PORT=$(free_port)
        printf '%s\n' "listener $MQTT_PORT 127.0.0.1" "allow_anonymous true" "persistence false" "$@" >"$WORK_DIR/mosquitto.conf"
        start_background broker.log timeout "$lifetime" /usr/sbin/mosquitto -c "$WORK_DIR/mosquitto.conf"
        wait_for 30 "mosquitto to run or exit" mosquitto_settled "$LAST_PID"
        grep -qsF "running" "$WORK_DIR/broker.log" && return 0
        grep -qsF "Address already in use" "$WORK_DIR/broker.log" ||
            fail "mosquitto did not start: $(tail -n 20 "$WORK_DIR/broker.log")"
        echo "mosquitto's port $MQTT_PORT was taken before it bound it (attempt $attempt): another port"
    done
    fail "mosquitto found its port taken $attempt times"
}

# mosquitto_settled PID : whether the broker runs, or its process (PID) has ended.
mosquitto_settled() {
    grep -qsF "running" "$WORK_DIR/broker.log" || ! kill -0 "$1" 2>/dev/null
}

# socat_pair A B : a connected pseudo-terminal pair with links at the two paths.
socat_pair() {
    start_background socat.log timeout "$PEER_LIFETIME" socat \
        "pty,raw,echo=0,link=$1" "pty,raw,echo=0,link=$2"
    wait_for_path "$1"
    wait_for_path "$2"
}

# expect_equal ACTUAL EXPECTED WHAT : stops the test unless ACTUAL is EXPECTED.
expect_equal() {
    [[ $1 == "$2" ]] || fail "$3: expected '$2', got '$1'"
    if ((${#1} > 160)); then echo "ok: $3 = ${1:0:140} ..."; else echo "ok: $3 = $1"; fi
}

# metric PORT NAME : the value of one loopwire_ metric of the gateway's HTTP front on PORT, without
# labels or of its first series; empty when /metrics does not have it.
metric() {
    curl -s --max-time 10 "http://127.0.0.1:$1/metrics" | awk -v name="loopwire_$2" '$1 == name || index($1, name "{") == 1 { print $2; exit }'
}

# --- Tallied checks: a failure is counted and reported, and the test goes on. ---

count_pass() { passes=$((passes + 1)); }

# count_failure NAME [FILE...] : counts a failure, printing NAME and the start of each FILE.
count_failure() {
    local name=$1 file
    shift
    echo "FAIL $name"
    for file in "$@"; do
        [[ -e $file ]] && sed 's/^/    /' "$file" | head -n 40
    done
    failures=$((failures + 1))
}

# check NAME STATUS TEXT COMMAND... : runs COMMAND (20 s at most) and passes when it exits with
# STATUS and its stdout and stderr together contain TEXT.
check() {
    local name=$1 want=$2 text=$3
    shift 3
    local out status=0
    out=$(timeout 20 "$@" 2>&1) || status=$?
    if [[ $status -ne $want || $out != *"$text"* ]]; then
        echo "FAIL $name: status $status (want $want), output:"
        echo "$out" | sed 's/^/    /'
        echo "    (wanted text: $text)"
        failures=$((failures + 1))
    else
        passes=$((passes + 1))
    fi
}

# expect NAME COMMAND... : passes when COMMAND succeeds.
expect() {
    local name=$1
    shift
    if "$@"; then count_pass; else count_failure "$name"; fi
}

# finish : prints the tally; the test's status is non-zero on any failure.
finish() {
    echo "$passes passed, $failures failed"
    [[ $failures -eq 0 ]]
}

# --- A real PostgreSQL server (tests that forward the history to one). ---

# PostgreSQL 15's programs; LOOPWIRE_PG_BIN overrides the folder (as tests/support/postgres_server.hpp).
PG_BIN=${LOOPWIRE_PG_BIN:-/usr/lib/postgresql/15/bin}

# start_postgres [HBA] : a new cluster in $WORK_DIR/pg, listening only on a Unix socket in that
# folder, on a port the kernel had free (the socket's name carries it); HBA is pg_hba.conf's
# text (trust for every local user unless given). Sets PG_HOST (the socket folder) and PG_PORT.
# As root the server runs as `postgres` (setpriv, so the PID is the server's and the EXIT trap
# stops it). Exits 77, shown as skipped with the reason, without PostgreSQL 15.
start_postgres() {
    local hba=${1:-"local all all trust"}
    if [[ ! -x $PG_BIN/initdb || ! -x $PG_BIN/postgres ]]; then
        echo "SKIP: PostgreSQL 15 is not installed ($PG_BIN/initdb missing): apt-get install postgresql-15" >&2
        exit 77
    fi
    PG_HOST=$WORK_DIR/pg
    PG_PORT=$(free_port)
    mkdir -p "$PG_HOST"
    local as=()
    if ((EUID == 0)); then
        id postgres >/dev/null 2>&1 || { echo "SKIP: root without a postgres user to run the server" >&2; exit 77; }
        chown postgres: "$WORK_DIR" "$PG_HOST"
        as=(setpriv --reuid=postgres --regid=postgres --init-groups --)
    fi
    "${as[@]}" "$PG_BIN/initdb" -D "$PG_HOST/data" -U postgres -A trust --no-sync -E UTF8 >"$WORK_DIR/initdb.log" 2>&1 ||
        fail "initdb failed: $(tail -n 20 "$WORK_DIR/initdb.log")"
    printf '%s\n' "$hba" >"$PG_HOST/data/pg_hba.conf"
    start_background postgres.log "${as[@]}" "$PG_BIN/postgres" -D "$PG_HOST/data" -k "$PG_HOST" -p "$PG_PORT" \
        -c listen_addresses= -c fsync=off
    wait_for 120 "PostgreSQL to accept connections" "$PG_BIN/pg_isready" -q -h "$PG_HOST" -p "$PG_PORT" -U postgres
}

# pg_sql SQL [DATABASE] : runs SQL as the superuser and prints the rows unaligned, no headers.
pg_sql() {
    psql -X -q -At -v ON_ERROR_STOP=1 -h "$PG_HOST" -p "$PG_PORT" -U postgres -d "${2:-postgres}" -c "$1"
}
