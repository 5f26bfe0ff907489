#!/bin/sh
# Installs the Debian packages surfd builds, tests and benchmarks with. Idempotent: asks apt only
# for what is missing, so `make run` and CI on a fresh machine call it unconditionally.
# Usage: deploy/install-deps.sh [--bench]   (--bench adds the reference tools: povray, wrk, plastimatch, numpy)
# npm (the machine's, or Debian's when there is none) installs the page's three.js and esbuild for the build
# (client/web/README.md) and the OpenAPI linter and playwright-core the tests use.
set -eu

BUILD="build-essential pkg-config libembree-dev libopenimageio-dev libmicrohttpd-dev libjansson-dev \
libsqlite3-dev libpq-dev postgresql zlib1g-dev libcurl4-openssl-dev libdcmtk-dev libopenjp2-7-dev libgnutls28-dev curl openssl python3 clang libclang-rt-14-dev \
chromium prometheus lintian dicom3tools dcmtk libopenjp2-tools python3-vtk9 python3-pydicom python3-numpy \
libocct-data-exchange-dev libocct-modeling-algorithms-dev orthanc orthanc-dicomweb plastimatch sqlite3" # for the tests: the page in a headless browser, promtool on /metrics, make deb, exported RT Structure Sets (and plastimatch reading their volumes: tests/api/rtstruct_export.sh), the store altered behind its back (sqlite3: tests/api/damage.sh), compressed DICOM made by dcmtk's tools and OpenJPEG's opj_compress, VTK reading our VTP/VTK meshes and its Flying Edges as the isodoses' oracle, multi-frame DICOM (Enhanced CT, RT Dose, Segmentation) written by pydicom, Open CASCADE as the IGES oracle, a real PACS (Orthanc with its DICOMweb plugin: tests/tools/orthanc.sh)
BENCH="povray wrk bc libopenvdb-dev libboost-dev libtbb-dev" # (bc: tests/bench/dicom_net.sh's seconds; OpenVDB: tests/bench/vdb_adaptive.cpp)

want="$BUILD"
[ "${1:-}" = "--bench" ] && want="$want $BENCH"

missing=""
command -v npm >/dev/null 2>&1 || missing="npm" # the build (client/web) and tests/api/openapi_lint.sh use it
for p in $want; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
[ -z "$missing" ] && exit 0

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
echo "install-deps: installing$missing" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q >/dev/null
# shellcheck disable=SC2086
$SUDO apt-get install -y -q --no-install-recommends $missing >/dev/null
# Debian's orthanc starts a system Orthanc (user orthanc, ports 4242 and 8042) when it is installed; the tests start
# their own on free ports (tests/tools/orthanc.sh), so the one installed here is stopped and left disabled
case " $missing " in
*" orthanc "*)
    if [ -d /run/systemd/system ]; then
        $SUDO systemctl disable --now orthanc.service >/dev/null 2>&1 || true
    else
        $SUDO update-rc.d orthanc disable >/dev/null 2>&1 || true
        $SUDO invoke-rc.d orthanc stop >/dev/null 2>&1 || true
    fi ;;
esac
