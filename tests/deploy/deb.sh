#!/bin/sh
# make deb (issue 19): the package lintian passes without errors, installed into a scratch root
# by dpkg (its maintainer scripts told so by DPKG_ROOT), whose surfd serves the page and the API
# with the packaged config, then removed and purged. Needs dpkg-deb and lintian (install-deps).
. "$(dirname "$0")/../api/lib.inc"
deb=$(make -s deb 2>"$T/make.err" | tail -n 1)
check "make deb builds build/surfd_VERSION_amd64.deb" '[ -f "$deb" ] && dpkg-deb -f "$deb" Package | grep -qx surfd'
if ! command -v lintian >/dev/null; then
    bad "no lintian (deploy/install-deps.sh installs it)"
elif [ -f "$deb" ]; then
    lintian --tag-display-limit 0 "$deb" >"$T/lintian" 2>&1
    check "lintian: no errors" '! grep -q "^E:" "$T/lintian"'
    grep "^[EW]:" "$T/lintian"
fi
R=$T/root
mkdir -p "$R/var/lib/dpkg/info" "$R/var/lib/dpkg/updates" "$R/var/lib/dpkg/triggers"
: >"$R/var/lib/dpkg/status"; : >"$R/var/lib/dpkg/available"
dpkg --root="$R" --force-depends --force-script-chrootless --log=/dev/null -i "$deb" >"$T/dpkg.out" 2>&1
check "dpkg installs it into a scratch root" '[ $? -eq 0 ] && dpkg --root="$R" -s surfd 2>/dev/null | grep -q "Status: install ok installed"'
check "... binaries, unit, conffile, Python client, man pages, docs in place" '[ -x "$R/usr/bin/surfd" ] && [ -x "$R/usr/bin/surfctl" ] && [ -f "$R/usr/lib/surfd/libsurfd-image.so" ] && grep -q "^ExecStart=/usr/bin/surfd serve --config /etc/surfd/surfd.conf" "$R/lib/systemd/system/surfd.service" && [ -f "$R/etc/surfd/surfd.conf" ] && [ -f "$R/usr/lib/python3/dist-packages/surfd.py" ] && [ -f "$R/usr/share/man/man1/surfctl.1.gz" ] && [ -f "$R/usr/share/doc/surfd/copyright" ]'
check "... its copyright names the licence of LICENSE (Apache-2.0)" 'grep -qx "License: Apache-2.0" "$R/usr/share/doc/surfd/copyright" && grep -q "Apache License" LICENSE && grep -q "Version 2.0, January 2004" LICENSE'
S="$R/usr/bin/surfd"
start_daemon "$T/d" --config "$R/etc/surfd/surfd.conf" --listen 127.0.0.1:0 || cat "$T/dpkg.out"
code=$(status GET /)
check "the packaged surfd with the packaged config serves the page" '[ "$code" = 200 ] && grep -q "<title>surfd</title>" "$T/body"'
code=$(status POST "/render?width=32&height=24" -H "Content-Type: application/json" --data-binary @"$D/teapot.json")
check "... and renders (its image library found beside it)" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ]'
stop_daemon
dpkg --root="$R" --force-script-chrootless --log=/dev/null -r surfd >/dev/null 2>&1
check "dpkg -r removes the binaries, keeps the conffile" '[ ! -e "$R/usr/bin/surfd" ] && [ -f "$R/etc/surfd/surfd.conf" ]'
dpkg --root="$R" --force-script-chrootless --log=/dev/null -P surfd >/dev/null 2>&1
check "dpkg -P purges the conffile" '[ ! -e "$R/etc/surfd/surfd.conf" ]'
finish
