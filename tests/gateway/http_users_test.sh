#!/usr/bin/env bash
# Users and roles on the HTTP API, against the built gateway with curl:
# - `loopwire passwd` makes the users file (mode 0600; the password from a pipe) and a machine's
#   token; --check names the file and line of a bad line, an unknown role, a bad hash, and refuses
#   a file readable by every user;
# - with open_reads = "none" nothing is read without a login; a login answers a session cookie
#   (HttpOnly, SameSite=Strict) and a CSRF token; a write over the cookie without the token is
#   403, with it 200, and the audit names the user; an operator may not write configuration, a
#   viewer nothing (403 with the reason);
# - a machine's bearer token and the token_file's token write without a cookie; a wrong one is 401;
# - five wrong passwords from one address, then the next is 429 with Retry-After, logged at
#   warning; logout ends the session;
# - a reload (SIGHUP) reads the users file again: a user added logs in, a session open before
#   stays open; open_reads = "loopback" reads without a login from 127.0.0.1.
set -u
loopwire=$(realpath "${1:?usage: http_users_test.sh path/to/loopwire}")
source "$(dirname "$0")/../support/test_lib.sh"
cd "$WORK_DIR" || exit 1

# ---- loopwire passwd ----------------------------------------------------------------------------
check passwd-operator 0 "" sh -c "echo 'op-secret-1' | '$loopwire' passwd users op --role operator"
check passwd-viewer 0 "" sh -c "echo 'view-secret' | '$loopwire' passwd users viewer1 --role viewer"
"$loopwire" passwd users robot --role operator --token >robot.token 2>passwd.err || fail "passwd --token: $(cat passwd.err)"
robot=$(cat robot.token)
expect_equal "${#robot}" 43 "a machine token's length"
expect_equal "$(stat -c %a users)" 600 "the users file's mode"
expect_equal "$(grep -c '^op:operator:\$argon2id\$' users)" 1 "the operator's Argon2id line"
expect_equal "$(grep -c '^robot:operator:token-sha256:' users)" 1 "the machine's token line"
check passwd-empty-stdin 2 "expected the password" sh -c "'$loopwire' passwd users nobody --role viewer </dev/null"
check passwd-bad-role 2 "" "$loopwire" passwd users nobody --role root
check passwd-bad-name 2 "is not a user name" sh -c "echo pw | '$loopwire' passwd users 'a:b' --role viewer"
echo "gateway-token-1234" >token && chmod 600 token

write_config() {  # FILE USERS_FILE OPEN_READS
  cat >"$1" <<TOML
[[lines]]
name = "furnace"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "200ms"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false

[history]
database = "$WORK_DIR/plant.db"

[http]
listen = "127.0.0.1:0"
token_file = "token"
users_file = "$2"
open_reads = "$3"
TOML
}

# ---- --check -------------------------------------------------------------------------------------
cp users bad-line && printf 'mallory root\n' >>bad-line && chmod 600 bad-line
write_config bad-line.toml bad-line none
check check-bad-line 2 "bad-line:4: expected NAME:ROLE:HASH" "$loopwire" gateway --config bad-line.toml --check
cp users bad-role && printf 'mallory:root:%s\n' "$(sed -n 's/^robot:operator://p' users)" >>bad-role && chmod 600 bad-role
write_config bad-role.toml bad-role none
check check-bad-role 2 'bad-role:4: "root" is not a role' "$loopwire" gateway --config bad-role.toml --check
printf 'mallory:admin:plaintext\n' >bad-hash && chmod 600 bad-hash
write_config bad-hash.toml bad-hash none
check check-bad-hash 2 'bad-hash:1: the hash of "mallory" is neither' "$loopwire" gateway --config bad-hash.toml --check
cp users open-users && chmod 644 open-users
write_config open-users.toml open-users none
check check-readable-by-all 2 "readable by every user" "$loopwire" gateway --config open-users.toml --check
write_config plant.toml users none
check check-accepts 0 "" "$loopwire" gateway --config plant.toml --check

# ---- serving -------------------------------------------------------------------------------------
start_background gateway.log timeout 200 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_pid=$LAST_PID
port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 30)
url=http://127.0.0.1:$port
wait_for_text "$WORK_DIR/gateway.log" "device oven (tc10@3) answers" 30

status() { curl -s -o body.json -w '%{http_code}' --max-time 20 "$@"; }
expect_status() {  # NAME STATUS CURL_ARGS...
  local name=$1 want=$2
  shift 2
  local got
  got=$(status "$@")
  if [ "$got" = "$want" ]; then count_pass; else echo "$name: HTTP $got, expected $want: $(cat body.json)"; count_failure "$name"; fi
}
login() {  # USER PASSWORD JAR: the CSRF token
  curl -s --max-time 20 -c "$3" -H 'Content-Type: application/json' -d "{\"user\": \"$1\", \"password\": \"$2\"}" \
    "$url/api/login" | sed -n 's/.*"csrf": *"\([^"]*\)".*/\1/p'
}
write_sp() {  # VALUE CURL_ARGS...: the status of writing the oven's set point
  local value=$1
  shift
  status -X POST -H 'Content-Type: application/json' -d "{\"set_point\": $value}" "$@" "$url/api/devices/oven/write"
}

expect_status reads-need-a-login 401 "$url/api/devices"
expect_status no-session 401 "$url/api/session"
expect_status wrong-password 401 -H 'Content-Type: application/json' -d '{"user":"op", "password": "nope"}' "$url/api/login"
expect_status unknown-user 401 -d 'user=nobody&password=nope' "$url/api/login"
curl -s -D login.headers -o login.json --max-time 20 -c op.jar -d 'user=op&password=op-secret-1' "$url/api/login"
check login-cookie 0 "HttpOnly; SameSite=Strict" cat login.headers
check login-answer 0 '"role":"operator"' cat login.json
csrf=$(sed -n 's/.*"csrf": *"\([^"]*\)".*/\1/p' login.json)
expect_equal "${#csrf}" 43 "the CSRF token's length"
expect_status session-reads 200 -b op.jar "$url/api/devices"
expect_status session-says-who 200 -b op.jar "$url/api/session"
check session-user 0 '"user":"op"' cat body.json
expect_equal "$(write_sp 150 -b op.jar)" 403 "a write over the cookie without X-CSRF-Token"
check csrf-reason 0 "X-CSRF-Token" cat body.json
expect_equal "$(write_sp 150 -b op.jar -H 'X-CSRF-Token: wrong')" 403 "a write with a wrong X-CSRF-Token"
expect_equal "$(write_sp 151 -b op.jar -H "X-CSRF-Token: $csrf")" 200 "the operator's set point write"
expect_status operator-no-configuration 403 -b op.jar -H "X-CSRF-Token: $csrf" -d '{"decimal_point": 1}' \
  "$url/api/devices/oven/write"
check operator-reason 0 'only an admin' cat body.json

viewer_csrf=$(login viewer1 view-secret viewer.jar)
[ -n "$viewer_csrf" ] || fail "the viewer's login"
expect_equal "$(write_sp 152 -b viewer.jar -H "X-CSRF-Token: $viewer_csrf")" 403 "a viewer's write"
check viewer-reason 0 'is a viewer' cat body.json

expect_equal "$(write_sp 153 -H "Authorization: Bearer $robot")" 200 "the machine token's write"
expect_status machine-reads 200 -H "Authorization: Bearer $robot" "$url/api/devices"
expect_equal "$(write_sp 154 -H "Authorization: Bearer wrong-token-123")" 401 "a wrong bearer token"
expect_equal "$(write_sp 155 -H "Authorization: Bearer gateway-token-1234")" 200 "the token_file's token, as an admin"

# The audit names who wrote.
wait_for 20 "the audit's rows" sh -c "curl -s -b op.jar '$url/api/audit' | grep -q '\"user\":\"robot\"'"
check audit-operator 0 '"user":"op"' curl -s --max-time 20 -b op.jar "$url/api/audit"
check audit-viewer-refused 0 '"user":"viewer1"' curl -s --max-time 20 -b op.jar "$url/api/audit"

# Logout ends the session.
expect_status logout-needs-csrf 403 -X POST -b op.jar "$url/api/logout"
expect_status logout 200 -X POST -b op.jar -H "X-CSRF-Token: $csrf" "$url/api/logout"
expect_status after-logout 401 -b op.jar "$url/api/devices"

# Five wrong passwords, then a refusal with the wait, at once and logged.
for i in 1 2 3 4 5; do
  expect_status "wrong-$i" 401 -d 'user=viewer1&password=guess' "$url/api/login"
done
curl -s -D limited.headers -o limited.json --max-time 20 -d 'user=viewer1&password=view-secret' "$url/api/login"
check limited-429 0 "HTTP/1.1 429" cat limited.headers
check limited-retry-after 0 "Retry-After:" cat limited.headers
check limited-logged 0 'failed login as "viewer1" from 127.0.0.1 (its logins wait 1 s)' cat gateway.log
wait_for 10 "the wait to pass" sh -c "[ \"\$(curl -s -o /dev/null -w '%{http_code}' -d 'user=viewer1&password=view-secret' '$url/api/login')\" = 200 ]"

# ---- a reload reads the users file again -----------------------------------------------------
echo 'new-secret' | "$loopwire" passwd users newcomer --role admin 2>/dev/null || fail "passwd newcomer"
write_config plant.toml users loopback
kill -HUP "$gateway_pid"
wait_for 30 "the reload to take the new user" sh -c "[ \"\$(curl -s -o /dev/null -w '%{http_code}' -d 'user=newcomer&password=new-secret' '$url/api/login')\" = 200 ]"
expect_status session-survives-reload 200 -b viewer.jar "$url/api/session"
expect_status open-reads-loopback 200 "$url/api/devices"
expect_equal "$(write_sp 156)" 401 "a write without a login, reads open or not"

kill "$gateway_pid"
finish
