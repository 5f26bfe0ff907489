#!/bin/sh
# dicom_net.sh N REPEAT [nodelay]: the DICOM network's bench (issue 44), for bench.py's dicom part. A CT
# series of N slices of 256 x 256 (tests/bench/ct_series.py) moved between a real Orthanc and the
# release surfd on this machine, each way timed REPEAT times; prints "what seconds" lines:
#   storescu_orthanc / storescu_surfd   DCMTK's storescu sending the series (C-STORE) to each
#   orthanc_storescp / orthanc_surfd    Orthanc sending it (its /modalities/NAME/store) to DCMTK's
#                                       storescp writing files, and to surfd's node
#   wado_curl / wado_surfd              the series by WADO-RS: curl writing the answer to one file,
#                                       and surfd's POST /series/pull keeping each instance
#   cget_surfd                          surfd's POST /series/pull from Orthanc as a DIMSE PACS (C-GET)
# Every receiver starts empty each time (surfd keeps each SOP Instance UID once: a resent series
# would be no work). DCMTK (storescu, storescp, Orthanc's) leaves Nagle's algorithm on unless
# TCP_NODELAY=1 is in its environment, and then waits on delayed ACKs instance by instance; surfd
# sets it for itself. With "nodelay" every DCMTK process here gets it too, as a site would set it.
N=${1:-300}; REPEAT=${2:-3}
[ "${3:-}" = nodelay ] && export TCP_NODELAY=1
SURFD_BIN=${SURFD_BIN:-./build/surfd}
. "$(dirname "$0")/../api/lib.inc"
. tests/tools/orthanc.sh
/usr/bin/python3 tests/bench/ct_series.py "$N" "$T/ct" >"$T/uids" || exit 1
read -r STUDY SERIES <"$T/uids"
DP=$(orthanc_free_port); SP=$(orthanc_free_port)
orthanc_start "$T/orthanc" "SURFD@127.0.0.1:$DP" "STORESCP@127.0.0.1:$SP" "STORESCU@127.0.0.1:1" >/dev/null || exit 1
printf 'STORESCU 127.0.0.1 1\nORTHANC 127.0.0.1 %s\n' "$ORTHANC_DICOM_PORT" >"$T/peers"
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" --log-level warn \
    --pacs "orthanc=$ORTHANC_DICOMWEB" --pacs-credentials "orthanc=$ORTHANC_CREDENTIALS" \
    --pacs "orthanc-dimse=dicom://$ORTHANC_AET@127.0.0.1:$ORTHANC_DICOM_PORT" >/dev/null || exit 1
now() { date +%s.%N; }
took() { echo "$1 $(echo "$3 - $2" | bc)"; }
clear_orthanc() { for id in $(orthanc_curl -s /studies | tr -d '[]",'); do orthanc_curl -s -X DELETE "/studies/$id" >/dev/null; done; }
clear_surfd() { curl -s -o /dev/null -X DELETE "$URL/series/$SERIES"; }
mkdir -p "$T/scp"
storescp -aet STORESCP -od "$T/scp" "$SP" & SCP=$!
for _ in $(seq "$REPEAT"); do
    clear_orthanc; a=$(now); storescu -aet STORESCU -aec ORTHANC 127.0.0.1 "$ORTHANC_DICOM_PORT" "$T"/ct/*.dcm; b=$(now)
    took storescu_orthanc "$a" "$b"
    clear_surfd; a=$(now); storescu -aet STORESCU -aec SURFD 127.0.0.1 "$DP" "$T"/ct/*.dcm; b=$(now)
    took storescu_surfd "$a" "$b"
    OID=$(orthanc_curl -s -X POST -d "$SERIES" /tools/lookup | tr ',' '\n' | sed -n 's/.*"ID" *: *"\([^"]*\)".*/\1/p' | head -n 1)
    rm -f "$T"/scp/*; a=$(now); orthanc_send storescp "$OID" >/dev/null; b=$(now)
    took orthanc_storescp "$a" "$b"
    clear_surfd; a=$(now); orthanc_send surfd "$OID" >/dev/null; b=$(now)
    took orthanc_surfd "$a" "$b"
    a=$(now); curl -s -K "$ORTHANC_CURL" -H 'Accept: multipart/related; type="application/dicom"' \
        -o "$T/wado" "$ORTHANC_DICOMWEB/studies/$STUDY/series/$SERIES"; b=$(now)
    took wado_curl "$a" "$b"
    clear_surfd; a=$(now); curl -s -o "$T/pull" -X POST "$URL/series/pull?pacs=orthanc&study=$STUDY&series=$SERIES"; b=$(now)
    grep -q "\"instances\":$N}" "$T/pull" || { echo "the pull kept other than $N: $(cat "$T/pull")" >&2; exit 1; }
    took wado_surfd "$a" "$b"
    clear_surfd; a=$(now); curl -s -o "$T/pull" -X POST "$URL/series/pull?pacs=orthanc-dimse&study=$STUDY&series=$SERIES"; b=$(now)
    grep -q "\"instances\":$N}" "$T/pull" || { echo "the C-GET kept other than $N: $(cat "$T/pull")" >&2; exit 1; }
    took cget_surfd "$a" "$b"
done
echo "instances $N"
echo "bytes $(du -sb "$T/ct" | cut -f1)"
kill "$SCP" 2>/dev/null
