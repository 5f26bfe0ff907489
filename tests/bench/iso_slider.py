"""An iso slider over HTTP (issue 45): the shared CT posted at iso 226.5 (levels from argv, 1 by default) to a
daemon of 2 workers, then isos 300, 226.5, 500, 100, 226.5 in turn, each `POST /models/{id}/iso?value=V` and
`GET /models/{id}/mesh?format=delta&since=V-1`, as the page asks them; each step's times printed.
Usage: python3 tests/bench/iso_slider.py build/surfd [LEVELS]  (SURFD_DATA: the shared data, ../shared/data)."""
import json, os, re, shutil, subprocess, sys, tempfile, time, urllib.request

surfd = sys.argv[1]
levels = int(sys.argv[2]) if len(sys.argv) > 2 else 1
data = os.environ.get("SURFD_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data"))
tmp = tempfile.mkdtemp(prefix="surfd-slider-")
log = open(os.path.join(tmp, "log"), "w")
d = subprocess.Popen([surfd, "serve", "--listen", "127.0.0.1:0", "--data-dir", os.path.join(tmp, "data"), "--threads", "2",
                      "--log-level", "info"], stdout=log, stderr=log)
try:
    m = None
    for _ in range(400):
        time.sleep(0.05)
        m = re.search(r"listening on http://127\.0\.0\.1:(\d+)", open(os.path.join(tmp, "log")).read())
        if m:
            break
    base = "http://127.0.0.1:%s" % m.group(1)

    def post(url, body):
        req = urllib.request.Request(url, data=body, headers={"Content-Type": "application/octet-stream", "Prefer": "wait=600"})
        with urllib.request.urlopen(req, timeout=600) as r:
            return json.loads(r.read())

    raw = open(os.path.join(data, "volumes", "ct_head_256x256x108_int16.raw"), "rb").read()
    model = post(base + "/isosurface?iso=226.5&dims=256,256,108&type=int16&spacing=0.9570312,0.9570312,1.5&levels=%d" % levels, raw)
    time.sleep(2)  # (the kept extraction made after the answer)
    with urllib.request.urlopen(base + "/models/%s/mesh?format=delta&since=0" % model["id"], timeout=120) as r:
        r.read()
    for v in (300, 226.5, 500, 100, 226.5):
        t0 = time.time()
        e = post(base + "/models/%s/iso?value=%g" % (model["id"], v), b"")
        t1 = time.time()
        with urllib.request.urlopen(base + "/models/%s/mesh?format=delta&since=%d" % (model["id"], e["version"] - 1),
                                    timeout=120) as r:
            n = len(r.read())
        t2 = time.time()
        print("iso %6g  drawn %6.1f ms  request %5.0f ms  delta %5.0f ms (%.1f MB)  step %5.0f ms" % (
            v, e["edit"]["ms"], (t1 - t0) * 1e3, (t2 - t1) * 1e3, n / 1e6, (t2 - t0) * 1e3), flush=True)
finally:
    d.send_signal(2)
    d.wait()
    shutil.rmtree(tmp, ignore_errors=True)
