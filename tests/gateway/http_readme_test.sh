#!/usr/bin/env bash
# The HTTP API commands of README.md and docs/*.md (the curl lines of their sh blocks, all in
# docs/http-api.md), run as written against
# `loopwire gateway` with an [http] table: only the port (the kernel's choice, not 8080) and the
# token file's path (a temporary one, not /etc/loopwire/token) are replaced.
set -u
loopwire=${1:?usage: http_readme_test.sh path/to/loopwire path/to/README.md}
readme=${2:?usage: http_readme_test.sh path/to/loopwire path/to/README.md}
source "$(dirname "$0")/../support/test_lib.sh"

token_file="$WORK_DIR/token"
head -c 24 /dev/urandom | base64 >"$token_file"
chmod 600 "$token_file"
cat >"$WORK_DIR/plant.toml" <<TOML
[[lines]]
name = "plant"
link = "rtu:virtual?baud=19200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:0"
token_file = "$token_file"

[history]
database = "$WORK_DIR/plant.db"
TOML

start_background gateway.log timeout 60 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 20)

mapfile -t examples < <(awk '/^```sh/{f=1;next} /^```/{f=0} f' "$readme" "$(dirname "$readme")"/docs/*.md | grep -E '^curl ')
expect_equal "${#examples[@]}" 5 "curl commands in README.md and docs/"
audit_has_the_write() { "$loopwire" audit --database "$WORK_DIR/plant.db" --format csv | grep -qs set_point; }
cd "$WORK_DIR" || fail "no work dir"
for i in "${!examples[@]}"; do
    command=${examples[$i]//127.0.0.1:8080/127.0.0.1:$port}
    command=${command//\/etc\/loopwire\/token/$token_file}
    # The audit's rows are committed with the history's, every 0.5 s: the write's must be in.
    if [[ $command == *"/api/audit"* ]]; then
        wait_for 10 "the write's audit record" audit_has_the_write
    fi
    status=0
    timeout 30 bash -c "set -o pipefail; $command" >"out-$i.txt" 2>&1 || status=$?
    if [[ $status -eq 0 ]]; then count_pass; else count_failure "README: ${examples[$i]} (exit $status)" "out-$i.txt"; fi
done

check readme-devices 0 '"name":"oven"' cat out-0.txt
check readme-device 0 '"parameters"' cat out-1.txt
check readme-write 0 '{"written":{"set_point":"150"}}' cat out-2.txt
check readme-metrics 0 'loopwire_line_requests_total{line="plant"}' cat out-3.txt
check readme-audit 0 '"front":"http","peer":"127.0.0.1","user":"","device":"oven","parameter":"set_point"' cat out-4.txt
finish
