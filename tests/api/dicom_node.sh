#!/bin/sh
# surfd as a DICOM node (issue 44): `serve --dicom-listen PORT --dicom-peers FILE` answers C-ECHO
# and C-STORE from DCMTK's own echoscu and storescu, as a PACS or a planning system would send.
# Peers are held to AE title and address both; a series sent is kept by series in the store (each
# SOP Instance UID once, however often it is sent), listed by GET /series with its geometry, its
# patient's name and ID blanked, and survives a kill -9 right after the sender heard success;
# ?series=UID on /isosurface gives the mesh the same slices posted give, on /model the models
# of a structure set posted, and a received structure set is made into models once complete
# (auto-model), once; an instance over max-body is refused, the node alive.
. "$(dirname "$0")/lib.inc"
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27"
RS="${SURFD_DATA:-../shared/data}/contours/dicompyler-core_example_rtss.dcm"
[ -d "$DD" ] && [ -f "$RS" ] || { bad "../shared/data not found"; checks_done; exit 1; }
command -v storescu >/dev/null || { bad "no storescu (deploy/install-deps.sh installs dcmtk)"; checks_done; exit 1; }
free_port() { python3 -c "import socket; s = socket.socket(); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1])"; }
DP=$(free_port)
cat >"$T/peers" <<EOF
# AE title, host, port
STORESCU  127.0.0.1 11112
FARAWAY   192.0.2.1 104
EOF
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" --series-idle 1 || exit 1
field() { python3 -c "import json,sys; v = json.load(open(sys.argv[1])); [v := v[k] if not isinstance(v, list) else v[int(k)] for k in sys.argv[2:]]; print(v)" "$T/body" "$@"; }
send() { storescu -aet "$1" -aec SURFD 127.0.0.1 "$DP" "$2"/*.dcm >"$T/scu" 2>&1; }

# ---- associations ----
echoscu -aet STORESCU -aec SURFD 127.0.0.1 "$DP" >"$T/scu" 2>&1
check "C-ECHO from a listed peer: success" '[ $? = 0 ]'
echoscu -aet STRANGER -aec SURFD 127.0.0.1 "$DP" >"$T/scu" 2>&1; rc=$?
check "an AE title not listed: refused at association (calling AE title not recognised)" '[ $rc != 0 ] && grep -q "Calling AE Title Not Recognized" "$T/scu"'
echoscu -aet FARAWAY -aec SURFD 127.0.0.1 "$DP" >"$T/scu" 2>&1; rc=$?
check "a listed AE title from another address than its own: refused" '[ $rc != 0 ] && grep -q "Not Recognized" "$T/scu"'
echoscu -aet STORESCU -aec NOTSURFD 127.0.0.1 "$DP" >"$T/scu" 2>&1; rc=$?
check "calling another AE title than the node's: refused" '[ $rc != 0 ] && grep -q "Called AE Title Not Recognized" "$T/scu"'

# ---- C-STORE: a series kept by series ----
send STORESCU "$DD"; rc=$?
check "C-STORE of the CT series' 27 slices: success for each" '[ $rc = 0 ] && ! grep -q "^[EF]:" "$T/scu"'
code=$(status GET /series)
check "GET /series: one series of 27 instances, CT, received from STORESCU" '[ "$code" = 200 ] && [ "$(field series 0 instances)" = 27 ] && [ "$(field series 0 modality)" = CT ] && [ "$(field series 0 source)" = "received from STORESCU" ]'
SUID=$(field series 0 uid)
send STORESCU "$DD"; rc=$?
status GET /series >/dev/null
check "the same 27 sent again: success, and still 27 instances (each SOP Instance UID once)" '[ $rc = 0 ] && [ "$(field series 0 instances)" = 27 ]'
sleep 1.2
code=$(status GET "/series/$SUID")
check "GET /series/{uid}: its dims 64 x 64 x 27, spacing from PixelSpacing and the slice positions, complete after series-idle" \
    '[ "$code" = 200 ] && [ "$(field dims)" = "[64, 64, 27]" ] && [ "$(field spacing)" = "[3.828125, 3.828125, 6.0]" ] && [ "$(field complete)" = True ]'
name=$(dcmdump +P PatientName "$DD/IM0001.dcm" | sed 's/.*\[\(.*\)\].*/\1/')
pid=$(dcmdump +P PatientID "$DD/IM0001.dcm" | sed 's/.*\[\(.*\)\].*/\1/')
check "the stored instances hold neither the patient's name ($name) nor ID ($pid)" '[ -n "$name" ] && [ -n "$pid" ] && ! grep -rqaF "$name" "$T/d" && ! grep -rqaF "$pid" "$T/d" && ! grep -qF "$name" "$T/daemon.log"'
check "the data dir 0700, its files 0600, the spool empty" '[ "$(stat -c %a "$T/d")" = 700 ] && [ -z "$(find "$T/d" -type f ! -perm 600)" ] && [ -z "$(ls "$T/d/spool")" ]'

# ---- a stored series read as a posted one ----
parts=""; for f in "$DD"/*.dcm; do parts="$parts -F slice=@$f"; done
# shellcheck disable=SC2086
code=$(status POST "/isosurface?iso=226.5" $parts); cp "$T/body" "$T/posted.json"
code=$(status POST "/isosurface?iso=226.5&series=$SUID")
check "POST /isosurface?series=UID: the mesh the same slices posted give (triangles, volume, bounds)" '[ "$code" = 201 ] && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a[\"triangles\"] == b[\"triangles\"] > 0 and a[\"volume_mm3\"] == b[\"volume_mm3\"] and a[\"bounds\"] == b[\"bounds\"] else 1)" "$T/body" "$T/posted.json"'
code=$(status POST "/matrix-model?iso=226.5&series=$SUID")
cp "$T/body" "$T/mm.json"
code2=$(status POST "/matrix-model?iso=226.5" $parts)
check "POST /matrix-model?series=UID: the matrix model the same slices posted give" '[ "$code" = 200 ] && [ "$code2" = 200 ] && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
a.pop(\"timings_ms\", None), b.pop(\"timings_ms\", None)
sys.exit(0 if a == b else 1)" "$T/mm.json" "$T/body"'
code=$(status POST "/isosurface?iso=226.5&series=1.2.3.4")
check "?series= a UID not stored: 422 at ?series" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?series\"" "$T/body"'
code=$(status POST "/isosurface?iso=226.5&series=$SUID" -H 'Content-Type: application/dicom' --data-binary @"$DD/IM0001.dcm")
check "?series= with a body: 400 at ?series" '[ "$code" = 400 ] && grep -q "\"pointer\":\"?series\"" "$T/body"'
code=$(status POST "/render?series=$SUID" -H 'Content-Type: application/json' --data-binary '{}')
check "?series= on a route that reads no series: 400 at ?series" '[ "$code" = 400 ] && grep -q "\"pointer\":\"?series\"" "$T/body"'

# ---- an RT Structure Set sent, then modelled ----
mkdir -p "$T/rs" && cp "$RS" "$T/rs/rs.dcm"
send STORESCU "$T/rs"; rc=$?
code=$(status GET /series)
RUID=$(python3 -c "import json,sys; print(next(s['uid'] for s in json.load(open(sys.argv[1]))['series'] if s['modality'] == 'RTSTRUCT'))" "$T/body")
check "an RT Structure Set sent: a series of its own, RTSTRUCT" '[ $rc = 0 ] && [ -n "$RUID" ]'
code=$(status POST "/model" -H 'Content-Type: application/dicom' --data-binary @"$RS"); cp "$T/body" "$T/all.json"
for _ in $(seq 100); do # series-idle (1 s) after it came, the node makes its models
    status GET "/series/$RUID" >/dev/null
    JOB=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['links'].get('job', ''))" "$T/body")
    [ -n "$JOB" ] && [ "$(status GET "$JOB")" = 200 ] && [ "$(field state)" = succeeded ] && break
    sleep 0.1
done
status GET "$JOB/result" >/dev/null
check "auto-model: once complete, the received RT Structure Set made into models by a job (its link), as POST /model of the file makes them" \
    '[ -n "$JOB" ] && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1]))[\"models\"], json.load(open(sys.argv[2]))[\"models\"]
sys.exit(0 if len(a) == len(b) > 1 and [(m[\"name\"], m[\"volume_mm3\"]) for m in a] == [(m[\"name\"], m[\"volume_mm3\"]) for m in b] else 1)" "$T/body" "$T/all.json"'
sleep 1.5
status GET "/series/$RUID" >/dev/null
check "... once: the series still names that job" '[ "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"links\"][\"job\"])" "$T/body")" = "$JOB" ]'
mkdir -p "$T/empty"
/usr/bin/python3 - "$RS" "$T/empty/rs.dcm" <<'PY'
import pydicom, sys
from pydicom.uid import generate_uid
d = pydicom.dcmread(sys.argv[1])
del d.ROIContourSequence                      # a structure set without contours: it makes no model
d.SeriesInstanceUID, d.SOPInstanceUID = generate_uid(), generate_uid()
d.file_meta.MediaStorageSOPInstanceUID = d.SOPInstanceUID
d.save_as(sys.argv[2])
PY
EUID_=$(dcmdump +P SeriesInstanceUID "$T/empty/rs.dcm" | head -n 1 | sed 's/.*\[\(.*\)\].*/\1/')
send STORESCU "$T/empty"
sleep 3.5
status GET "/series/$EUID_" >/dev/null
check "a received structure set that makes no model: no job linked, said once in the log (not retried each second)" \
    '[ "$(python3 -c "import json,sys; print(\"job\" in json.load(open(sys.argv[1]))[\"links\"])" "$T/body")" = False ] && [ "$(grep -c "makes no model" "$T/daemon.log")" = 1 ]'
code=$(status POST "/model?roi=Heart" -H 'Content-Type: application/dicom' --data-binary @"$RS"); cp "$T/body" "$T/posted.json"
code=$(status POST "/model?roi=Heart&series=$RUID")
check "POST /model?series=UID&roi=Heart: the model the file posted makes (volume, contours)" '[ "$code" = 201 ] && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a[\"volume_mm3\"] == b[\"volume_mm3\"] > 0 and a[\"contours\"] == b[\"contours\"] else 1)" "$T/body" "$T/posted.json"'
code=$(status POST "/model?series=$SUID")
check "POST /model?series= a CT series: 422 at ?series (27 instances, not one structure set)" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?series\"" "$T/body"'

# ---- kill -9 right after success: nothing acknowledged is lost ----
code=$(status DELETE "/series/$SUID")
check "DELETE /series/{uid}: 204, then 404" '[ "$code" = 204 ] && [ "$(status GET "/series/$SUID")" = 404 ]'
send STORESCU "$DD"; rc=$?
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" || exit 1
code=$(status GET "/series/$SUID")
check "the series sent again, the daemon killed (-9) as storescu ended: after a restart all 27 are there" '[ $rc = 0 ] && [ "$code" = 200 ] && [ "$(field instances)" = 27 ]'
code=$(status GET "/series/9.9.9..9")
check "GET /series/ a path that is no UID: 404" '[ "$code" = 404 ]'

# ---- an instance surfd cannot keep: refused by its C-STORE status, nothing stored, the node up (a UID
# that is not one storescu will not send: fuzz_instance and test_dicom_scan hold those) ----
mkdir -p "$T/bad"
/usr/bin/python3 - "$DD/IM0001.dcm" "$T/bad" <<'PY'
import pydicom, sys
from pydicom.uid import generate_uid
d = pydicom.dcmread(sys.argv[1])
del d.SeriesInstanceUID                       # no series to keep it by
d.SOPInstanceUID = d.file_meta.MediaStorageSOPInstanceUID = generate_uid()
d.save_as(sys.argv[2] + "/noseries.dcm")
PY
before=$(status GET /series >/dev/null; python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['series']))" "$T/body")
storescu -v -aet STORESCU -aec SURFD 127.0.0.1 "$DP" "$T"/bad/*.dcm >"$T/scu" 2>&1
after=$(status GET /series >/dev/null; python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['series']))" "$T/body")
check "an instance without a SeriesInstanceUID: refused by its C-STORE response (0xC000, cannot understand), no series made, the node up" \
    '[ "$(grep -c "Store Response (Error: CannotUnderstand)" "$T/scu")" = 1 ] && [ "$before" = "$after" ] && alive && echoscu -aet STORESCU -aec SURFD 127.0.0.1 "$DP" >/dev/null 2>&1'

# ---- an instance over max-body ----
stop_daemon
start_daemon "$T/d2" --dicom-listen "$DP" --dicom-peers "$T/peers" --max-body 4096 || exit 1
send STORESCU "$DD"; rc=$?
code=$(status GET /series)
check "instances over max-body (9 KB of 4 KB): refused, none stored, the node alive and answering C-ECHO" '[ $rc != 0 ] && [ "$(field series)" = "[]" ] && alive && echoscu -aet STORESCU -aec SURFD 127.0.0.1 "$DP" >/dev/null 2>&1'
checks_done
