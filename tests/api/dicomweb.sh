#!/bin/sh
# The DICOMweb client (daemon/dicomweb.c, issue 44) against a real PACS: Debian's Orthanc with its
# DICOMweb plugin (tests/tools/orthanc.sh), given the shared CT series and an RT Structure Set
# through its REST API; driven by tests/tools/dicomweb_tool. QIDO-RS finds the study and series
# (its query values percent-encoded); WADO-RS brings back every instance byte for byte as Orthanc
# holds it, 0600, with its progress, the per-instance cap refusing one byte too few and nothing
# left of the refused instance; STOW-RS sends an RT Structure Set that Orthanc then holds byte for
# byte, and one it refuses is reported failed; wrong and too-open credentials are refused; a PACS
# that is down or stalls fails within its bounded time with a clear message that names no patient.
. "$(dirname "$0")/lib.inc"
. tests/tools/orthanc.sh
TOOL=build/tests/tools/dicomweb_tool
[ -x "$TOOL" ] || { bad "$TOOL is not built (make test builds it)"; checks_done; exit 1; }
DATA="${SURFD_DATA:-../shared/data}"
CT="$DATA/volumes/dicom_ct_head_64x64x27"
RS="$DATA/contours/synthetic_bean.rtstruct.dcm"
RS2="$DATA/contours/synthetic_ellipsoid.rtstruct.dcm"
[ -d "$CT" ] && [ -f "$RS" ] && [ -f "$RS2" ] || { bad "no shared data at $DATA"; checks_done; exit 1; }
chmod 755 "$T" # Orthanc's user (nobody, under root) reaches its directory inside
SCP_PORT=$(orthanc_free_port) # the modality Orthanc sends to: dcmtk's storescp stands in for surfd's SCP
orthanc_start "$T/orthanc" "SURFD@127.0.0.1:$SCP_PORT" || { bad "Orthanc did not start"; checks_done; exit 1; }
dw() { "$TOOL" --credentials "$ORTHANC_CREDENTIALS" "$@"; }
# tag FILE KEYWORD: a DICOM file's value (Debian's pydicom, headers only)
tag() { /usr/bin/python3 -c 'import sys, pydicom; print(getattr(pydicom.dcmread(sys.argv[1], stop_before_pixels=True), sys.argv[2]))' "$1" "$2"; }
# json_get EXPR < JSON: a Python expression over the answer d
json_get() { python3 -c "import json, sys; d = json.load(sys.stdin); print($1)"; }
sums() { for f in "$@"; do sha256sum <"$f"; done | sort; }

STUDY=$(tag "$CT/IM0001.dcm" StudyInstanceUID)
SERIES=$(tag "$CT/IM0001.dcm" SeriesInstanceUID)
RS_PATIENT=$(tag "$RS" PatientID)

# the PACS's contents, through its REST API
orthanc_upload "$CT"/*.dcm "$RS" >"$T/ids"
check "Orthanc took the 27 CT slices and the structure set" '[ "$(wc -l <"$T/ids")" = 28 ]'
check "Orthanc counts 28 instances" \
    '[ "$(orthanc_curl -s /statistics | json_get "d[\"CountInstances\"]")" = 28 ]'

# --- the harness's DICOM side: Orthanc answers its listed modality alone, and sends to it
check "C-ECHO from the listed AE title is answered" \
    'echoscu -aet SURFD -aec ORTHANC -to 5 127.0.0.1 "$ORTHANC_DICOM_PORT" >/dev/null 2>&1'
check "C-ECHO from an AE title Orthanc does not list is refused" \
    '! echoscu -aet STRANGER -aec ORTHANC -to 5 127.0.0.1 "$ORTHANC_DICOM_PORT" >/dev/null 2>&1'
mkdir "$T/scp"
storescp -aet SURFD -od "$T/scp" -ta 5 -td 10 "$SCP_PORT" >"$T/scp.log" 2>&1 &
SCP=$!
for _ in $(seq 50); do echoscu -aec SURFD -to 2 127.0.0.1 "$SCP_PORT" >/dev/null 2>&1 && break; sleep 0.1; done
orthanc_send surfd "$(orthanc_curl -s -X POST -d "$SERIES" /tools/lookup | json_get 'd[0]["ID"]')"; rc=$?
kill $SCP 2>/dev/null; wait $SCP 2>/dev/null
check "Orthanc sends the series to its modality entry (C-STORE: 27 files)" \
    '[ $rc = 0 ] && [ "$(ls "$T/scp" | wc -l)" = 27 ]'

# --- QIDO-RS
dw "$ORTHANC_DICOMWEB" search studies ModalitiesInStudy=CT >"$T/q1"
check "QIDO: one CT study, the series' study" \
    '[ "$(json_get "[s[\"0020000D\"][\"Value\"][0] for s in d]" <"$T/q1")" = "['"'$STUDY'"']" ]'
dw "$ORTHANC_DICOMWEB" search studies >"$T/q2"
check "QIDO: two studies in all" '[ "$(json_get "len(d)" <"$T/q2")" = 2 ]'
dw "$ORTHANC_DICOMWEB" search series "$STUDY" >"$T/q3"
check "QIDO: the study's one series, CT, 27 instances" \
    '[ "$(json_get "[(s[\"0020000E\"][\"Value\"][0], s[\"00080060\"][\"Value\"][0], s[\"00201209\"][\"Value\"][0]) for s in d]" <"$T/q3")" = "[('"'$SERIES', 'CT', 27"')]" ]'
dw "$ORTHANC_DICOMWEB" search studies "PatientID=$RS_PATIENT" >"$T/q4"
check "QIDO: PatientID finds the structure set's study alone" \
    '[ "$(json_get "[s[\"00100020\"][\"Value\"][0] for s in d]" <"$T/q4")" = "['"'$RS_PATIENT'"']" ]'
# a value holding '#', '&' and '=' stays one value: sent bare, '#' would cut the URL there and
# find the patient; encoded, no patient has that ID
dw "$ORTHANC_DICOMWEB" search studies "PatientID=$RS_PATIENT#&ModalitiesInStudy=CT" >"$T/q5"
check "QIDO: query values are percent-encoded" '[ "$(json_get "len(d)" <"$T/q5")" = 0 ]'
dw "$ORTHANC_DICOMWEB" search instances "$STUDY" "$SERIES" limit=5 >"$T/q6"
check "QIDO: the series' instances, limit passed through" '[ "$(json_get "len(d)" <"$T/q6")" = 5 ]'
dw "$ORTHANC_DICOMWEB" search series "1.2.3/../../x" >"$T/out" 2>"$T/err"; rc=$?
check "QIDO: a study UID that is not one is refused before any request" \
    '[ $rc = 1 ] && grep -q "^error -1 .*not a DICOM UID" "$T/err"'

# --- WADO-RS: every instance as Orthanc holds it
orthanc_curl -s "/series/$(orthanc_curl -s -X POST -d "$SERIES" /tools/lookup | json_get 'd[0]["ID"]')/instances" |
    json_get '"\n".join(i["ID"] for i in d)' >"$T/ct_ids"
mkdir "$T/orthanc_files" "$T/w"
while read -r id; do orthanc_curl -s -o "$T/orthanc_files/$id.dcm" "/instances/$id/file"; done <"$T/ct_ids"
dw --expect 27 "$ORTHANC_DICOMWEB" retrieve "$STUDY" "$SERIES" "$T/w" 100000000 >"$T/wado" 2>"$T/err"; rc=$?
check "WADO: the series retrieved ($(tail -n 1 "$T/wado"))" '[ $rc = 0 ] && grep -q "^retrieved 27 instances" "$T/wado"'
check "WADO: 27 files, one an instance, each handed over once" \
    '[ "$(ls "$T/w" | wc -l)" = 27 ] && [ "$(grep -c "^instance " "$T/wado")" = 27 ]'
check "WADO: every instance byte-identical to Orthanc's" \
    '[ "$(sums "$T"/w/*)" = "$(sums "$T"/orthanc_files/*)" ]'
check "WADO: ... and to the files uploaded" '[ "$(sums "$T"/w/*)" = "$(sums "$CT"/*.dcm)" ]'
check "WADO: the files are 0600" '[ -z "$(find "$T/w" -type f ! -perm 0600)" ]'
check "WADO: progress reached 1 over the 27 expected" 'grep -q "progress 1.00$" "$T/wado"'
biggest=$(for f in "$CT"/*.dcm; do wc -c <"$f"; done | sort -n | tail -n 1)
mkdir "$T/w2" "$T/w3"
dw "$ORTHANC_DICOMWEB" retrieve "$STUDY" "$SERIES" "$T/w2" "$biggest" >"$T/out" 2>"$T/err"; rc=$?
check "WADO: a cap of the largest instance's size takes all 27" '[ $rc = 0 ] && [ "$(ls "$T/w2" | wc -l)" = 27 ]'
dw "$ORTHANC_DICOMWEB" retrieve "$STUDY" "$SERIES" "$T/w3" $((biggest - 1)) >"$T/out" 2>"$T/err"; rc=$?
check "WADO: one byte less refuses the largest instance (SF_ELIMIT)" \
    '[ $rc = 1 ] && grep -q "^error -3 .*is over $((biggest - 1)) bytes" "$T/err"'
check "WADO: nothing is left of the instance refused" \
    '[ "$(ls "$T/w3" | wc -l)" = "$(grep -c "^instance " "$T/out")" ] && [ "$(ls "$T/w3" | wc -l)" -lt 27 ]'
mkdir "$T/w4"
dw "$ORTHANC_DICOMWEB" retrieve "$STUDY" "1.2.3.4.5" "$T/w4" 100000000 >"$T/out" 2>"$T/err"; rc=$?
check "WADO: an unknown series is not found (SF_ENOTFOUND)" '[ $rc = 1 ] && grep -q "^error -10 " "$T/err"'
dw "$ORTHANC_DICOMWEB" retrieve "$STUDY" "$SERIES" "$T/w" 100000000 >"$T/out" 2>"$T/err"; rc=$?
check "WADO: an instance's file is never written over" '[ $rc = 1 ] && grep -q "^error -6 .*File exists" "$T/err"'

# --- STOW-RS
RS2_SOP=$(tag "$RS2" SOPInstanceUID)
dw "$ORTHANC_DICOMWEB" store - 10000000 "$RS2" >"$T/stow" 2>"$T/err"; rc=$?
check "STOW: the structure set stored, with its SOP Instance UID" \
    '[ $rc = 0 ] && grep -q "^stored $RS2_SOP 1.2.840.10008.5.1.4.1.1.481.3 0$" "$T/stow" && grep -q "^1 stored, 0 failed" "$T/stow"'
id=$(orthanc_curl -s -X POST -d "$RS2_SOP" /tools/lookup | json_get 'd[0]["ID"]' 2>/dev/null)
orthanc_curl -s -o "$T/stowed.dcm" "/instances/$id/file"
check "STOW: Orthanc holds it, byte-identical" '[ -n "$id" ] && cmp -s "$T/stowed.dcm" "$RS2"'
check "STOW: Orthanc counts 29 instances" \
    '[ "$(orthanc_curl -s /statistics | json_get "d[\"CountInstances\"]")" = 29 ]'
# sent to another study's URL, Orthanc refuses the instance and says so in FailedSOPSequence
dw "$ORTHANC_DICOMWEB" store "$STUDY" 10000000 "$RS" >"$T/stow2" 2>"$T/err"; rc=$?
check "STOW: an instance of another study is reported failed, with its reason" \
    '[ $rc = 0 ] && grep -q "^failed $(tag "$RS" SOPInstanceUID) .* [1-9][0-9]*$" "$T/stow2" && grep -q "^0 stored, 1 failed" "$T/stow2"'
dw "$ORTHANC_DICOMWEB" store - 1000 "$RS2" >"$T/out" 2>"$T/err"; rc=$?
check "STOW: a file over the cap is refused before sending (SF_ELIMIT)" '[ $rc = 1 ] && grep -q "^error -3 " "$T/err"'

# --- credentials
(umask 077; printf 'surfd-test:wrong\n' >"$T/badcred")
"$TOOL" --credentials "$T/badcred" "$ORTHANC_DICOMWEB" search studies >"$T/out" 2>"$T/err"; rc=$?
check "a wrong password: refused, said so" '[ $rc = 1 ] && grep -q "refused surfd.s credentials (HTTP 401)" "$T/err"'
cp "$ORTHANC_CREDENTIALS" "$T/opencred"; chmod 644 "$T/opencred"
"$TOOL" --credentials "$T/opencred" "$ORTHANC_DICOMWEB" search studies >"$T/out" 2>"$T/err"; rc=$?
check "a credentials file others may read is refused" '[ $rc = 1 ] && grep -q "^error -1 .*mode 0644" "$T/err"'
"$TOOL" "http://surfd-test:x@127.0.0.1:1/dicom-web" search studies >"$T/out" 2>"$T/err"; rc=$?
check "a password in the URL is refused" '[ $rc = 1 ] && grep -q "^error -1 .*credentials" "$T/err"'

# --- a PACS that is down: a closed port, 3 attempts 0.5 s then 1 s apart
down=$(orthanc_free_port)
start=$(date +%s%N)
dw "http://127.0.0.1:$down/dicom-web" search studies "PatientID=$RS_PATIENT" >"$T/out" 2>"$T/err"; rc=$?
ms=$((($(date +%s%N) - start) / 1000000))
check "a PACS that is down fails in ${ms} ms (< 5 s), 3 attempts, a clear message" \
    '[ $rc = 1 ] && [ $ms -lt 5000 ] && grep -q "^error -6 .*cannot be reached.*(3 attempts" "$T/err"'
check "... naming no patient" '! grep -q "$RS_PATIENT" "$T/err"'
mkdir "$T/w5"
dw --attempts 1 "http://127.0.0.1:$down/dicom-web" retrieve "$STUDY" "$SERIES" "$T/w5" 1000000 >"$T/out" 2>"$T/err"; rc=$?
check "WADO from a PACS that is down fails, nothing written" '[ $rc = 1 ] && grep -q "cannot be reached" "$T/err" && [ -z "$(ls "$T/w5")" ]'
# a PACS that takes the connection and never answers: the stall timeout ends each attempt
"$PYTHON3" -c '
import socket, sys, time
s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen(8)
print(s.getsockname()[1], flush=True)
held = []
while True:
    c, _ = s.accept(); held.append(c)' >"$T/stall_port" &
STALL=$!
for _ in $(seq 50); do [ -s "$T/stall_port" ] && break; sleep 0.1; done
start=$(date +%s%N)
dw --stall-timeout 1 --attempts 2 "http://127.0.0.1:$(cat "$T/stall_port")/dicom-web" search studies >"$T/out" 2>"$T/err"; rc=$?
ms=$((($(date +%s%N) - start) / 1000000))
kill $STALL 2>/dev/null; wait $STALL 2>/dev/null
check "a PACS that stalls fails in ${ms} ms (2 attempts of a 1 s stall: < 6 s), said so" \
    '[ $rc = 1 ] && [ $ms -lt 6000 ] && [ $ms -ge 2000 ] && grep -q "^error -6 .*did not answer in time.*(2 attempts" "$T/err"'

checks_done
