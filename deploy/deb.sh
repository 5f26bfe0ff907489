#!/bin/sh
# deploy/deb.sh VERSION: build/surfd_VERSION_amd64.deb from the built binaries (make deb runs it):
# surfd and surfctl in /usr/bin (the web page and the spec are compiled in), the OpenImageIO shim
# in /usr/lib/surfd, the systemd unit, the default config as a conffile, the Python client, the
# docs and examples; a system user "surfd" made by postinst. Depends are the packages that hold
# the libraries the binaries link (dpkg -S), at least the versions built against. Plain dpkg-deb,
# no debhelper: the project has no debian/ tree of its own.
set -eu
cd "$(dirname "$0")/.."
V=$1
B=build
S=$B/deb/surfd_${V}_amd64
rm -rf "$B/deb" "$B"/surfd_*_amd64.deb && mkdir -p "$S/DEBIAN"

inst() { # inst MODE SRC DEST
    install -D -m "$1" "$2" "$S/$3"
}
inst 0755 $B/surfd usr/bin/surfd
inst 0755 $B/surfctl usr/bin/surfctl
inst 0644 $B/libsurfd-image.so usr/lib/surfd/libsurfd-image.so
strip --strip-unneeded --remove-section=.comment --remove-section=.note "$S/usr/bin/surfd" "$S/usr/bin/surfctl" \
    "$S/usr/lib/surfd/libsurfd-image.so"
sed 's|/usr/local/|/usr/|g; s|Installed by `make install` as /etc/systemd/system/surfd.service|Installed by the Debian package|' \
    deploy/surfd.service >"$B/deb/surfd.service"
inst 0644 "$B/deb/surfd.service" lib/systemd/system/surfd.service
inst 0644 deploy/surfd.conf etc/surfd/surfd.conf
inst 0644 client/python/surfd.py usr/lib/python3/dist-packages/surfd.py
D=usr/share/doc/surfd
inst 0644 api/openapi.yaml $D/openapi.yaml
for f in client/examples/*.sh; do inst 0644 "$f" "$D/examples/$(basename "$f")"; done
inst 0644 deploy/nginx.conf $D/examples/nginx.conf
gzip -9n -c README.md >"$B/deb/README.md.gz" && inst 0644 "$B/deb/README.md.gz" $D/README.md.gz
cat >"$B/deb/copyright" <<'C'
Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: surfd
Source: the surfd repository

Files: *
Copyright: 2026 the surfd developers
License: Apache-2.0
 Licensed under the Apache License, Version 2.0 (the "License"); you may not use this software
 except in compliance with the License. You may obtain a copy of the License at
 https://www.apache.org/licenses/LICENSE-2.0
 .
 Unless required by applicable law or agreed to in writing, software distributed under the
 License is distributed on an "AS IS" BASIS, WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either
 express or implied. See the License for the specific language governing permissions and
 limitations under the License.
 .
 On Debian systems, the complete text of the Apache License, Version 2.0 can be found in
 "/usr/share/common-licenses/Apache-2.0". The same text is LICENSE in the source tree.
C
inst 0644 "$B/deb/copyright" $D/copyright
{ printf 'surfd (%s) unstable; urgency=medium\n\n  * Built from the repository at %s.\n\n' "$V" "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
  printf ' -- surfd developers <surfd@example.org>  %s\n' "$(date -R -d "@$(git log -1 --format=%ct 2>/dev/null || date +%s)")"; } |
    gzip -9n >"$B/deb/changelog.gz"
inst 0644 "$B/deb/changelog.gz" $D/changelog.gz

# manual pages from the commands' own --help (one source for the usage)
man_page() { # man_page NAME SUMMARY
    { printf '.TH %s 1 "%s" "surfd %s" "User Commands"\n.SH NAME\n%s \\- %s\n.SH SYNOPSIS\n.nf\n' \
          "$(echo "$1" | tr a-z A-Z)" "$(date -u -d "@$(git log -1 --format=%ct 2>/dev/null || date +%s)" +%Y-%m-%d)" "$V" "$1" "$2"
      "$B/$1" --help | sed 's/\\/\\e/g; s/^[.'"'"']/\\\&&/'
      printf '.fi\n.SH SEE ALSO\n%s, /usr/share/doc/surfd/README.md.gz, the API at /openapi.yaml\n' \
          "$([ "$1" = surfd ] && echo 'surfctl(1)' || echo 'surfd(1)')"; } | gzip -9n >"$B/deb/$1.1.gz"
    inst 0644 "$B/deb/$1.1.gz" "usr/share/man/man1/$1.1.gz"
}
man_page surfd "network render and modelling service for free-form surfaces"
man_page surfctl "the command-line client of surfd"

# Depends: the package of every library the binaries link directly (their NEEDED entries), at
# least as new as this machine's
deps=$(for f in "$S/usr/bin/surfd" "$S/usr/bin/surfctl" "$S/usr/lib/surfd/libsurfd-image.so"; do
           for so in $(readelf -d "$f" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'); do
               ldd "$f" | awk -v so="$so" '$1 == so && $2 == "=>" {print $3}'
           done
       done | sort -u | while read -r lib; do
           dpkg -S "$(realpath "$lib")" 2>/dev/null || dpkg -S "$lib" 2>/dev/null
       done | cut -d: -f1 | sort -u | while read -r p; do
           printf '%s (>= %s), ' "$p" "$(dpkg-query -W -f='${Version}' "$p")"
       done)
cat >"$S/DEBIAN/control" <<C
Package: surfd
Version: $V
Architecture: amd64
Maintainer: surfd developers <surfd@example.org>
Installed-Size: $(du -sk "$S" | cut -f1)
Depends: ${deps}adduser
Suggests: python3
Section: science
Priority: optional
Homepage: https://surfd.example.org/
Description: network render and modelling service for free-form surfaces
 surfd ray-traces Bezier, B-spline and NURBS surfaces directly, builds surfaces
 and exact volumes from slice contours (DICOM RT Structure Sets), isosurfaces of
 CT/MRI volumes and FRep objects, and matrix models, each as a queued job over
 HTTP, with a web page at /, the surfctl client and a Python client.
C
printf '/etc/surfd/surfd.conf\n' >"$S/DEBIAN/conffiles"
cat >"$S/DEBIAN/postinst" <<'C'
#!/bin/sh
# the service's system user and its state directory; installed into another root (DPKG_ROOT,
# dpkg --root ... --force-script-chrootless) nothing outside that root is touched
set -e
if [ "$1" = configure ] && [ -z "${DPKG_ROOT:-}" ]; then
    if ! getent passwd surfd >/dev/null; then
        adduser --system --group --home /var/lib/surfd --no-create-home --gecos "surfd service" surfd >/dev/null
    fi
    install -d -m 0750 -o surfd -g surfd /var/lib/surfd
    chgrp surfd /etc/surfd/surfd.conf && chmod 0640 /etc/surfd/surfd.conf
    if [ -d /run/systemd/system ]; then
        systemctl daemon-reload >/dev/null || true
    fi
fi
exit 0
C
cat >"$S/DEBIAN/postrm" <<'C'
#!/bin/sh
# purge removes the state directory (jobs, models) and the user
set -e
if [ "$1" = purge ] && [ -z "${DPKG_ROOT:-}" ]; then
    rm -rf /var/lib/surfd
    if getent passwd surfd >/dev/null; then deluser --system surfd >/dev/null || true; fi
fi
if [ -d /run/systemd/system ] && [ -z "${DPKG_ROOT:-}" ]; then
    systemctl daemon-reload >/dev/null || true
fi
exit 0
C
chmod 0755 "$S/DEBIAN/postinst" "$S/DEBIAN/postrm"
(cd "$S" && find . -type f ! -path './DEBIAN/*' -printf '%P\0' | sort -z | xargs -0 md5sum) >"$S/DEBIAN/md5sums"
dpkg-deb --root-owner-group -Zxz --build "$S" "$B/surfd_${V}_amd64.deb" >/dev/null
echo "$B/surfd_${V}_amd64.deb"
