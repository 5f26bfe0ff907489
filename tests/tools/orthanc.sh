# orthanc.sh - a real PACS for the tests (sourced): Debian's Orthanc with its DICOMweb plugin
# (deploy/install-deps.sh installs both), run by the test as an unprivileged user with its own
# config, storage and log in a directory of the test's, and stopped when the test ends.
#
#   orthanc_start DIR [AET@HOST:PORT ...]   starts it; each argument a DICOM modality it may
#                                           talk to (surfd's SCP first), named by its AE title in
#                                           lower case. ORTHANC_PEER_DICOMWEB=URL adds a DicomWeb
#                                           server "surfd" at URL (credentials: none).
#   orthanc_stop                            stops it (the EXIT trap set by orthanc_start does too)
#   orthanc_curl [CURL ARGS] PATH           curl on its REST API, authenticated (-K: no password
#                                           in argv), PATH relative to $ORTHANC_URL
#   orthanc_upload FILE...                  POST /instances, one file at a time; prints each
#                                           instance's Orthanc id; 1 if one is refused
#   orthanc_send MODALITY ID...             C-STORE of Orthanc resources (instances, series,
#                                           studies: Orthanc ids) to a listed modality, as a
#                                           site's Orthanc sends to surfd (POST
#                                           /modalities/NAME/store, synchronous); 1 if it failed
#
# Sets ORTHANC_URL (http://127.0.0.1:PORT), ORTHANC_DICOMWEB ($ORTHANC_URL/dicom-web),
# ORTHANC_AET (ORTHANC), ORTHANC_DICOM_PORT, ORTHANC_PID, ORTHANC_CREDENTIALS (a 0600 file holding
# "user:password", as surfd reads credentials) and ORTHANC_CURL (the curl config file with them).
#
# What it may do, and why:
# - Every port is on a free loopback port; Orthanc 1.10 has no bind address, so its HTTP server
#   (DICOMweb included) refuses other hosts (RemoteAccessAllowed false) and asks for a password
#   (AuthenticationEnabled, one random user), and its DICOM server answers the listed modalities
#   alone, from their hosts (DicomAlways* false, DicomCheckModalityHost, DicomCheckCalledAet).
# - As root (CI) Orthanc runs as nobody (setpriv: no fork, so ORTHANC_PID is Orthanc's own); DIR
#   is then nobody's, mode 0700, and DIR's parent gets o+x so that nobody can reach it.
# - Nothing is left running: the EXIT trap stops it, and a watchdog stops it when the test's shell
#   is gone without its trap (kill -9).
# - The trap set here replaces the sourcing script's: it runs orthanc_stop, then
#   $ORTHANC_ON_EXIT (default: lib.inc's own trap, stop_daemon and rm -rf "$T").

ORTHANC_BIN=${ORTHANC_BIN:-/usr/sbin/Orthanc}
ORTHANC_PID=""
ORTHANC_WATCH=""
ORTHANC_ON_EXIT=${ORTHANC_ON_EXIT:-'stop_daemon; rm -rf "$T"'}

# A free TCP port on loopback (the kernel's pick: bound, read, closed; orthanc_start tries again
# on the rare port taken in between)
orthanc_free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

orthanc_plugin() { # the DICOMweb plugin's shared object, wherever the package puts it
    for f in /usr/share/orthanc/plugins/libOrthancDicomWeb.so $(dpkg -L orthanc-dicomweb 2>/dev/null | grep '\.so'); do
        [ -e "$f" ] && { echo "$f"; return 0; }
    done
    return 1
}


# orthanc_config AET@HOST:PORT ...: the JSON config, on stdout
orthanc_config() {
    modalities=""
    for m in "$@"; do
        aet=${m%%@*}; rest=${m#*@}; host=${rest%:*}; port=${rest##*:}
        name=$(printf '%s' "$aet" | tr 'A-Z' 'a-z')
        modalities="$modalities${modalities:+,}
    \"$name\": {\"AET\": \"$aet\", \"Host\": \"$host\", \"Port\": $port}"
    done
    servers=""
    [ -n "${ORTHANC_PEER_DICOMWEB:-}" ] && servers="\"surfd\": {\"Url\": \"$ORTHANC_PEER_DICOMWEB\"}"
    cat <<EOF
{
  "Name": "surfd-test",
  "StorageDirectory": "$ORTHANC_DIR/db",
  "IndexDirectory": "$ORTHANC_DIR/db",
  "StorageCompression": false,
  "Plugins": ["$ORTHANC_PLUGIN"],
  "HttpPort": $ORTHANC_HTTP_PORT,
  "RemoteAccessAllowed": false,
  "AuthenticationEnabled": true,
  "RegisteredUsers": {"$ORTHANC_USER": "$ORTHANC_PASSWORD"},
  "OrthancExplorerEnabled": false,
  "WebDavEnabled": false,
  "HttpThreadsCount": 8,
  "HttpRequestTimeout": 30,
  "DicomServerEnabled": true,
  "DicomAet": "$ORTHANC_AET",
  "DicomPort": $ORTHANC_DICOM_PORT,
  "DicomCheckCalledAet": true,
  "DicomCheckModalityHost": true,
  "DicomAlwaysAllowEcho": false,
  "DicomAlwaysAllowStore": false,
  "DicomScuTimeout": 10,
  "DicomModalities": {$modalities
  },
  "SaveJobs": false,
  "ConcurrentJobs": 1,
  "DicomWeb": {
    "Enable": true,
    "Root": "/dicom-web/",
    "EnableWado": false,
    "Servers": {$servers}
  }
}
EOF
}

orthanc_start() {
    ORTHANC_DIR=$1; shift
    [ -x "$ORTHANC_BIN" ] || { echo "Orthanc is not installed (deploy/install-deps.sh installs it)"; return 1; }
    ORTHANC_PLUGIN=$(orthanc_plugin) || { echo "Orthanc's DICOMweb plugin is not installed (orthanc-dicomweb)"; return 1; }
    mkdir -p "$ORTHANC_DIR/db" || return 1
    ORTHANC_AET=ORTHANC
    ORTHANC_USER=surfd-test
    ORTHANC_PASSWORD=$(od -An -N12 -tx1 /dev/urandom | tr -d ' \n')
    ORTHANC_CREDENTIALS="$ORTHANC_DIR/credentials"
    ORTHANC_CURL="$ORTHANC_DIR/curl.conf"
    (umask 077
     printf '%s:%s\n' "$ORTHANC_USER" "$ORTHANC_PASSWORD" >"$ORTHANC_CREDENTIALS"
     printf 'user = "%s:%s"\n' "$ORTHANC_USER" "$ORTHANC_PASSWORD" >"$ORTHANC_CURL")
    as=""
    if [ "$(id -u)" = 0 ]; then
        as="setpriv --reuid=nobody --regid=$(id -g nobody) --clear-groups --"
        chmod o+x "$(dirname "$ORTHANC_DIR")"
        chown nobody "$ORTHANC_DIR" "$ORTHANC_DIR/db"
        chmod 700 "$ORTHANC_DIR" "$ORTHANC_DIR/db"
    fi
    trap 'orthanc_stop; eval "$ORTHANC_ON_EXIT"' EXIT
    for _attempt in 1 2 3; do
        ORTHANC_HTTP_PORT=$(orthanc_free_port) && ORTHANC_DICOM_PORT=$(orthanc_free_port) || return 1
        [ "$ORTHANC_HTTP_PORT" = "$ORTHANC_DICOM_PORT" ] && continue
        ORTHANC_URL="http://127.0.0.1:$ORTHANC_HTTP_PORT"
        ORTHANC_DICOMWEB="$ORTHANC_URL/dicom-web"
        (umask 077; orthanc_config "$@" >"$ORTHANC_DIR/orthanc.json")
        [ "$(id -u)" = 0 ] && chown nobody "$ORTHANC_DIR/orthanc.json"
        # a simple command in the background: the shell's child execs setpriv, which execs Orthanc
        $as "$ORTHANC_BIN" "$ORTHANC_DIR/orthanc.json" >"$ORTHANC_DIR/orthanc.log" 2>&1 &
        ORTHANC_PID=$!
        # the watchdog: Orthanc goes when this shell does, trap or not
        (while kill -0 $$ 2>/dev/null && kill -0 "$ORTHANC_PID" 2>/dev/null; do sleep 1; done
         kill "$ORTHANC_PID" 2>/dev/null) >/dev/null 2>&1 &
        ORTHANC_WATCH=$!
        for _ in $(seq 300); do # 30 s at most: ready when its REST API answers and the plugin is in
            if orthanc_curl -sf /plugins 2>/dev/null | grep -q '"dicom-web"'; then
                return 0
            fi
            kill -0 "$ORTHANC_PID" 2>/dev/null || break
            sleep 0.1
        done
        orthanc_stop
        grep -qi 'address already in use\|cannot bind\|SocketError\|port' "$ORTHANC_DIR/orthanc.log" || break
    done
    echo "Orthanc did not start:"; tail -n 30 "$ORTHANC_DIR/orthanc.log"
    return 1
}

orthanc_stop() {
    [ -n "$ORTHANC_WATCH" ] && kill "$ORTHANC_WATCH" 2>/dev/null
    ORTHANC_WATCH=""
    [ -n "$ORTHANC_PID" ] || return 0
    kill "$ORTHANC_PID" 2>/dev/null
    for _ in $(seq 100); do # 10 s for its clean stop, then kill -9
        kill -0 "$ORTHANC_PID" 2>/dev/null || break
        sleep 0.1
    done
    kill -9 "$ORTHANC_PID" 2>/dev/null
    wait "$ORTHANC_PID" 2>/dev/null
    ORTHANC_PID=""
}

orthanc_curl() {
    n=$#; last=$(eval "printf '%s' \"\${$n}\"")
    args=""; i=1
    while [ $i -lt $n ]; do args="$args \"\${$i}\""; i=$((i + 1)); done
    eval "curl -K \"\$ORTHANC_CURL\" --max-time 60 $args \"\$ORTHANC_URL\$last\""
}

orthanc_upload() {
    for f in "$@"; do
        out=$(orthanc_curl -sf -H 'Content-Type: application/dicom' --data-binary "@$f" -X POST /instances) ||
            { echo "Orthanc refused $f" >&2; return 1; }
        printf '%s\n' "$out" | sed -n 's/.*"ID" *: *"\([^"]*\)".*/\1/p'
    done
}

orthanc_send() {
    m=$1; shift
    ids=""
    for id in "$@"; do ids="$ids${ids:+, }\"$id\""; done
    orthanc_curl -sf -X POST -d "{\"Resources\": [$ids], \"Synchronous\": true}" "/modalities/$m/store" >/dev/null
}
