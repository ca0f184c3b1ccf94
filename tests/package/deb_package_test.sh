#!/usr/bin/env bash
# The Debian package scripts/package makes of this build tree: what it holds (stripped binary,
# man pages, completion, conffile, hardened unit, state folder, maintainer scripts; the debug
# information in the -dbgsym package), lintian without errors, the package unpacked into a
# scratch root and run from there, the unit verified and scored by systemd-analyze, and, as
# root with LOOPWIRE_TEST_DPKG_INSTALL=1, a real dpkg install and purge on this machine.
#   deb_package_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
source=$1 build=$2
work=$(mktemp -d)
installed_by_test=false user_made_by_test=false
cleanup() {
    # A failed install check leaves the machine as it found it too.
    if $installed_by_test; then dpkg --purge loopwire >/dev/null 2>&1 || true; fi
    if $user_made_by_test && getent passwd loopwire >/dev/null; then
        deluser --system --quiet loopwire >/dev/null 2>&1 || true
        delgroup --system --quiet loopwire >/dev/null 2>&1 || true
    fi
    rm -rf "$work"
}
trap cleanup EXIT

fail() { echo "FAIL: $*" >&2; exit 1; }
pass() { echo "PASS: $*"; }
skip() { echo "SKIP: $*"; }
run_logged() {  # log-name, command...: the command's output is shown only when it fails
    local log=$work/$1.log; shift
    "$@" >"$log" 2>&1 || { cat "$log" >&2; fail "$* exited with $?"; }
}

# The tree as the test run has it: packaging it must not build anything.
started=$SECONDS
run_logged package "$source/scripts/package" --no-build "$build"
version=$("$build/loopwire" --version | sed -n 's/^loopwire //p')
arch=$(dpkg --print-architecture)
deb=$build/loopwire_${version}_${arch}.deb
dbgsym=$build/loopwire-dbgsym_${version}_${arch}.deb
[ -f "$deb" ] && [ -f "$dbgsym" ] || fail "scripts/package made no $deb and $dbgsym"
pass "scripts/package made $(basename "$deb") ($(du -k "$deb" | cut -f1) KiB) in $((SECONDS - started)) s"

# --- What the package holds --------------------------------------------------------------
dpkg-deb --contents "$deb" | awk '{print $6}' | sed 's#^\./#/#; s#/$##' >"$work/contents"
expect_in_package() { grep -qxF "$1" "$work/contents" || fail "the package has no $1"; }
for path in /usr/bin/loopwire /usr/share/bash-completion/completions/loopwire /usr/share/zsh/vendor-completions/_loopwire \
            /etc/loopwire/plant.toml /lib/systemd/system/loopwire-gateway.service /var/lib/loopwire \
            /usr/share/doc/loopwire/copyright /usr/share/doc/loopwire/changelog.gz; do
    expect_in_package "$path"
done
# Every man page the build wrote, compressed.
pages=0
for page in "$build"/man/man*/*; do
    expect_in_package "/usr/share/man/$(basename "$(dirname "$page")")/$(basename "$page").gz"
    pages=$((pages + 1))
done
[ "$pages" -ge 2 ] || fail "the build wrote only $pages man page(s) under $build/man"
# The library, headers and CMake package are for developers (cmake --install), not the service.
if grep -E '^/usr/(include|lib/.*\.a$|lib/cmake)' "$work/contents"; then fail "the package holds development files"; fi
pass "the package holds the binary, $pages man pages, bash and zsh completion, plant.toml, the unit, /var/lib/loopwire"

dpkg-deb --control "$deb" "$work/control"
[ "$(cat "$work/control/conffiles")" = /etc/loopwire/plant.toml ] || fail "conffiles is not exactly /etc/loopwire/plant.toml: $(cat "$work/control/conffiles")"
# The commands as sh runs them: continued lines joined.
postinst=$(sed -e ':joined' -e '/\\$/{N;s/\\\n *//;b joined' -e '}' "$work/control/postinst")
grep -q 'adduser --system --group .* loopwire$' <<<"$postinst" || fail "postinst makes no system user loopwire"
grep -q 'adduser --quiet loopwire dialout' <<<"$postinst" || fail "postinst does not put loopwire in dialout"
for script in postinst prerm postrm; do sh -n "$work/control/$script" || fail "$script is not valid sh"; done
depends=$(dpkg-deb --field "$deb" Depends)
grep -q 'libc6 (>= ' <<<"$depends" || fail "Depends names no versioned libc6 (dpkg-shlibdeps): $depends"
grep -qw adduser <<<"$depends" || fail "Depends lacks adduser, which postinst runs: $depends"
if grep -q -- '-dev\b' <<<"$depends"; then fail "Depends names a -dev package: $depends"; fi
pass "conffile, maintainer scripts, Depends: $depends"

unit=$work/unit.service
dpkg-deb --fsys-tarfile "$deb" | tar -xO ./lib/systemd/system/loopwire-gateway.service >"$unit"
for directive in 'Type=notify' 'WatchdogSec=30s' 'ExecStart=/usr/bin/loopwire gateway --config /etc/loopwire/plant.toml' \
                 'ExecReload=/bin/kill -HUP $MAINPID' 'User=loopwire' 'SupplementaryGroups=dialout' \
                 'ProtectSystem=strict' 'ProtectHome=yes' 'PrivateTmp=yes' 'NoNewPrivileges=yes' 'CapabilityBoundingSet=' \
                 'RestrictAddressFamilies=AF_UNIX AF_INET AF_INET6' 'SystemCallFilter=@system-service' \
                 'StateDirectory=loopwire' 'ConfigurationDirectory=loopwire' 'LimitNOFILE=65536' 'DevicePolicy=closed' \
                 'DeviceAllow=char-ttyS rw' 'DeviceAllow=char-ttyUSB rw' 'DeviceAllow=char-ttyACM rw'; do
    grep -qxF "$directive" "$unit" || fail "the unit lacks the line $directive"
done
pass "the unit runs as loopwire, confined, with the serial ports allowed"

# --- Debug information: out of the binary, into the -dbgsym package under its build id ------
dpkg-deb --fsys-tarfile "$deb" | tar -xO ./usr/bin/loopwire >"$work/loopwire"
build_id=$(LC_ALL=C readelf -n "$work/loopwire" | sed -n 's/^ *Build ID: *//p')
[ -n "$build_id" ] || fail "the packaged binary has no build id"
if LC_ALL=C readelf -S "$work/loopwire" | grep -qE '\.debug_|\.symtab'; then fail "the packaged binary is not stripped"; fi
debug_path=/usr/lib/debug/.build-id/${build_id:0:2}/${build_id:2}.debug
dpkg-deb --fsys-tarfile "$dbgsym" | tar -xO ".$debug_path" >"$work/loopwire.debug" || fail "the -dbgsym package has no $debug_path"
LC_ALL=C readelf -S "$work/loopwire.debug" 2>/dev/null | grep -q '\.debug_line' || fail "$debug_path has no line table"
[ "$(dpkg-deb --field "$dbgsym" Depends)" = "loopwire (= $version)" ] || fail "the -dbgsym package does not depend on loopwire (= $version)"
pass "the binary is stripped; its line tables are in the -dbgsym package at $debug_path"

# --- lintian: no error; its warnings are printed ------------------------------------------
if command -v lintian >/dev/null; then
    lintian_out=$(lintian "$deb" 2>&1 | grep -v 'running with root privileges' || true)
    [ -z "$lintian_out" ] || echo "$lintian_out" | sed 's/^/    lintian: /'
    if grep -q '^E:' <<<"$lintian_out"; then fail "lintian reports errors on $(basename "$deb")"; fi
    pass "lintian: no error ($(grep -c '^W:' <<<"$lintian_out" || true) warning(s))"
else
    skip "lintian: not installed (scripts/setup installs it)"
fi

# --- Unpacked into a scratch root and run from there ---------------------------------------
root=$work/root
dpkg-deb --extract "$deb" "$root"
binary=$root/usr/bin/loopwire
[ "$("$binary" --version)" = "loopwire $version" ] || fail "the unpacked loopwire --version does not say loopwire $version"
size=$(stat -c %s "$binary")
[ "$size" -lt $((25 * 1024 * 1024)) ] || fail "the installed binary is $size bytes, over 25 MB"
pass "the unpacked binary runs: loopwire $version, $((size / 1024)) KiB"
# The conffile as shipped, its state folder moved into the scratch root (the state folder of the
# machine is the real install's, below).
sed "s#/var/lib/loopwire#$root/var/lib/loopwire#g" "$root/etc/loopwire/plant.toml" >"$work/plant.toml"
run_logged check "$binary" gateway --check --config "$work/plant.toml"
grep -q "history: $root/var/lib/loopwire/history.db" "$work/check.log" || { cat "$work/check.log"; fail "the plan does not record history in the state folder"; }
pass "loopwire gateway --check accepts /etc/loopwire/plant.toml"

# --- systemd-analyze: the unit verifies, and its exposure is "OK" (at most 2.0) -------------
if command -v systemd-analyze >/dev/null; then
    # The unit as the scratch root has it, its binary and Documentation= pages the root's.
    sed "s#^ExecStart=/usr/bin/loopwire #ExecStart=$binary #" "$unit" >"$work/loopwire-gateway.service"
    verify_out=$(MANPATH=$root/usr/share/man timeout 30 systemd-analyze verify "$work/loopwire-gateway.service" 2>&1) \
        || fail "systemd-analyze verify failed: $verify_out"
    [ -z "$verify_out" ] || fail "systemd-analyze verify is not clean: $verify_out"
    pass "systemd-analyze verify: clean"
    if security_out=$(timeout 30 systemd-analyze security --offline=true "$unit" 2>&1); then
        score=$(sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\) .*/\1/p' <<<"$security_out")
        [ -n "$score" ] || fail "no exposure level in systemd-analyze security's output: $security_out"
        awk -v score="$score" 'BEGIN { exit !(score <= 2.0) }' || { echo "$security_out"; fail "exposure level $score, over 2.0"; }
        pass "systemd-analyze security: exposure level $score"
    elif grep -q "offline" <<<"$security_out"; then
        skip "systemd-analyze security: this systemd has no --offline ($security_out)"
    else
        fail "systemd-analyze security failed: $security_out"
    fi
else
    skip "systemd-analyze: not installed (package systemd)"
fi

# --- A real install and purge on this machine --------------------------------------------
if [ "$(id -u)" -ne 0 ] || [ "${LOOPWIRE_TEST_DPKG_INSTALL:-}" != 1 ]; then
    skip "dpkg -i / --purge: needs root and LOOPWIRE_TEST_DPKG_INSTALL=1 (it installs the package on this machine)"
    exit 0
fi
if dpkg-query -W -f='${Status}' loopwire 2>/dev/null | grep -q 'installed'; then
    skip "dpkg -i / --purge: a loopwire package is installed on this machine already; left alone"
    exit 0
fi
[ -e /usr/bin/loopwire ] && fail "/usr/bin/loopwire exists but belongs to no package; the test will not overwrite it"
getent passwd loopwire >/dev/null || user_made_by_test=true
installed_by_test=true
run_logged dpkg-install dpkg -i "$deb"
IFS=: read -r _ _ uid _ _ home shell < <(getent passwd loopwire) || fail "postinst made no user loopwire"
[ "$uid" -lt 1000 ] && [ "$home" = /var/lib/loopwire ] && [ "$shell" = /usr/sbin/nologin ] \
    || fail "loopwire is no system user: uid $uid, home $home, shell $shell"
id -nG loopwire | grep -qw dialout || fail "user loopwire is not in group dialout: $(id -nG loopwire)"
[ "$(stat -c '%U:%G %a' /var/lib/loopwire)" = "loopwire:loopwire 750" ] || fail "/var/lib/loopwire is $(stat -c '%U:%G %a' /var/lib/loopwire)"
[ -f /etc/loopwire/plant.toml ] || fail "no /etc/loopwire/plant.toml after install"
dpkg-query -W -f='${Conffiles}\n' loopwire | grep -q '/etc/loopwire/plant.toml' || fail "dpkg does not list plant.toml as a conffile"
run_logged check-as-loopwire runuser -u loopwire -- /usr/bin/loopwire gateway --check --config /etc/loopwire/plant.toml
grep -q 'history: /var/lib/loopwire/history.db' "$work/check-as-loopwire.log" || fail "the installed check does not record history in /var/lib/loopwire"
# The enable links an administrator makes, for the purge to take away.
enable_link=/etc/systemd/system/multi-user.target.wants/loopwire-gateway.service
systemctl enable loopwire-gateway.service >/dev/null 2>&1 || true
links="no enable link (systemctl enable made none here)"
[ -L "$enable_link" ] && links="enabled"
pass "dpkg -i: user loopwire (uid $uid, in dialout), /var/lib/loopwire, conffile; gateway --check as loopwire; $links"

run_logged dpkg-purge dpkg --purge loopwire
installed_by_test=false
for path in /usr/bin/loopwire /etc/loopwire /var/lib/loopwire /lib/systemd/system/loopwire-gateway.service \
            "$enable_link"; do
    if [ -e "$path" ] || [ -L "$path" ]; then fail "$path is still there after dpkg --purge"; fi
done
if [ -n "$(find /var/lib/systemd/deb-systemd-helper-enabled -name '*loopwire*' 2>/dev/null)" ]; then
    fail "deb-systemd-helper state for the unit is left after purge"
fi
# Debian keeps a package's system user on purge (postrm says why); the test removes the one it made.
getent passwd loopwire >/dev/null || fail "purge removed the system user loopwire (Debian keeps system users)"
if $user_made_by_test; then
    deluser --system --quiet loopwire >/dev/null 2>&1
    delgroup --system --quiet loopwire >/dev/null 2>&1 || true
    user_made_by_test=false
    if getent passwd loopwire >/dev/null || getent group loopwire >/dev/null; then fail "user or group loopwire left behind"; fi
fi
pass "dpkg --purge: binary, conffile, state folder, unit and enable links gone; the system user kept as Debian does"
pass "all in $((SECONDS - started)) s"
