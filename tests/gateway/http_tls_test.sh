#!/usr/bin/env bash
# HTTPS on the HTTP API, against the built gateway and real peers (openssl, curl, python):
# - --check refuses a key readable by every user, a key that is not the certificate's, a file
#   that is not PEM, and a certificate without its key, each naming its key in the file;
# - curl with the test's CA reads /api/devices over TLS, with Strict-Transport-Security, and
#   the event stream sends its data over TLS;
# - TLS 1.3 is spoken, TLS 1.1 refused; plain HTTP on the port is closed, the gateway lives on;
# - a client that connects and never says hello is closed after header_timeout;
# - certificate files replaced + SIGHUP: a new connection sees the new subject, while the event
#   stream opened before goes on receiving; a file that no longer loads keeps the running one;
#   a reload that reopens the gateway serves TLS again on the same port.
set -u
loopwire=$(realpath "${1:?usage: http_tls_test.sh path/to/loopwire}")
source "$(dirname "$0")/../support/test_lib.sh"
cd "$WORK_DIR" || exit 1

# ---- a throwaway CA and two server certificates for 127.0.0.1 ---------------------------------
quiet() { "$@" >>openssl.log 2>&1 || fail "$* (openssl.log: $(tail -n 3 openssl.log))"; }
quiet openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 -subj "/CN=loopwire test CA" \
  -keyout ca.key -out ca.crt
for name in one two; do
  quiet openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/CN=loopwire-$name" \
    -keyout "$name.key" -out "$name.csr"
  printf 'subjectAltName=IP:127.0.0.1\n' >san.ext
  quiet openssl x509 -req -in "$name.csr" -CA ca.crt -CAkey ca.key -CAcreateserial -days 2 -extfile san.ext -out "$name.crt"
done
chmod 600 one.key two.key
echo "tls-test-token-1234" >token && chmod 600 token
cp one.crt https.crt
cp one.key https.key

write_config() {  # FILE [HTTP_LINES]
  cat >"$1" <<TOML
[[lines]]
name = "furnace"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven-a"
device = "tc10@3"
poll = "200ms"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:0"
header_timeout = "1s"
token_file = "token"
${2-}
TOML
}

# ---- --check -------------------------------------------------------------------------------------
cp one.key open.key && chmod 644 open.key
write_config open.toml $'certificate = "one.crt"\nprivate_key = "open.key"'
check check-key-readable-by-all 2 'http.private_key' "$loopwire" gateway --config open.toml --check
check check-key-readable-by-all-says 2 'readable by every user' "$loopwire" gateway --config open.toml --check
write_config mismatch.toml $'certificate = "one.crt"\nprivate_key = "two.key"'
check check-key-not-the-certificates 2 'is not the key of the certificate' "$loopwire" gateway --config mismatch.toml --check
echo "not a certificate" >garbage.crt
write_config garbage.toml $'certificate = "garbage.crt"\nprivate_key = "one.key"'
check check-garbage-certificate 2 'garbage.toml:18' "$loopwire" gateway --config garbage.toml --check
check check-garbage-certificate-says 2 'does not load as a certificate' "$loopwire" gateway --config garbage.toml --check
write_config alone.toml 'certificate = "one.crt"'
check check-certificate-alone 2 '`private_key` is missing' "$loopwire" gateway --config alone.toml --check
write_config missing.toml $'certificate = "none.crt"\nprivate_key = "one.key"'
check check-missing-file 2 'http.certificate' "$loopwire" gateway --config missing.toml --check
write_config plant.toml $'certificate = "https.crt"\nprivate_key = "https.key"'
check check-accepts-the-pair 0 "" "$loopwire" gateway --config plant.toml --check

# ---- serving over TLS --------------------------------------------------------------------------
start_background gateway.log "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_pid=$LAST_PID
port=$(wait_for_log gateway.log 'HTTP API and dashboard on https:..127\.0\.0\.1:([0-9]+)' 30)
url=https://127.0.0.1:$port

check curl-devices 0 '"oven-a"' curl -sS --max-time 10 --cacert ca.crt "$url/api/devices"
check curl-hsts 0 'strict-transport-security: max-age=31536000' \
  bash -c "curl -sS --max-time 10 --cacert ca.crt -D - -o /dev/null '$url/api/devices' | tr 'A-Z' 'a-z'"
check dashboard-over-https 0 '<html' curl -sS --max-time 10 --cacert ca.crt "$url/"

# The event stream, opened before the reload below and watched through it.
start_background events.log curl -sS -N --cacert ca.crt "$url/api/events"
events_pid=$LAST_PID
wait_for 20 "the event stream's data over TLS" grep -q '^data:' events.log

subject() {  # what a new connection's certificate says
  openssl s_client -connect "127.0.0.1:$port" -CAfile ca.crt -verify_return_error </dev/null 2>/dev/null |
    sed -nE 's/^subject=.*CN ?= ?([^,]*).*/\1/p'
}
check tls13 0 'New, TLSv1.3, Cipher is TLS_' bash -c "openssl s_client -tls1_3 -connect 127.0.0.1:$port -CAfile ca.crt </dev/null 2>&1"
# Debian's OpenSSL may not offer 1.1 at its default security level: then the client fails on
# its own; at level 0 it offers it and the server must refuse.
tls11=$(timeout 20 openssl s_client -tls1_1 -cipher 'DEFAULT@SECLEVEL=0' -connect "127.0.0.1:$port" </dev/null 2>&1)
echo "TLS 1.1 attempt: $(grep -m1 -iE 'alert|error|Protocol' <<<"$tls11")"
expect tls11-refused-by-the-server grep -q 'alert protocol version' <<<"$tls11"
expect tls11-no-session grep -q 'Cipher is (NONE)' <<<"$tls11"
expect_equal "$(subject)" loopwire-one first-subject

# Plain HTTP on the TLS port: closed without an answer, the gateway goes on.
check plain-http-closed 52 'Empty reply' curl -sS --max-time 10 "http://127.0.0.1:$port/api/devices"
expect alive-after-plain kill -0 "$gateway_pid"

# A client that connects and never says hello is closed after header_timeout (1 s).
closed_after=$(timeout 20 /usr/bin/python3 - "$port" <<'PY'
import socket, sys, time
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])))
start = time.monotonic()
s.settimeout(15)
data = s.recv(100)
print(f"{time.monotonic() - start:.2f} {len(data)}")
PY
)
echo "a silent client was closed after (seconds, bytes): $closed_after"
expect silent-client-closed bash -c "awk '{ exit !(\$1 >= 0.8 && \$1 < 8 && \$2 == 0) }' <<<'$closed_after'"
check curl-after-silent 0 '"oven-a"' curl -sS --max-time 10 --cacert ca.crt "$url/api/devices"

# ---- a new certificate on SIGHUP ----------------------------------------------------------------
cp two.crt https.crt
cp two.key https.key
kill -HUP "$gateway_pid"
wait_for_text gateway.log 're-read for new connections' 20
expect_equal "$(subject)" loopwire-two new-subject
# A write after the reload changes set_point: the stream opened before carries the new value.
check write-after-reload 0 '' curl -sS --max-time 10 --cacert ca.crt -H "Authorization: Bearer tls-test-token-1234" \
  -d '{"set_point": "137"}' "$url/api/devices/oven-a/write"
wait_for 20 "the written set_point on the stream opened before the reload" \
  grep -q '"parameter":"set_point","value":137' events.log
expect stream-still-open kill -0 "$events_pid"
# A certificate file that no longer loads: the reload is refused, the running certificate stays.
echo "truncated" >https.crt
kill -HUP "$gateway_pid"
wait_for_text gateway.log 'configuration not reloaded' 20
expect_equal "$(subject)" loopwire-two subject-kept-on-a-bad-file
check curl-new-certificate 0 '"oven-a"' curl -sS --max-time 10 --cacert ca.crt "$url/api/devices"

# A reload that reopens the gateway ([http] changed, listen kept): the next server speaks TLS with
# the files' certificate on the same port.
cp two.crt https.crt
sed -i 's/^header_timeout = "1s"/header_timeout = "2s"/' plant.toml
kill -HUP "$gateway_pid"
wait_for_text gateway.log 'plant.toml reloaded' 20
wait_for 20 "the reopened gateway to answer over TLS" \
  curl -sS --max-time 5 -o /dev/null --cacert ca.crt "$url/api/devices"
expect_equal "$(subject)" loopwire-two subject-after-a-restarting-reload
check hsts-after-a-restarting-reload 0 'strict-transport-security' \
  bash -c "curl -sS --max-time 10 --cacert ca.crt -D - -o /dev/null '$url/api/devices' | tr 'A-Z' 'a-z'"

kill -TERM "$gateway_pid"
wait_for 30 "the gateway to stop on SIGTERM" bash -c "! kill -0 $gateway_pid 2>/dev/null"
finish
