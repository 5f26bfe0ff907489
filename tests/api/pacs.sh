#!/bin/sh
# surfd and a real PACS (issue 44): Debian's Orthanc with its DICOMweb plugin (tests/tools/orthanc.sh)
# holds the shared CT series and an RT Structure Set, uploaded through its REST API. surfd, told of
# it by --pacs (DICOMweb, credentials from a file) and --pacs NAME=dicom://AET@HOST:PORT (DIMSE),
# searches it (GET /pacs/{name}/studies: QIDO-RS passed through, or a C-FIND answered in the same
# DICOM JSON), pulls a series and a whole study (POST /series/pull: WADO-RS or C-GET into the
# store, as the node keeps what it receives), and sends models back (POST /models/{id}/send:
# STOW-RS and C-STORE), read out of Orthanc again; Orthanc sends to surfd's node (its
# /modalities/surfd/store). A PACS that is down, of either kind, fails the job with a clear
# problem within its bounds, and bad requests are 4xx at the option. surfctl and the Python client
# search, pull, list and send as curl does.
. "$(dirname "$0")/lib.inc"
. tests/tools/orthanc.sh
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27"
RS="${SURFD_DATA:-../shared/data}/contours/dicompyler-core_example_rtss.dcm"
[ -d "$DD" ] && [ -f "$RS" ] || { bad "../shared/data not found"; checks_done; exit 1; }
[ -x "$ORTHANC_BIN" ] || { bad "no Orthanc (deploy/install-deps.sh installs orthanc and orthanc-dicomweb)"; checks_done; exit 1; }
PY=/usr/bin/python3
DP=$(orthanc_free_port)
orthanc_start "$T/orthanc" "SURFD@127.0.0.1:$DP" || { bad "Orthanc did not start"; checks_done; exit 1; }
orthanc_upload "$DD"/*.dcm "$RS" >"$T/ids" || bad "Orthanc refused an upload"
[ -n "${PACS_DEBUG:-}" ] && { echo "$T"; trap '' EXIT; }
echo "ORTHANC 127.0.0.1 $ORTHANC_DICOM_PORT" >"$T/peers"
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" --series-idle 1 \
    --pacs "orthanc=$ORTHANC_DICOMWEB" --pacs-credentials "orthanc=$ORTHANC_CREDENTIALS" \
    --pacs "orthanc-dimse=dicom://$ORTHANC_AET@127.0.0.1:$ORTHANC_DICOM_PORT" --pacs "down=http://127.0.0.1:1/dicom-web" \
    --pacs "down-dimse=dicom://NOBODY@127.0.0.1:1" || exit 1
field() { python3 -c "import json,sys; v = json.load(open(sys.argv[1])); [v := v[k] if not isinstance(v, list) else v[int(k)] for k in sys.argv[2:]]; print(v)" "$T/body" "$@"; }
uid_of() { dcmdump +P "$1" "$2" | head -n 1 | sed "s/.*\\[\\(.*\\)\\].*/\\1/"; }
STUDY=$(uid_of StudyInstanceUID "$DD/IM0001.dcm")
CT=$(uid_of SeriesInstanceUID "$DD/IM0001.dcm")
RSS=$(uid_of SeriesInstanceUID "$RS")
pointer_is() { grep -q "\"pointer\":\"$1\"" "$T/body"; }

# ---- search ----
code=$(status GET "/pacs/orthanc/studies?StudyInstanceUID=$STUDY")
check "GET /pacs/orthanc/studies?StudyInstanceUID=: QIDO-RS's answer, the study found (application/dicom+json)" \
    '[ "$code" = 200 ] && header Content-Type | grep -q "application/dicom+json" && grep -q "$STUDY" "$T/body"'
code=$(status GET "/pacs/orthanc/studies?StudyInstanceUID=1.2.3.4.5")
check "... a study it does not hold: 200, []" '[ "$code" = 200 ] && [ "$(tr -d " \n" <"$T/body")" = "[]" ]'
# the DIMSE PACS: a C-FIND of the same keys, answered in the same DICOM JSON
status GET "/pacs/orthanc/studies?StudyInstanceUID=$STUDY" >/dev/null; cp "$T/body" "$T/qido.json"
code=$(status GET "/pacs/orthanc-dimse/studies?StudyInstanceUID=$STUDY")
check "GET /pacs/orthanc-dimse/studies?StudyInstanceUID=: C-FIND finds the study, its UID, patient, date, series and instances as QIDO-RS gives them" \
    '[ "$code" = 200 ] && header Content-Type | grep -q "application/dicom+json" && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
keys = [\"0020000D\", \"00100020\", \"00100010\", \"00080020\", \"00201206\", \"00201208\"]
sys.exit(0 if len(a) == len(b) == 1 and all(a[0][k] == b[0][k] for k in keys) and a[0][\"0020000D\"][\"Value\"] == [sys.argv[3]] else 1)" "$T/body" "$T/qido.json" "$STUDY"'
PATIENT=$(dcmdump +P PatientID "$DD/IM0001.dcm" | sed 's/.*\[\(.*\)\].*/\1/')
SDATE=$(dcmdump +P StudyDate "$DD/IM0001.dcm" | sed 's/.*\[\(.*\)\].*/\1/')
code=$(status GET "/pacs/orthanc-dimse/studies?PatientID=$PATIENT&StudyDate=$SDATE-")
check "... by PatientID and a StudyDate range: the study" '[ -n "$PATIENT" ] && [ "$code" = 200 ] && grep -q "$STUDY" "$T/body"'
check "... the PatientID searched is nowhere in the daemon's log" '! grep -qF "$PATIENT" "$T/daemon.log"'
code=$(status GET "/pacs/orthanc-dimse/studies?StudyInstanceUID=1.2.3.4.5")
check "... a study it does not hold: 200, []" '[ "$code" = 200 ] && [ "$(tr -d " \n" <"$T/body")" = "[]" ]'
code=$(status GET "/pacs/orthanc-dimse/studies?NoSuchKeyword=1")
check "... a key that is no DICOM attribute: 422 at it" '[ "$code" = 422 ] && pointer_is "?NoSuchKeyword"'
t0=$(date +%s)
code=$(status GET "/pacs/down-dimse/studies?StudyInstanceUID=$STUDY")
t1=$(date +%s)
check "... a DIMSE PACS that is down: a 5xx naming it within 10 s" '[ "$code" -ge 500 ] && grep -q "127.0.0.1:1" "$T/body" && [ $((t1 - t0)) -lt 10 ]'
code=$(status GET "/pacs/nowhere/studies")
check "GET /pacs/{name}/studies of a PACS not configured: 404 naming those that are" '[ "$code" = 404 ] && grep -q "orthanc" "$T/body"'

# ---- pull ----
code=$(status POST "/series/pull?pacs=orthanc&study=$STUDY&series=$CT")
check "POST /series/pull of the CT series: 27 instances kept" '[ "$code" = 200 ] && [ "$(field instances)" = 27 ]'
code=$(status GET "/series/$CT")
check "GET /series/{uid}: pulled from orthanc, 27 instances, 64 x 64 x 27" '[ "$code" = 200 ] && [ "$(field source)" = "pulled from orthanc" ] && [ "$(field dims)" = "[64, 64, 27]" ]'
parts=""; for f in "$DD"/*.dcm; do parts="$parts -F slice=@$f"; done
# shellcheck disable=SC2086
status POST "/isosurface?iso=226.5" $parts >/dev/null; cp "$T/body" "$T/posted.json"
code=$(status POST "/isosurface?iso=226.5&series=$CT")
check "... its isosurface (?series=) the one the files posted give" '[ "$code" = 201 ] && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a[\"triangles\"] == b[\"triangles\"] > 0 and a[\"volume_mm3\"] == b[\"volume_mm3\"] else 1)" "$T/body" "$T/posted.json"'
code=$(status DELETE "/series/$CT")
code=$(status POST "/series/pull?pacs=orthanc&study=$STUDY")
check "a whole study pulled (no ?series): the CT's 27" '[ "$code" = 200 ] && [ "$(field instances)" = 27 ] && [ "$(field series 0 uid)" = "$CT" ]'
code=$(status POST "/series/pull?pacs=orthanc&study=$(uid_of StudyInstanceUID "$RS")")
check "... and the structure set's study: its one instance" '[ "$code" = 200 ] && [ "$(field instances)" = 1 ] && [ "$(status GET "/series/$RSS")" = 200 ]'
check "nothing left in the data dir of the pull's files" '[ -z "$(ls -d "$T"/d/pull-* 2>/dev/null)" ]'
name=$(dcmdump +P PatientName "$DD/IM0001.dcm" | sed 's/.*\[\(.*\)\].*/\1/')
check "the pulled instances hold no patient name ($name)" '[ -n "$name" ] && ! grep -rqaF "$name" "$T/d"'
code=$(status POST "/series/pull?pacs=orthanc&study=1.2.3.4.5")
check "a study the PACS does not hold: the job's 404 or 422, saying so" '[ "$code" = 404 ] || [ "$code" = 422 ]'
code=$(status POST "/series/pull?pacs=orthanc&study=not-a-uid")
check "?study not a UID: 422 at ?study" '[ "$code" = 422 ] && pointer_is "?study"'
# ... and by C-GET from the DIMSE PACS: the same instances, the same isosurface
status DELETE "/series/$CT" >/dev/null
code=$(status POST "/series/pull?pacs=orthanc-dimse&study=$STUDY&series=$CT")
check "POST /series/pull?pacs=orthanc-dimse of the CT series (C-GET): 27 instances kept" \
    '[ "$code" = 200 ] && [ "$(field pacs)" = orthanc-dimse ] && [ "$(field instances)" = 27 ] && [ "$(field series 0 instances)" = 27 ]'
code=$(status GET "/series/$CT")
check "... GET /series/{uid}: pulled from orthanc-dimse, 27 instances, 64 x 64 x 27" '[ "$code" = 200 ] && [ "$(field source)" = "pulled from orthanc-dimse" ] && [ "$(field instances)" = 27 ] && [ "$(field dims)" = "[64, 64, 27]" ]'
code=$(status POST "/isosurface?iso=226.5&series=$CT")
check "... its isosurface the one the files posted give" '[ "$code" = 201 ] && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a[\"triangles\"] == b[\"triangles\"] > 0 and a[\"volume_mm3\"] == b[\"volume_mm3\"] else 1)" "$T/body" "$T/posted.json"'
status DELETE "/series/$CT" >/dev/null
code=$(status POST "/series/pull?pacs=orthanc-dimse&study=$STUDY")
check "... a whole study by C-FIND of its series, then C-GET: the CT's 27" '[ "$code" = 200 ] && [ "$(field instances)" = 27 ] && [ "$(field series 0 uid)" = "$CT" ] && [ "$(status GET "/series/$CT")" = 200 ] && [ "$(field instances)" = 27 ]'
check "... nothing left of the C-GET's files, and no patient name kept" '[ -z "$(ls -d "$T"/d/pull-* 2>/dev/null)" ] && ! grep -rqaF "$name" "$T/d"'
code=$(status POST "/series/pull?pacs=orthanc-dimse&study=$STUDY&series=1.2.3.4.5")
check "... a series it does not hold: the job's 404, saying so" '[ "$code" = 404 ] && grep -q "holds no instances" "$T/body"'
t0=$(date +%s)
code=$(status POST "/series/pull?pacs=down-dimse&study=$STUDY&series=$CT")
t1=$(date +%s)
check "a DIMSE PACS that is down: the pull fails naming it within 10 s, the daemon alive" '[ "$code" -ge 500 ] && grep -q "127.0.0.1:1" "$T/body" && [ $((t1 - t0)) -lt 10 ] && alive'
t0=$(date +%s)
code=$(status POST "/series/pull?pacs=down&study=$STUDY")
t1=$(date +%s)
check "a PACS that is down: the job fails with a 502 naming it, within 30 s, the daemon alive" '[ "$code" = 502 ] && grep -q "127.0.0.1:1" "$T/body" && [ $((t1 - t0)) -lt 30 ] && alive'

# ---- send ----
code=$(status POST "/model?series=$RSS")
cp "$T/body" "$T/models.json"
MODEL=$(field models 0 id); NAME=$(field models 0 name)
before=$(orthanc_curl -s /instances | python3 -c "import json,sys; print(len(json.load(sys.stdin)))")
code=$(status POST "/models/$MODEL/send?pacs=orthanc&as=rtstruct")
check "POST /models/{id}/send?pacs=orthanc&as=rtstruct: STOW-RS, the instance stored" '[ "$code" = 200 ] && [ "$(field instances 0 stored)" = True ]'
SENT=$(field instances 0 sop_instance_uid)
after=$(orthanc_curl -s /instances | python3 -c "import json,sys; print(len(json.load(sys.stdin)))")
ID=$(orthanc_curl -s -X POST -d "$SENT" /tools/lookup | python3 -c "import json,sys; print(json.load(sys.stdin)[0]['ID'])")
orthanc_curl -s "/instances/$ID/file" >"$T/back.dcm"
check "... Orthanc holds it: an RT Structure Set of the model's ROI ($NAME), read back by pydicom" '[ "$after" = $((before + 1)) ] && $PY -c "
import pydicom, sys
d = pydicom.dcmread(sys.argv[1])
sys.exit(0 if d.Modality == \"RTSTRUCT\" and [r.ROIName for r in d.StructureSetROISequence] == [sys.argv[2]] else 1)" "$T/back.dcm" "$NAME"'
code=$(status POST "/models/$MODEL/send?pacs=orthanc&as=dicom-stl")
check "... as=dicom-stl: stored" '[ "$code" = 200 ] && [ "$(field instances 0 stored)" = True ]'
if command -v dciodvfy >/dev/null; then
    dciodvfy "$T/back.dcm" >"$T/vfy" 2>&1
    check "the RT Structure Set read back out of Orthanc: dciodvfy finds no error" '! grep -q "^Error" "$T/vfy"'
else
    bad "no dciodvfy (deploy/install-deps.sh installs dicom3tools)"
fi
code=$(status POST "/models/$MODEL/send?pacs=orthanc&as=seg&spacing=2")
SENT=$(field instances 0 sop_instance_uid)
ID=$(orthanc_curl -s -X POST -d "$SENT" /tools/lookup | python3 -c "import json,sys; print(json.load(sys.stdin)[0]['ID'])" 2>/dev/null)
orthanc_curl -s "/instances/$ID/file" >"$T/seg.dcm"
check "... as=seg (?spacing=2: its CT is not stored): stored, Orthanc holds a Segmentation of its ROI" '[ "$code" = 200 ] && [ "$(field instances 0 stored)" = True ] && $PY -c "
import pydicom, sys
d = pydicom.dcmread(sys.argv[1])
sys.exit(0 if d.Modality == \"SEG\" and [s.SegmentLabel for s in d.SegmentSequence] == [sys.argv[2]] else 1)" "$T/seg.dcm" "$NAME"'
code=$(status POST "/models/$MODEL/send?pacs=orthanc-dimse")
check "... to the DIMSE PACS (C-STORE): stored, status 0" '[ "$code" = 200 ] && [ "$(field instances 0 stored)" = True ] && [ "$(field instances 0 status)" = 0 ]'
MODELS=$(python3 -c "import json,sys; print(','.join(m['id'] for m in json.load(open(sys.argv[1]))['models'][:3]))" "$T/models.json")
code=$(status POST "/rtstruct/send?models=$MODELS&pacs=orthanc")
SENT=$(field instances 0 sop_instance_uid)
ID=$(orthanc_curl -s -X POST -d "$SENT" /tools/lookup | python3 -c "import json,sys; print(json.load(sys.stdin)[0]['ID'])")
orthanc_curl -s "/instances/$ID/file" >"$T/back3.dcm"
check "POST /rtstruct/send?models=A,B,C&pacs=orthanc: one structure set of the three ROIs, stored in Orthanc" '[ "$code" = 200 ] && [ "$(field instances 0 stored)" = True ] && $PY -c "
import pydicom, sys
d = pydicom.dcmread(sys.argv[1])
sys.exit(0 if len(d.StructureSetROISequence) == 3 else 1)" "$T/back3.dcm"'
code=$(status POST "/rtstruct/send?models=$MODELS&pacs=orthanc&as=dicom-stl")
check "... as=dicom-stl of several: 422 at ?as" '[ "$code" = 422 ] && pointer_is "?as"'
code=$(status POST "/models/$MODEL/send?pacs=orthanc&as=nifti")
check "as=nifti (not a DICOM object surfd sends): 422 at ?as" '[ "$code" = 422 ] && pointer_is "?as"'
code=$(status POST "/models/$MODEL/send?pacs=nowhere")
check "an unknown PACS: 422 at ?pacs" '[ "$code" = 422 ] && pointer_is "?pacs"'
code=$(status POST "/models/$MODEL/send?pacs=down")
check "to a PACS that is down: the job fails with a 502, the daemon alive" '[ "$code" = 502 ] && alive'

# ---- Orthanc sends to surfd ----
status DELETE "/series/$CT" >/dev/null
OID=$(orthanc_curl -s -X POST -d "$CT" /tools/lookup | python3 -c "import json,sys; print(json.load(sys.stdin)[0]['ID'])")
orthanc_send surfd "$OID"; rc=$?
code=$(status GET "/series/$CT")
check "Orthanc's C-STORE to surfd (its /modalities/surfd/store): 27 instances received from ORTHANC" '[ $rc = 0 ] && [ "$code" = 200 ] && [ "$(field instances)" = 27 ] && [ "$(field source)" = "received from ORTHANC" ]'

# ---- kill -9 during a pull: the job runs again after the restart, nothing lost or doubled ----
status DELETE "/series/$CT" >/dev/null
code=$(status POST "/series/pull?pacs=orthanc&study=$STUDY&series=$CT" -H 'Prefer: respond-async')
PJ=$(field id)
sleep 0.05
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" --series-idle 1 \
    --pacs "orthanc=$ORTHANC_DICOMWEB" --pacs-credentials "orthanc=$ORTHANC_CREDENTIALS" \
    --pacs "orthanc-dimse=dicom://$ORTHANC_AET@127.0.0.1:$ORTHANC_DICOM_PORT" --pacs "down=http://127.0.0.1:1/dicom-web" || exit 1
for _ in $(seq 100); do [ "$(status GET "/jobs/$PJ")" = 200 ] && [ "$(field state)" = succeeded ] && break; sleep 0.1; done
code=$(status GET "/series/$CT")
check "a pull killed (-9) as it ran: after the restart its job succeeds and the series holds its 27 instances once" '[ "$code" = 200 ] && [ "$(field instances)" = 27 ]'

# ---- the clients ----
export SURFD_URL="$URL"
C=build/surfctl
$C studies orthanc "StudyInstanceUID=$STUDY" >"$T/out" 2>"$T/err"; rc=$?
check "surfctl studies orthanc StudyInstanceUID=...: the PACS's answer, the study in it" '[ $rc = 0 ] && grep -q "$STUDY" "$T/out"'
status DELETE "/series/$CT" >/dev/null
$C pull orthanc "$STUDY" "$CT" >"$T/out" 2>"$T/err"; rc=$?
check "surfctl pull orthanc STUDY SERIES: 27 instances kept" '[ $rc = 0 ] && grep -q "\"instances\":27}" "$T/out"'
$C series "$CT" >"$T/out" 2>"$T/err"; rc=$?
check "surfctl series UID: its resource, pulled from orthanc" '[ $rc = 0 ] && grep -q "pulled from orthanc" "$T/out"'
$C send "$MODEL" orthanc --as dicom-stl >"$T/out" 2>"$T/err"; rc=$?
check "surfctl send ID orthanc --as dicom-stl: stored" '[ $rc = 0 ] && grep -q "\"stored\":true" "$T/out"'
$C send "$MODEL" nowhere >"$T/out" 2>"$T/err"; rc=$?
check "surfctl send ID to an unknown PACS: non-zero, naming ?pacs" '[ $rc != 0 ] && grep -q "pacs" "$T/err"'
$C series "$CT" --delete >/dev/null 2>&1; rc=$?
check "surfctl series UID --delete: gone" '[ $rc = 0 ] && [ "$(status GET "/series/$CT")" = 404 ]'
check "the Python client: studies, pull, series, send" 'PYTHONPATH=client/python python3 -c "
import sys, surfd
c = surfd.Client(sys.argv[1])
assert any(sys.argv[2] in str(s) for s in c.studies(\"orthanc\", StudyInstanceUID=sys.argv[2]))
assert c.pull(\"orthanc\", sys.argv[2], sys.argv[3])[\"instances\"] == 27
assert c.series(sys.argv[3])[\"dims\"] == [64, 64, 27] and any(s[\"uid\"] == sys.argv[3] for s in c.series())
assert c.send(sys.argv[4], \"orthanc\")[\"instances\"][0][\"stored\"] is True
c.delete_series(sys.argv[3])
try:
    c.series(sys.argv[3]); sys.exit(1)
except surfd.SurfdError as e:
    assert e.status == 404
" "$URL" "$STUDY" "$CT" "$MODEL"'

# ---- the cap on a C-GET's instance: max-body under a CT slice's 8 KB of pixels ----
stop_daemon
start_daemon "$T/small" --max-body 4096 --pacs "orthanc-dimse=dicom://$ORTHANC_AET@127.0.0.1:$ORTHANC_DICOM_PORT" || exit 1
code=$(status POST "/series/pull?pacs=orthanc-dimse&study=$STUDY&series=$CT")
check "a C-GET instance over max-body: the job's 422 as it passes 4096 bytes, nothing kept or left, the daemon alive" \
    '[ "$code" = 422 ] && grep -q "over 4096 bytes" "$T/body" && [ "$(status GET "/series/$CT")" = 404 ] && [ -z "$(ls "$T"/small/pull-* 2>/dev/null)" ] && alive'
code=$(status POST "/series/pull?pacs=orthanc-dimse&study=$(uid_of StudyInstanceUID "$RS")&series=$RSS")
check "... the 1.9 MB structure set: the association aborted mid-instance, the same 422, the daemon alive" \
    '[ "$code" = 422 ] && grep -q "over 4096 bytes" "$T/body" && [ -z "$(ls "$T"/small/pull-* 2>/dev/null)" ] && alive'
checks_done
