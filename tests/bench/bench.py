#!/usr/bin/env python3
"""Render benchmarks of issue 3, written to tests/bench/RESULTS.md.

Teapot 1024x1024 (eye [7,-10,6], target [0.2,0,1.3], up z, fov 30°), primary rays + shading with
one shadow-casting light, at 1 and 2 threads, every method; teacup, teaspoon and the three ducks
(auto-framed). In the same run: POV-Ray 3.7 on the same Bézier patches and camera
(bicubic_patch type 1, flatness 0, u_steps 5, v_steps 5; its own "Trace Time"), and surfd's mesh
method. Each figure is the median of REPEAT runs; POV-Ray's and auto's runs take turns."""
import json
import urllib.error
import shutil
import os, platform, re, signal, statistics, struct, subprocess, sys, tempfile, time, urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.environ.get("SURFD_DATA", os.path.join(ROOT, "..", "shared", "data"))
SURFD = os.path.join(ROOT, "build", "surfd")
# Every program of the bench runs with glibc's huge pages for its heaps, as surfd gives them itself
# (daemon/main.c): a peer left on 4 KB pages pays a first touch of its output that surfd does not
# (Flying Edges' warm run on the CT head: 87 ms on small pages, 38 on huge ones).
_tunables = os.environ.get("GLIBC_TUNABLES", "")
if "glibc.malloc.hugetlb" not in _tunables:
    os.environ["GLIBC_TUNABLES"] = (_tunables + ":" if _tunables else "") + "glibc.malloc.hugetlb=1"
REPEAT = int(os.environ.get("BENCH_REPEAT", "3"))
W = H = 1024
CAM = {"eye": [7, -10, 6], "target": [0.2, 0, 1.3], "up": [0, 0, 1], "fov_deg": 30}
LIGHT = {"type": "directional", "direction": [-0.5, 0.6, -1.0], "color": [1, 1, 1]}
TMP = tempfile.mkdtemp(prefix="surfd-bench-")


def scene_file(name, camera):
    with open(os.path.join(DATA, "scenes", name)) as f:
        patches = json.load(f)["patches"]
    sc = {"image": {"width": W, "height": H}, "lights": [LIGHT], "objects": patches}
    if camera:
        sc["camera"] = CAM
    path = os.path.join(TMP, name)
    with open(path, "w") as f:
        json.dump(sc, f)
    return path, patches


def surfd_once(inputs, method, threads, w=W, h=H):
    out = os.path.join(TMP, "out.png")
    p = subprocess.run([SURFD, "render", *inputs, "-o", out, "--method", method, "--threads", str(threads),
                        "--width", str(w), "--height", str(h), "--stats"], capture_output=True, text=True)
    if p.returncode:
        sys.exit(f"surfd failed: {p.stderr}")
    return json.loads(p.stderr.strip().splitlines()[-1])


def medians(runs):
    r = dict(runs[0])
    for k in ("prepare_ms", "render_ms", "encode_ms"):
        r[k] = statistics.median(x[k] for x in runs)
    return r


def surfd(inputs, method, threads, w=W, h=H):
    return medians([surfd_once(inputs, method, threads, w, h) for _ in range(REPEAT)])


def povray_scene(patches):
    pov = os.path.join(TMP, "scene.pov")
    with open(pov, "w") as f:
        f.write("#version 3.7;\nglobal_settings { assumed_gamma 1.0 }\n")
        f.write("camera { perspective location <7,-10,6> sky <0,0,1> up <0,0,1> right <-%g,0,0> "
                "look_at <0.2,0,1.3> angle %g }\n" % (W / H, 30.0))  # angle: horizontal fov = vertical at 1:1
        f.write("light_source { <%g,%g,%g>*1000 color rgb 1 }\n" % tuple(-x for x in LIGHT["direction"]))
        f.write("background { color rgb 1 }\n")
        for p in patches:
            pts = ",".join("<%r,%r,%r>" % tuple(q) for q in p["points"])
            f.write("bicubic_patch { type 1 flatness 0 u_steps 5 v_steps 5 %s texture { pigment { color rgb 0.8 } "
                    "finish { specular 0.3 } } }\n" % pts)
    return pov


def povray_once(pov, threads, aa=()):
    p = subprocess.run(["povray", "+I" + pov, "+O" + os.path.join(TMP, "pov.png"), "+W%d" % W, "+H%d" % H,
                        "-D", "+WT%d" % threads, "-V", *aa], capture_output=True, text=True)
    m = re.search(r"Trace Time:.*\(([\d.]+) seconds\)", p.stderr)
    if not m:
        sys.exit("povray: no trace time\n" + p.stderr[-2000:])
    return float(m.group(1)) * 1000


def http_get(url):
    # right after wrk stops, the connections it left waiting for their renders still count against the
    # daemon's per-address limit until those jobs end: a refused connection is retried for a while
    for attempt in range(120):
        try:
            with urllib.request.urlopen(url, timeout=30) as r:
                return r.read().decode()
        except (ConnectionError, urllib.error.URLError):
            if attempt == 119:
                raise
            time.sleep(0.5)


def metric(text, name):
    m = re.search(r"^" + re.escape(name) + r" (\S+)$", text, re.M)
    return float(m.group(1)) if m else 0.0


def rss_kb(pid):
    with open("/proc/%d/status" % pid) as f:
        return int(re.search(r"VmRSS:\s+(\d+)", f.read()).group(1))


def wrk(url, body_path, conns, secs):
    lua = os.path.join(TMP, "post.lua")
    with open(lua, "w") as f:
        f.write('wrk.method = "POST"\nwrk.headers["Content-Type"] = "application/json"\n'
                'local f = io.open("%s", "rb")\nwrk.body = f:read("*a")\nf:close()\n' % body_path)
    p = subprocess.run(["wrk", "-t2", "-c%d" % conns, "-d%ds" % secs, "--timeout", "30s", "--latency", "-s", lua, url],
                       capture_output=True, text=True)
    out = p.stdout
    rps = float(re.search(r"Requests/sec:\s+([\d.]+)", out).group(1))
    def pct(q):
        m = re.search(r"^\s+%s%%\s+([\d.]+)(us|ms|s)" % q, out, re.M)
        return float(m.group(1)) * {"us": 1e-3, "ms": 1.0, "s": 1e3}[m.group(2)] if m else float("nan")
    total = int(re.search(r"(\d+) requests in", out).group(1))
    return rps, pct(50), pct(99), total


def start_daemon(name, *args):
    """surfd serve on a free loopback port, its data and log under TMP/name: (the process, its base URL)."""
    log_path = os.path.join(TMP, name + ".log")
    log = open(log_path, "w")  # a file, never a pipe nobody reads: a full pipe would block the daemon's log
    d = subprocess.Popen([SURFD, "serve", "--listen", "127.0.0.1:0", "--data-dir", os.path.join(TMP, name),
                          "--log-level", "warn", *args], stdout=log, stderr=log)
    for _ in range(200):
        time.sleep(0.05)
        with open(log_path) as f:
            m = re.search(r"listening on http://127\.0\.0\.1:(\d+)", f.read())
        if m:
            return d, "http://127.0.0.1:%d" % int(m.group(1))
    d.terminate()
    sys.exit("surfd serve did not start: see " + log_path)


def http_bench(lines):
    """Issue 4: wrk against the daemon, RSS over 10 000 requests, 1024² over HTTP vs in-process."""
    d, base = start_daemon("srv", "--queue-max", "64")
    small = os.path.join(TMP, "teapot256.json")
    with open(os.path.join(DATA, "scenes", "teapot.json")) as f:
        sc = {"image": {"width": 256, "height": 256}, "camera": CAM, "lights": [LIGHT], "objects": json.load(f)["patches"]}
    with open(small, "w") as f:
        json.dump(sc, f)
    # what a fresh daemon's first render costs (a PNG loads no image library: api/png.c)
    idle = rss_kb(d.pid)
    body = json.dumps(sc).encode()
    first = []
    for _ in range(2):
        t0 = time.monotonic()
        req = urllib.request.Request(base + "/render", data=body, headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as r:
            r.read()
        first.append((time.monotonic() - t0) * 1e3)
    lines.append("First 256x256 render of a fresh daemon %.0f ms (a PNG needs no image library, api/png.c; EXR and "
                 "TIFF load OpenImageIO on the first, api/image.h), the next "
                 "%.0f ms; RSS %.0f MiB idle, %.0f MiB after it.\n" % (first[0], first[1], idle / 1024, rss_kb(d.pid) / 1024))
    lines.append("## HTTP (issue 4): wrk POSTing a 256x256 teapot render, 20 s each\n")
    lines.append("| connections | requests/s | p50 ms | p99 ms | requests | non-2xx other than 429 | left by wrk at its end |")
    lines.append("|---|---|---|---|---|---|---|")
    for conns in (16, 64):
        before = http_get(base + "/metrics")
        rps, p50, p99, total = wrk(base + "/render", small, conns, 20)
        after = http_get(base + "/metrics")
        bad = 0
        for code in ("400", "404", "413", "415", "422", "500", "503", "other"):
            name = 'surfd_http_requests_total{status="%s"}' % code
            bad += metric(after, name) - metric(before, name)
        n429 = metric(after, 'surfd_http_requests_total{status="429"}') - metric(before, 'surfd_http_requests_total{status="429"}')
        left = metric(after, "surfd_http_aborted_total") - metric(before, "surfd_http_aborted_total")
        lines.append("| %d | %.1f | %.1f | %.1f | %d (429: %d) | %d | %d |" % (conns, rps, p50, p99, total, n429, bad, left))
    # RSS over 10 000 requests of a small render (the request path, the store and the pool)
    tiny = os.path.join(TMP, "teapot64.json")
    sc["image"] = {"width": 64, "height": 64}
    with open(tiny, "w") as f:
        json.dump(sc, f)
    wrk(base + "/render", tiny, 8, 3)  # warm up
    r0 = rss_kb(d.pid)
    done0 = metric(http_get(base + "/metrics"), 'surfd_http_requests_total{status="200"}')
    while metric(http_get(base + "/metrics"), 'surfd_http_requests_total{status="200"}') - done0 < 10000:
        wrk(base + "/render", tiny, 8, 5)
    n = metric(http_get(base + "/metrics"), 'surfd_http_requests_total{status="200"}') - done0
    r1 = rss_kb(d.pid)
    lines.append("")
    lines.append("RSS over %d requests (64x64 renders, 8 connections, after a warm-up): %.1f MiB -> %.1f MiB "
                 "(%+.1f %%, target < 10 %%).\n" % (n, r0 / 1024, r1 / 1024, 100.0 * (r1 - r0) / r0))
    # 1024² end to end over HTTP against the same render in-process, once the jobs wrk left behind
    # (queued or running when it stopped) are done, so the request has the daemon to itself
    for _ in range(600):
        m = http_get(base + "/metrics")
        if metric(m, "surfd_store_queued") + metric(m, 'surfd_jobs{state="running"}') == 0:
            break
        time.sleep(0.1)
    big, _ = scene_file("teapot.json", True)
    walls = []
    for _ in range(REPEAT):
        t0 = time.monotonic()
        subprocess.run(["curl", "-sf", "-o", os.path.join(TMP, "h.png"), "-H", "Content-Type: application/json",
                        "--data-binary", "@" + big, base + "/render"], check=True)
        walls.append((time.monotonic() - t0) * 1000)
    http_ms = statistics.median(walls)
    r = surfd([big], "auto", os.cpu_count())
    inproc = r["prepare_ms"] + r["render_ms"] + r["encode_ms"]
    lines.append("1024x1024 teapot: over HTTP (curl, wall) %.1f ms; in-process (prepare + render + encode) %.1f ms; "
                 "ratio %.2f (target <= 1.3).\n" % (http_ms, inproc, http_ms / inproc))
    d.send_signal(signal.SIGTERM)
    d.wait(timeout=60)


def volume_of(data, **options):
    """surfd volume on the contour JSON `data` with the given options put in it: the figures, or None."""
    path = os.path.join(TMP, "c.json")
    with open(path, "w") as f:
        json.dump(dict(data, **options), f)
    p = subprocess.run([SURFD, "volume", path], capture_output=True, text=True)
    return json.loads(p.stdout) if p.returncode == 0 else None


def contour_bench(lines):
    """Issue 5: surfd's volumes beside the reference figures in the shared files, and timings."""
    cdir = os.path.join(DATA, "contours")
    with open(os.path.join(cdir, "reference_volumes.json")) as f:
        refs = json.load(f)["files"]
    lines.append("## Contours (issue 5): volumes in cm3, parabolic method\n")
    lines.append("| file | flat caps | slab caps | dome caps | trapezoid | Cavalieri | references (file's own) | exact (synthetic) |")
    lines.append("|---|---|---|---|---|---|---|---|")
    for name in sorted(os.listdir(cdir)):
        if not name.endswith(".json") or name == "reference_volumes.json":
            continue
        with open(os.path.join(cdir, name)) as f:
            data = json.load(f)
        figs = {caps: volume_of(data, caps=caps) for caps in ("flat", "slab", "dome")}
        if not figs["flat"]:
            lines.append("| %s | failed | | | | | | |" % name)
            continue
        cc = lambda v: "%.2f" % (v / 1000.0)
        exact = data.get("exact_volume_between_end_slices_mm3")
        ex = ""
        if exact:
            solid = data["exact_volume_mm3"]
            ex = "between end slices %s: flat %+.3f %%; solid %s: slab %+.3f %%, dome %+.3f %%" % (
                cc(exact), 100 * (figs["flat"]["volume_mm3"] - exact) / exact, cc(solid),
                100 * (figs["slab"]["volume_mm3"] - solid) / solid, 100 * (figs["dome"]["volume_mm3"] - solid) / solid)
        r = data.get("reference_volumes_cc") or {}
        rs = "; ".join("%s %.2f" % (k.split(" ")[0], v) for k, v in r.items())
        lines.append("| %s | %s | %s | %s | %s | %s | %s | %s |" % (name, cc(figs["flat"]["volume_mm3"]),
                     cc(figs["slab"]["volume_mm3"]), cc(figs["dome"]["volume_mm3"]), cc(figs["flat"]["volume"]["trapezoid"]),
                     cc(figs["flat"]["volume"]["cavalieri"]), rs, ex))
    methods_table(lines, cdir, refs)
    p = subprocess.run([SURFD, "volume", os.path.join(cdir, "dicompyler_heart.json"), "--repeat", "20"],
                       capture_output=True, text=True)
    t = json.loads(p.stdout)["timings_ms"]
    lines.append("")
    lines.append("Heart (33 slices, up to 178 points), warm (`surfd volume FILE --repeat 20`, last run): read %.1f ms; "
                 "model + exact volume %.1f ms (target < 10 ms): the curves fitted and the exact volume (closed form) "
                 "%.1f ms, the closed solid as exact Bezier patches from the same curves %.1f ms; area, quadrature and "
                 "10x10 grid cross-checks %.1f ms more.\n"
                 % (t["read"], t["fit"] + t["volume"], t["volume"], t["fit"], t["measure"]))
    for rs in ("dicompyler-core_example_rtss.dcm", "slicerrt_EclipseProstatePhantom_RS.dcm"):
        rtstruct_bench(lines, os.path.join(cdir, rs))


def methods_table(lines, cdir, refs):
    """The four methods of METHODS.md side by side (caps flat; dome against the exact solid)."""
    methods = ("parabolic", "parabolic/polar", "linear-parabolic", "coons", "bspline")
    lines.append("")
    lines.append("### The four methods (cm3; synthetic shapes: error against the exact volume between the end slices "
                 "with flat caps, against the exact solid with dome caps)\n")
    lines.append("| file | " + " | ".join(methods) + " |")
    lines.append("|---|" + "---|" * len(methods))
    for name in ("synthetic_ellipsoid.json", "synthetic_bean.json", "synthetic_torus_branching.json",
                 "eclipse_bladder.json", "eclipse_ptv.json", "dicompyler_heart.json"):
        with open(os.path.join(cdir, name)) as f:
            data = json.load(f)
        cells = []
        for m in methods:
            param = "polar" if m.endswith("/polar") else "arc-length"
            out = {caps: volume_of(data, method=m.split("/")[0], caps=caps, parameterisation=param)
                   for caps in ("flat", "dome")}
            if not out["flat"]:
                cells.append("failed")
                continue
            v = out["flat"]["volume_mm3"]
            exact = data.get("exact_volume_between_end_slices_mm3")
            if exact:
                solid = data["exact_volume_mm3"]
                cells.append("%.2f (%+.3f %%; dome %+.3f %%)" % (v / 1000, 100 * (v - exact) / exact,
                                                               100 * (out["dome"]["volume_mm3"] - solid) / solid))
            else:
                cells.append("%.2f (dome %.2f)" % (v / 1000, out["dome"]["volume_mm3"] / 1000))
        lines.append("| %s | %s |" % (name, " | ".join(cells)))


def rtstruct_bench(lines, path):
    """surfd on a whole RT Structure Set beside plastimatch (voxelised masks) on the same file."""
    runs, full = [], []
    for _ in range(5):
        p = subprocess.run([SURFD, "volume", path, "--repeat", "3"], capture_output=True, text=True)
        ms = json.loads(p.stdout)["models"]
        runs.append(sum(m["timings_ms"]["read"] + m["timings_ms"]["volume"] for m in ms))
        full.append(sum(sum(m["timings_ms"].values()) for m in ms))
    slab = {m["name"]: m["volume_mm3"] for m in json.loads(subprocess.run(
        [SURFD, "volume", path, "--caps", "slab"], capture_output=True, text=True).stdout)["models"]}
    pm, pm_ms = {}, None
    if shutil.which("plastimatch"):
        out = os.path.join(TMP, "pm")
        shutil.rmtree(out, ignore_errors=True)
        walls = []
        for _ in range(3):
            t0 = time.monotonic()
            subprocess.run(["plastimatch", "convert", "--input", path, "--output-prefix", out],
                           capture_output=True, check=True)
            walls.append((time.monotonic() - t0) * 1000)
        pm_ms = statistics.median(walls)
        for f in sorted(os.listdir(out)):
            hdr = subprocess.run(["plastimatch", "header", os.path.join(out, f)], capture_output=True, text=True).stdout
            st = subprocess.run(["plastimatch", "stats", os.path.join(out, f)], capture_output=True, text=True).stdout
            sp = [float(x) for x in re.search(r"Spacing = ([-0-9. ]+)", hdr).group(1).split()]
            nz = int(re.search(r"NONZERO (\d+)", st).group(1))
            pm[f[:-4]] = nz * sp[0] * sp[1] * sp[2]
    lines.append("")
    lines.append("%s (%d ROIs with contours), warm, median of 5: surfd reads, cleans, chains and gives the exact "
                 "volume of every ROI in %.1f ms (target < 100 ms); with every ROI's closed solid as patches and the "
                 "cross-checks, %.1f ms. plastimatch 1.9.4 `convert --output-prefix` (voxel masks at its default "
                 "grid) on the same file: %s ms (wall, median of 3).\n"
                 % (os.path.basename(path), len(ms), statistics.median(runs), statistics.median(full),
                    "%.0f" % pm_ms if pm_ms else "not installed"))
    lines.append("| ROI | surfd flat | surfd slab | plastimatch voxels |")
    lines.append("|---|---|---|---|")
    for m in ms:
        v = pm.get(m["name"])
        lines.append("| %s | %.2f | %.2f | %s |" % (m["name"], m["volume_mm3"] / 1000, slab[m["name"]] / 1000,
                                                    "%.2f" % (v / 1000) if v is not None else "-"))
    lines.append("")


def pg_cluster(path):
    """A throwaway PostgreSQL (tests/tools/pg.inc) in path: its URI."""
    subprocess.run(["sh", "-c", '. tests/tools/pg.inc && pg_start "$1"', "sh", path], cwd=ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    return "postgresql:///surfd?host=%s&user=surfd" % path


def pg_cluster_stop(path):
    subprocess.run(["sh", "-c", '. tests/tools/pg.inc && PG_DIR="$1" && pg_stop', "sh", path], cwd=ROOT)


def start_node(name, store, threads=2, lease=30):
    log_path = os.path.join(TMP, name + ".log")
    log = open(log_path, "w")
    args = [SURFD, "serve", "--listen", "127.0.0.1:0", "--data-dir", os.path.join(TMP, name), "--log-level", "warn",
            "--threads", str(threads), "--queue-max", "100000", "--node-name", name, "--lease", str(lease),
            "--sync-wait", "3600"]  # a long job is answered, not 202
    if store:
        args += ["--store", store]
    d = subprocess.Popen(args, stdout=log, stderr=log)
    for _ in range(400):
        time.sleep(0.05)
        with open(log_path) as f:
            m = re.search(r"listening on http://127\.0\.0\.1:(\d+)", f.read())
        if m:
            return d, "http://127.0.0.1:%s" % m.group(1)
    raise RuntimeError("node %s did not start" % name)


def post(url, body, headers):
    req = urllib.request.Request(url, data=body, headers=headers, method="POST")
    with urllib.request.urlopen(req, timeout=120) as r:
        return json.loads(r.read().decode())


def job(base, jid):
    return json.loads(http_get(base + "/jobs/" + jid))


def stamp_s(t):
    import datetime
    return datetime.datetime.strptime(t, "%Y-%m-%dT%H:%M:%S.%fZ").replace(tzinfo=datetime.timezone.utc).timestamp()


def throughput(bases, n):
    """n small contour volumes posted async round the nodes from 8 clients: jobs/s from the first post
    to the last end, and the median wait from created to started (claim latency)."""
    from concurrent.futures import ThreadPoolExecutor
    with open(os.path.join(DATA, "contours", "synthetic_ellipsoid.json"), "rb") as f:
        body = f.read()
    hdr = {"Content-Type": "application/json", "Prefer": "respond-async"}
    t0 = time.monotonic()
    with ThreadPoolExecutor(8) as ex:
        ids = list(ex.map(lambda k: post(bases[k % len(bases)] + "/volume", body, hdr)["id"], range(n)))
    pending = set(ids)
    jobs = {}
    while pending:
        for jid in list(pending):
            j = job(bases[0], jid)
            if j["state"] in ("succeeded", "failed", "cancelled"):
                jobs[jid] = j
                pending.discard(jid)
        time.sleep(0.02)
    wall = max(stamp_s(j["finished"]) for j in jobs.values()) - min(stamp_s(j["created"]) for j in jobs.values())
    ok = sum(j["state"] == "succeeded" for j in jobs.values())
    waits = sorted(stamp_s(j["started"]) - stamp_s(j["created"]) for j in jobs.values())
    nodes = len({j["node"] for j in jobs.values()})
    return n / wall, ok, statistics.median(waits) * 1000, waits[len(waits) * 9 // 10] * 1000, nodes, time.monotonic() - t0


def claim_latency(bases, n=50):
    """One job at a time (synchronous POSTs, round the nodes): median and p90 of created -> started, ms."""
    with open(os.path.join(DATA, "contours", "synthetic_ellipsoid.json"), "rb") as f:
        body = f.read()
    waits = []
    for k in range(n):
        req = urllib.request.Request(bases[k % len(bases)] + "/volume", data=body, method="POST",
                                     headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            jid = r.headers["X-Job-Id"]
        j = job(bases[0], jid)
        waits.append((stamp_s(j["started"]) - stamp_s(j["created"])) * 1000)
    waits.sort()
    return statistics.median(waits), waits[n * 9 // 10]


def cluster_bench(lines):
    """Issue 13: small-job throughput on SQLite and on PostgreSQL with 1 and 3 nodes, claim latency, and
    how long a job takes to run elsewhere after its node is killed."""
    n = 300
    lines.append("## Job machinery (issue 13): %d contour volumes (synthetic ellipsoid) posted async by 8 clients\n" % n)
    lines.append("| store | nodes x workers | jobs/s | succeeded | queued -> started p50 ms | p90 ms | nodes that ran jobs "
                 "| claim latency, idle: p50 ms | p90 ms |")
    lines.append("|---|---|---|---|---|---|---|---|---|")
    d, base = start_node("sq", None)
    r = throughput([base], n)
    c = claim_latency([base])
    lines.append("| SQLite (embedded) | 1 x 2 | %.1f | %d | %.1f | %.1f | %d | %.1f | %.1f |" % (r[:5] + c))
    d.send_signal(signal.SIGTERM)
    d.wait(timeout=60)
    pgdir = os.path.join(TMP, "pg")
    os.makedirs(pgdir)
    os.chmod(TMP, 0o755)
    uri = pg_cluster(pgdir)
    try:
        for count in (1, 3):
            nodes = [start_node("n%d-%d" % (count, k), uri) for k in range(count)]
            r = throughput([b for _, b in nodes], n)
            c = claim_latency([b for _, b in nodes])
            lines.append("| PostgreSQL | %d x 2 | %.1f | %d | %.1f | %.1f | %d | %.1f | %.1f |" % (
                (count,) + r[:5] + c))
            for p, _ in nodes:
                p.send_signal(signal.SIGTERM)
                p.wait(timeout=60)
        # failover: a long render on one of two nodes, its node killed once it runs
        lease = 5
        nodes = [start_node("f%d" % k, uri, threads=1, lease=lease) for k in range(2)]
        with open(os.path.join(DATA, "scenes", "teacup.json"), "rb") as f:
            body = f.read()
        jid = post(nodes[0][1] + "/render?width=2048&height=2048&method=bvh", body,
                   {"Content-Type": "application/json", "Prefer": "respond-async"})["id"]
        while job(nodes[1][1], jid)["state"] != "running":
            time.sleep(0.01)
        victim = job(nodes[1][1], jid)["node"]
        k = 0 if victim == "f0" else 1
        nodes[k][0].kill()
        t_kill = time.time()
        other = nodes[1 - k][1]
        while True:
            j = job(other, jid)
            if j["attempts"] >= 2 and j["state"] in ("running", "succeeded"):
                break
            time.sleep(0.01)
        moved = stamp_s(j["started"]) - t_kill
        lines.append("")
        lines.append("queued -> started is the wait of a job in a backlog of %d (the workers are the limit: a 2-core "
                     "machine, so three nodes share the same two cores); the claim latency is that wait for one job at "
                     "a time on idle nodes (created -> started: the submit, the keeper's wake-up and the claim)." % n)
        lines.append("")
        lines.append("Node killed (kill -9) while rendering: its job ran again on the other node %.2f s later "
                     "(lease %d s: the lease runs out, the next reap pass, at most a third of a lease later, queues it, "
                     "and an idle node claims it at once).\n" % (moved, lease))
        nodes[1 - k][0].send_signal(signal.SIGTERM)
        nodes[1 - k][0].wait(timeout=120)
    finally:
        pg_cluster_stop(pgdir)


VOLUMES = [("CT head 256x256x108 int16", "ct_head_256x256x108_int16.raw", (256, 256, 108), "int16", "<i2", 226.5,
            (0.9570312, 0.9570312, 1.5), -1024),
           ("MRI Colin27 181x217x181 uint8", "mri_colin27_181x217x181_uint8.raw", (181, 217, 181), "uint8", "u1", 40.5,
            (1, 1, 1), 0)]


def surfd_iso(path, dims, dtype, iso, sp, threads, repeat):
    p = subprocess.run([SURFD, "isosurface", path, "--iso", str(iso), "--dims", "%d,%d,%d" % dims, "--type", dtype,
                        "--spacing", "%.9g,%.9g,%.9g" % sp, "--threads", str(threads), "--repeat", str(repeat), "--stats"],
                       capture_output=True, text=True, check=True)
    m = json.loads(p.stdout)
    cold, warm = map(float, re.search(r"extract ([\d.]+) ms cold, ([\d.]+) ms warm", p.stderr).groups())
    return m, cold, warm


def iso_bench(lines):
    """Issue 14: surfd's isosurface against VTK's Flying Edges and marching cubes on the shared CT and MRI, padded with
    one layer of the volume's minimum (closed surfaces), normals from the gradient in both, 1 and 2 threads."""
    vtk_py = "/usr/bin/python3"  # Debian's, with python3-vtk9
    lines.append("## Isosurfaces (issue 14): surfd against VTK 9.1, padded (closed), normals on\n")
    lines.append("cold = the first extraction in a fresh process (its memory first touched, as every job of the daemon is); "
                 "warm = the best of %d in one process (memory reused). surfd's extract: both passes, vertices, normals "
                 "and triangles (`surfd isosurface --stats`); VTK: `Update()` of the filter (`tests/bench/vtk_iso.py`).\n" % 7)
    lines.append("| volume | threads | surfd cold ms | FE cold ms | MC cold ms | surfd warm ms | FE warm ms | MC warm ms "
                 "| surfd / FE (cold) | surfd / FE (warm) | triangles surfd / FE | volume surfd / FE | boundary + non-manifold edges |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, f, dims, dtype, npt, iso, sp, pad in VOLUMES:
        path = os.path.join(DATA, "volumes", f)
        for threads in (1, 2):
            m, cold, warm = surfd_iso(path, dims, dtype, iso, sp, threads, 7)
            p = subprocess.run([vtk_py, os.path.join(ROOT, "tests", "bench", "vtk_iso.py"), path] + [str(d) for d in dims] +
                               [npt, str(iso)] + ["%.9g" % x for x in sp] + [str(pad), str(threads), "7"],
                               capture_output=True, text=True, check=True)
            v = json.loads(p.stdout)
            fe, mc = v["flying_edges"], v["marching_cubes"]
            lines.append("| %s, iso %g | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.2f | %.2f | %d / %d (%+.3f %%) | "
                         "%.1f / %.1f (%+.3f %%) | %d |" % (
                             name, iso, threads, cold, fe["cold_ms"], mc["cold_ms"], warm, fe["warm_ms"], mc["warm_ms"],
                             cold / fe["cold_ms"], warm / fe["warm_ms"], m["triangles"], fe["triangles"],
                             100 * (m["triangles"] / fe["triangles"] - 1), m["volume_mm3"], fe["volume"],
                             100 * (m["volume_mm3"] / fe["volume"] - 1), m["boundary_edges"] + m["nonmanifold_edges"]))
    lines.append("")


def distances(a, b):
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "mesh_distance.py"), a, b],
                       capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def adapt_bench(lines):
    """Issue 15: the adaptive hierarchy on the shared CT against the full-resolution mesh, beside VTK's Flying Edges
    followed by vtkQuadricDecimation to the same triangle counts (times, distances both ways)."""
    name, f, dims, dtype, npt, iso, sp, pad = VOLUMES[0]
    path = os.path.join(DATA, "volumes", f)
    common = [path, "--iso", str(iso), "--dims", "%d,%d,%d" % dims, "--type", dtype, "--spacing", "%.9g,%.9g,%.9g" % sp,
              "--stats"]
    full = os.path.join(TMP, "ct_full.stl")
    p = subprocess.run([SURFD, "isosurface"] + common + ["-o", full], capture_output=True, text=True, check=True)
    m1 = json.loads(p.stdout)
    runs = []
    for levels, me, goal in ((2, 0.5, 3.6), (3, 1.0, 10)):
        out = os.path.join(TMP, "ct_l%d.stl" % levels)
        p = subprocess.run([SURFD, "isosurface"] + common + ["--levels", str(levels), "--max-error", str(me), "-o", out],
                           capture_output=True, text=True, check=True)
        m = json.loads(p.stdout)
        p2 = subprocess.run([SURFD, "isosurface"] + common + ["--levels", str(levels), "--max-error", str(me),
                                                              "--threads", "2"], capture_output=True, text=True, check=True)
        m["ms2"] = json.loads(p2.stdout)["timings_ms"]["extract"]
        runs.append((levels, me, goal, m, distances(out, full)))
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_decimate.py"), path] +
                       [str(d) for d in dims] + [npt, str(iso)] + ["%.9g" % x for x in sp] +
                       [str(pad), os.path.join(TMP, "vtk")] + [str(r[3]["triangles"]) for r in runs],
                       capture_output=True, text=True, check=True)
    v = json.loads(p.stdout)
    lines.append("## The adaptive hierarchy (issue 15) on the %s, iso %g\n" % (name, iso))
    lines.append("surfd `isosurface --levels L --max-error MM` (cold; ms on 1 / 2 threads) against its own full-resolution mesh "
                 "(%d triangles, extract %.0f ms); distances from every vertex of each mesh to the other's surface "
                 "(`tests/bench/mesh_distance.py`, VTK's cell locator), in mm. VTK: Flying Edges (%.0f ms, %d triangles, one "
                 "thread) then vtkQuadricDecimation to the same count (`tests/bench/vtk_decimate.py`).\n" % (
                     m1["triangles"], m1["timings_ms"]["extract"], v["fe_ms"], v["fe_triangles"]))
    lines.append("| pipeline | triangles | fewer than full | goal | ms | p99 to full | p99 from full | max to full | "
                 "max from full | closed | cells by level |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for (levels, me, goal, m, d), dec in zip(runs, v["decimated"]):
        lines.append("| surfd levels=%d max_error=%g | %d | %.2fx | %gx | %.0f / %.0f | %.3f | %.3f | %.3f | %.3f | %s | %s |" % (
            levels, me, m["triangles"], m1["triangles"] / m["triangles"], goal, m["timings_ms"]["extract"], m["ms2"],
            d["a_to_b"]["p99"], d["b_to_a"]["p99"], d["a_to_b"]["max"], d["b_to_a"]["max"],
            "yes" if m["boundary_edges"] + m["nonmanifold_edges"] == 0 else "NO", m["cells_by_level"]))
        dd = distances(os.path.join(TMP, "vtk_%d.stl" % dec["target"]), os.path.join(TMP, "vtk_fe.stl"))
        lines.append("| VTK FE + quadric decimation | %d | %.2fx | | %.0f + %.0f | %.3f | %.3f | %.3f | %.3f | | |" % (
            dec["triangles"], v["fe_triangles"] / dec["triangles"], v["fe_ms"], dec["ms"], dd["a_to_b"]["p99"],
            dd["b_to_a"]["p99"], dd["a_to_b"]["max"], dd["b_to_a"]["max"]))
    lines.append("")
    # the hierarchy's own ceiling: no bound on the distance at all
    ceiling = []
    for levels, _, goal, _, _ in runs:
        p = subprocess.run([SURFD, "isosurface"] + common + ["--levels", str(levels), "--max-error", "1000"],
                           capture_output=True, text=True, check=True)
        m = json.loads(p.stdout)
        ceiling.append("levels=%d: %d triangles, %.2fx (goal %gx), cells by level %s" % (
            levels, m["triangles"], m1["triangles"] / m["triangles"], goal, m["cells_by_level"]))
    lines.append("With no bound on the distance (max_error=1000 mm, every block whose merged cell can be drawn merges): %s. "
                 "A merged cell draws at most one crossing on each of its edges, so that the mesh stays closed and "
                 "manifold where cell sizes change; blocks whose coarse edges the surface crosses twice (thin bone) stay "
                 "level-1 cells whatever the bound.\n" % "; ".join(ceiling))


def kept_bench(lines):
    """Issue 45: marching cubes kept (core/iso/kept.h) on the shared CT, offline (`surfd isosurface --edits --isos`):
    20 edits of 16^3 blocks holding the surface, then the isos 500, 100, 226.5, each against VTK's Flying Edges'
    full extraction at that iso (1 thread) in the same run; every mesh checked against a fresh extraction."""
    name, f, dims, dtype, npt, iso, sp, pad = VOLUMES[0]
    path = os.path.join(DATA, "volumes", f)
    isos = (500, 100, 226.5)
    base = [SURFD, "isosurface", path, "--iso", str(iso), "--dims", "%d,%d,%d" % dims, "--type", dtype,
            "--spacing", "%.9g,%.9g,%.9g" % sp]
    cmd = base + ["--edits", "20", "--edit-size", "16"]
    iso_cmd = base + ["--isos", ",".join("%g" % v for v in isos + isos)]  # (on the volume as it is: FE's mesh the same;
    # twice: the first pass touches the extraction's memory anew, the second reuses it, as a slider's moves do)
    run = lambda c: json.loads(subprocess.run(c, capture_output=True, text=True, check=True).stdout)
    runs = [run(cmd) for _ in range(3)]
    iso_runs = [run(iso_cmd) for _ in range(3)]
    checked = run(cmd + ["--isos", ",".join("%g" % v for v in isos), "--check"])
    fe = {}
    for v in isos:
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_iso.py"), path] +
                           [str(d) for d in dims] + [npt, str(v)] + ["%.9g" % x for x in sp] + [str(pad), "1", "7"],
                           capture_output=True, text=True, check=True)
        fe[v] = json.loads(p.stdout)["flying_edges"]
    med = lambda xs: sorted(xs)[len(xs) // 2]
    lines.append("## Marching cubes kept (issue 45): edits and iso changes of the %s, iso %g\n" % (name, iso))
    lines.append("`%s` and `... --isos %s` (3 runs each, medians; one more of both with `--check`: every mesh equal to a fresh extraction of the edited "
                 "samples, triangle for triangle, positions and normals: **%s**). The model (levels=1) kept with its samples "
                 "(core/iso/kept.h: %.0f MB for this CT, the begin %.0f ms, then the lists an edit works on %.0f ms, as the "
                 "daemon's warm-up makes them after the model's answer). An edit draws again the cells whose corners or "
                 "vertices' normals read a written sample; an iso change draws the whole grid by the slabs' two passes "
                 "(`iso_box_whole`: the cells with a crossing, 64 cells of one state passed over at a time), every old triangle "
                 "removed, the new ones' ids handed out as the change (their corners are not: the daemon reads the new mesh back "
                 "whole), the mesh left as drawn; the first edit after a new iso first makes the lists (%.0f ms); each iso "
                 "twice (first: the extraction's memory touched anew; again: reused, as a slider's moves reuse it). Flying Edges: "
                 "VTK 9.1's full extraction at that iso, one thread, padded, normals on (`tests/bench/vtk_iso.py`).\n" % (
                     " ".join(["surfd"] + cmd[1:]).replace(DATA, "../shared/data"), ",".join("%g" % v for v in isos),
                     "yes" if checked["equal_to_fresh"] else "NO", med([r["bytes"] for r in runs]) / 1e6,
                     med([r["begin_ms"] for r in runs]), med([r["index_ms"] for r in runs]),
                     med([r["index_after_isos_ms"] for r in iso_runs])))
    lines.append("| edits | edit ms median | edit ms max | cells redrawn median | triangles added / removed (all edits) |")
    lines.append("|---|---|---|---|---|")
    lines.append("| 20 of 16^3 | %.2f | %.2f | %d | %d / %d |" % (
        med([r["edit_ms_median"] for r in runs]), med([r["edit_ms_max"] for r in runs]),
        med([r["cells_rebuilt_median"] for r in runs]), runs[0]["triangles_added"], runs[0]["triangles_removed"]))
    lines.append("")
    lines.append("| new iso | kept ms first / again | FE cold ms | FE warm ms | kept again / FE warm | triangles kept / FE | cells drawn |")
    lines.append("|---|---|---|---|---|---|---|")
    for i, v in enumerate(isos):
        first = med([r["isos"][i]["ms"] for r in iso_runs])
        again = med([r["isos"][i + len(isos)]["ms"] for r in iso_runs])
        lines.append("| %g | %.1f / %.1f | %.1f | %.1f | %.2f | %d / %d | %d |" % (
            v, first, again, fe[v]["cold_ms"], fe[v]["warm_ms"], again / fe[v]["warm_ms"], iso_runs[0]["isos"][i]["triangles"],
            fe[v]["triangles"], iso_runs[0]["isos"][i]["cells_drawn"]))
    lines.append("")


def edit_bench(lines, n_edits=20):
    """Issue 15: POST /models/{id}/edit of 16^3 blocks of the shared CT (bone painted into the samples round the
    skull), against the full extraction of the same model on the same daemon (2 workers)."""
    import random
    name, f, dims, dtype, npt, iso, sp, pad = VOLUMES[0]
    raw = open(os.path.join(DATA, "volumes", f), "rb").read()
    nx, ny, nz = dims
    d, base = start_node("edit", None, threads=2)
    rng = random.Random(15)
    blocks = []
    for _ in range(n_edits):  # blocks holding the surface: samples on both sides of iso
        while True:
            x0, y0, z0 = rng.randrange(0, nx - 16), rng.randrange(0, ny - 16), rng.randrange(0, nz - 16)
            vals = [struct.unpack_from("<16h", raw, 2 * (x0 + nx * (y0 + y + ny * (z0 + z)))) for z in range(16) for y in range(16)]
            flat = [v for row in vals for v in row]
            if min(flat) < iso < max(flat):
                break
        painted = [v + 400 if (k % 16 - 8) ** 2 + (k // 16 % 16 - 8) ** 2 + (k // 256 - 8) ** 2 < 30 else v
                   for k, v in enumerate(flat)]
        blocks.append(("%d,%d,%d,16,16,16" % (x0, y0, z0), struct.pack("<%dh" % len(painted), *painted)))
    q = "iso=%g&dims=%d,%d,%d&type=%s&spacing=%.9g,%.9g,%.9g" % ((iso,) + tuple(dims) + (dtype,) + tuple(sp))
    isos = (500, 100, 226.5)
    rows, iso_rows = [], []
    octet = {"Content-Type": "application/octet-stream"}
    try:
        for levels, me in ((2, 0.5), (3, 1.0), (1, None)):
            opts = q + "&levels=%d" % levels + ("&max_error=%g" % me if me else "")
            m = post(base + "/isosurface?" + opts, raw, octet)
            ms, wall, rebuilt, delta = [], [], [], []
            for region, body in blocks:
                t0 = time.time()
                e = post(base + "/models/%s/edit?region=%s" % (m["id"], region), body, octet)
                wall.append((time.time() - t0) * 1e3)
                ms.append(e["edit"]["ms"])
                rebuilt.append(e["edit"]["cells_rebuilt"])
                with urllib.request.urlopen(base + "/models/%s/mesh?format=delta&since=%d" % (m["id"], e["version"] - 1),
                                            timeout=60) as r:
                    delta.append(len(r.read()))
            closed = e["boundary_edges"] + e["nonmanifold_edges"] == 0
            rows.append((levels, me, m, ms, wall, rebuilt, delta, e, closed))
            changes = []
            for v in isos:  # the model at new isos (POST /models/{id}/iso), then its delta fetched
                t0 = time.time()
                e = post(base + "/models/%s/iso?value=%g" % (m["id"], v), b"", octet)
                t1 = time.time()
                with urllib.request.urlopen(base + "/models/%s/mesh?format=delta&since=%d" % (m["id"], e["version"] - 1),
                                            timeout=120) as r:
                    n = len(r.read())
                changes.append((v, e["edit"]["ms"], (t1 - t0) * 1e3, (time.time() - t0) * 1e3, n, e["triangles"]))
            iso_rows.append((levels, me, changes))
    finally:
        d.terminate()
        d.wait()
    fe = {}
    for v in isos:
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_iso.py"),
                            os.path.join(DATA, "volumes", f)] + [str(x) for x in dims] + [npt, str(v)] +
                           ["%.9g" % x for x in sp] + [str(pad), "1", "5"], capture_output=True, text=True, check=True)
        fe[v] = json.loads(p.stdout)["flying_edges"]
    label = lambda levels, me: "levels=%d max_error=%g" % (levels, me) if me else "levels=1 (marching cubes kept)"
    lines.append("## Edits (issues 15, 45) of the %s, iso %g\n" % (name, iso))
    lines.append("%d edits of 16^3 blocks (bone painted into samples that hold the surface), one after another, each "
                 "`POST /models/{id}/edit` on a daemon with 2 workers (the release build, SQLite). edit ms: the model's "
                 "`edit.ms` (the samples written, the cells they reach drawn again); request ms: the whole answer seen by "
                 "the client (the change stored in the model's journal with the samples and the resource in one "
                 "transaction, the job queued and answered); delta: `GET /models/{id}/mesh?format=delta&since=V-1` after "
                 "each edit, its bytes. A hierarchy is kept since the model's job; levels=1's kept marching cubes are "
                 "built after the model's job has answered (`edit_warm`; the first request below came as soon as the "
                 "model's answer, and waited for the rest of it). Full: the model's own extraction on the same daemon. "
                 "Each mesh equals a fresh extraction of the edited volume (tests/api/edit.sh, tests/api/mesh_journal.sh, "
                 "tests/core/iso/test_edit.c, test_kept.c).\n" % n_edits)
    lines.append("| model | triangles | full extract ms | edit ms median | edit ms max | cells redrawn median "
                 "| request ms median | first request ms | delta KB median / whole mesh KB | closed after |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|")
    for levels, me, m, ms, wall, rebuilt, delta, e, closed in rows:
        lines.append("| %s | %d | %.0f | %.2f | %.2f | %d | %.1f | %.0f | %.1f / %.0f | %s |" % (
            label(levels, me), m["triangles"], m["timings_ms"]["extract"], statistics.median(ms), max(ms),
            statistics.median(rebuilt), statistics.median(wall), wall[0], statistics.median(delta) / 1e3,
            (20 + 40 * m["triangles"]) / 1e3, "yes" if closed else "NO"))
    lines.append("\nNew isos over HTTP, one after another on the edited model (`POST /models/{id}/iso?value=V`, then its "
                 "delta): iso ms is the model's `edit.ms`; Flying Edges: VTK 9.1's full extraction at that iso of the "
                 "unedited CT, one thread, warm (`tests/bench/vtk_iso.py`).\n")
    lines.append("| model | new iso | iso ms | request ms | + delta ms | delta MB | triangles | FE warm ms | iso ms / FE |")
    lines.append("|---|---|---|---|---|---|---|---|---|")
    for levels, me, changes in iso_rows:
        for v, ms, req, total, n, tri in changes:
            lines.append("| %s | %g | %.1f | %.0f | %.0f | %.1f | %d | %.1f | %.2f |" % (
                label(levels, me), v, ms, req, total, n / 1e6, tri, fe[v]["warm_ms"], ms / fe[v]["warm_ms"]))
    lines.append("")


def views_bench(lines):
    """Issue 17: repeat views of a stored model over HTTP (GET /models/{id}/render, 1024x1024, 2 threads): the first
    builds the model's hierarchy, the next ones take it from the frame cache; wall time against X-Render-Ms."""
    d, base = start_daemon("views", "--threads", "2")
    try:
        with open(os.path.join(DATA, "contours", "dicompyler_heart.json"), "rb") as f:
            req = urllib.request.Request(base + "/model", data=f.read(), headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as r:
            mid = json.load(r)["id"]
        views = []
        for k, az in enumerate([30, 45, 60, 75, 90, 105] * 3):  # the first builds; 17 repeats, three rounds
            t0 = time.monotonic()
            with urllib.request.urlopen("%s/models/%s/render?width=%d&height=%d&azimuth=%d" % (base, mid, W, H, az),
                                        timeout=300) as r:
                r.read()
                render = float(r.headers["X-Render-Ms"])
            views.append(((time.monotonic() - t0) * 1000, render))
    finally:
        d.terminate()
        d.wait()
    first, rest = views[0], views[1:]
    wall = statistics.median(v[0] for v in rest)
    render = statistics.median(v[1] for v in rest)
    lines.append("## Repeat views of a stored model (issue 17)\n")
    lines.append("The heart contour model (`dicompyler_heart.json`), GET /models/{id}/render at %dx%d, "
                 "2 threads, azimuth 30, 45, ... 105 three times over: the first view parses the model and builds its hierarchy, the "
                 "next take both from the frame cache (`frame-cache`) and prepare only the camera. Wall = the whole "
                 "HTTP request (job, render, PNG, store); render = X-Render-Ms.\n" % (W, H))
    lines.append("| view | wall ms | render ms | wall / render |")
    lines.append("|---|---|---|---|")
    lines.append("| first | %.0f | %.0f | %.2f |" % (first[0], first[1], first[0] / first[1]))
    lines.append("| repeat (median of %d) | %.0f | %.0f | %.2f |" % (len(rest), wall, render, wall / render))
    lines.append("")
    lines.append("- Target of issue 17: a repeat view within 1.3x of its render time: %.2fx.\n" % (wall / render))


def aa_bench(lines):
    """Issue 18: anti-aliasing (?samples=N, stratified rays a pixel) on the teapot at 1024x1024, 2 threads, against
    one ray a pixel and POV-Ray's own supersampling (+A0.0 +AM1 +R4: 16 rays a pixel everywhere), same run."""
    teapot, patches = scene_file("teapot.json", True)
    pov_file = povray_scene(patches)
    runs = {}
    for n in (1, 4, 16):
        out = os.path.join(TMP, "aa.png")
        rs = []
        for _ in range(REPEAT):
            p = subprocess.run([SURFD, "render", teapot, "-o", out, "--threads", "2", "--width", str(W), "--height",
                                str(H), "--samples", str(n), "--stats"], capture_output=True, text=True)
            if p.returncode:
                sys.exit("surfd failed: " + p.stderr)
            rs.append(json.loads(p.stderr.strip().splitlines()[-1]))
        runs[n] = medians(rs)
    pov1 = statistics.median(povray_once(pov_file, 2) for _ in range(REPEAT))
    pov16 = statistics.median(povray_once(pov_file, 2, ("+A0.0", "+AM1", "+R4")) for _ in range(REPEAT))
    lines.append("## Anti-aliasing (issue 18)\n")
    lines.append("Teapot 1024x1024, 2 threads, PNG: `surfd render teapot.json --samples N --stats` (stratified rays a "
                 "pixel through the hierarchy: the map's candidates are the pixel centres'); POV-Ray 3.7 with +A0.0 +AM1 "
                 "+R4 (16 rays a pixel). Median of %d runs.\n" % REPEAT)
    lines.append("| renderer | rays a pixel | render ms | x one ray |")
    lines.append("|---|---|---|---|")
    for n in (1, 4, 16):
        lines.append("| surfd | %d | %.1f | %.2f |" % (n, runs[n]["render_ms"], runs[n]["render_ms"] / runs[1]["render_ms"]))
    lines.append("| POV-Ray | 1 | %.1f | 1.00 |" % pov1)
    lines.append("| POV-Ray | 16 | %.1f | %.2f |" % (pov16, pov16 / pov1))
    lines.append("")
    lines.append("- surfd at 16 rays a pixel against POV-Ray at 16: %.1fx faster.\n" % (pov16 / runs[16]["render_ms"]))


def shell_bench(lines):
    """Issue 18: a contour model's own patches posted back to POST /volume (`surfd volume PATCHES.json`, the same
    figures path): the boundaries matched, the sides agreed, the volume against the model's."""
    lines.append("## A model's patches back to POST /volume (issue 18)\n")
    lines.append("`surfd model FILE --caps dome --patches P.json`, then `surfd volume P.json` (wall, median of %d): every "
                 "patch's boundary sampled and matched to its neighbours' within 1e-4 of the diagonal, the sides agreed, "
                 "the divergence theorem (trimmed surfaces where the torus branches: the planes where its tubes end and "
                 "begin). The larger files' JSON values are read an object at a time.\n" % REPEAT)
    lines.append("| file | patches | boundary points | closed | ms | volume mm3 | model's mm3 |")
    lines.append("|---|---|---|---|---|---|---|")
    for name in ("synthetic_ellipsoid", "synthetic_torus_branching", "dicompyler_tumor_bed", "eclipse_bladder",
                 "dicompyler_heart", "dicompyler_lt_lung_multicontour", "eclipse_body"):
        pj = os.path.join(TMP, name + "_patches.json")
        p = subprocess.run([SURFD, "model", os.path.join(DATA, "contours", name + ".json"), "--caps", "dome",
                            "--patches", pj], capture_output=True, text=True, check=True)
        model = json.loads(p.stdout)
        runs = []
        for _ in range(REPEAT):
            t0 = time.perf_counter()
            p = subprocess.run([SURFD, "volume", pj], capture_output=True, text=True)
            runs.append(1000 * (time.perf_counter() - t0))
        if p.returncode:
            lines.append("| %s | | | refused: %s | %.0f | | %.1f |" % (name, p.stderr.strip()[-120:], statistics.median(runs),
                                                                     model["volume_mm3"]))
            continue
        r = json.loads(p.stdout)
        lines.append("| %s | %d | %d | %s | %.0f | %.1f | %.1f |" % (name, r["patches"], r["boundary_points"],
                                                                     "yes" if r["closed"] else "no", statistics.median(runs),
                                                                     r["volume_mm3"], model["volume_mm3"]))
    lines.append("")


def cad_bench(lines):
    """Issue 17: the trimmed IGES mug (mug_solid.igs, 13 trimmed NURBS surfaces) and the heart contour model at
    1024x1024, 1 and 2 threads, every method, against the teapot's auto render at the same size and threads; Open
    CASCADE's IGES read and triangulation of the same part (deflection 0.1 mm, half a pixel here) as the peer."""
    mug = os.path.join(DATA, "scenes", "mug_solid.igs")
    cam = ["--eye", "250,-300,220", "--target", "0,0,40", "--up", "0,0,1", "--fov", "30"]
    heart = os.path.join(TMP, "heart_patches.json")
    p = subprocess.run([SURFD, "model", os.path.join(DATA, "contours", "dicompyler_heart.json"), "--patches", heart],
                       capture_output=True, text=True)
    if p.returncode:
        sys.exit("surfd model failed: " + p.stderr)
    teapot, _ = scene_file("teapot.json", True)
    tea = {t: surfd([teapot], "auto", t) for t in (1, 2)}
    rows = {}
    methods = ("auto", "map", "bvh", "mesh")
    for name, inputs in (("mug_solid.igs", [mug] + cam), ("heart model", [heart])):
        for t in (1, 2):  # the methods take turns, run by run, so that a drift of the machine's speed hits them alike
            runs = {m: [] for m in methods}
            for _ in range(REPEAT):
                for m in methods:
                    runs[m].append(surfd_once(inputs, m, t))
            for m in methods:
                rows[(name, m, t)] = medians(runs[m])
    rows = {(n, m, t): rows[(n, m, t)] for n in ("mug_solid.igs", "heart model") for m in methods for t in (1, 2)}
    occt = os.path.join(ROOT, "build", "tests", "tools", "occt_iges")
    peer = None
    if os.path.exists(occt):
        runs = []
        for _ in range(REPEAT):
            p = subprocess.run([occt, mug, "--raster", "64", "64", "250,-300,220", "0,0,40", "0,0,1", "30", "0.1",
                                os.path.join(TMP, "occt.f32")], capture_output=True, text=True)
            out = [json.loads(l) for l in p.stdout.splitlines() if l.startswith("{")]
            runs.append((out[0]["read_ms"], out[1]["mesh_ms"], out[1]["triangles"]))
        peer = (statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs), runs[0][2])
    lines.append("## CAD parts and organ models (issue 17)\n")
    lines.append("`surfd render PART --method M --threads T --width 1024 --height 1024 --stats`: mug_solid.igs (13 trimmed "
                 "NURBS surfaces, 47 patches after the trims drop the wholly cut-away ones) from eye [250,-300,220] "
                 "towards [0,0,40], fov 30; the heart model's patches (`surfd model dicompyler_heart.json --patches`, "
                 "%d Bezier patches) auto-framed. render = trace and shade. Median of %d runs, the methods taking turns.\n" % (
                     rows[("heart model", "auto", 1)]["patches"], REPEAT))
    lines.append("| part | method | threads | prepare ms | render ms | x teapot auto render | iterations/primary |")
    lines.append("|---|---|---|---|---|---|---|")
    for (name, method, t), r in rows.items():
        lines.append("| %s | %s | %d | %.1f | %.1f | %.2f | %.2f |" % (name, method, t, r["prepare_ms"], r["render_ms"],
                                                                      r["render_ms"] / tea[t]["render_ms"],
                                                                      r["iterations_mean"]))
    for t in (1, 2):
        lines.append("| teapot | auto | %d | %.1f | %.1f | 1.00 | %.2f |" % (t, tea[t]["prepare_ms"], tea[t]["render_ms"],
                                                                           tea[t]["iterations_mean"]))
    lines.append("")
    if peer:
        m = rows[("mug_solid.igs", "auto", 2)]
        lines.append("Open CASCADE 7.6 on the same file (tests/tools/occt_iges): IGES read and transfer %.1f ms, "
                     "BRepMesh triangulation at 0.1 mm %.1f ms (%d triangles), before any pixel is drawn; surfd's "
                     "prepare + render of the exact trimmed surfaces at 2 threads: %.1f ms.\n" % (
                         peer[0], peer[1], peer[2], m["prepare_ms"] + m["render_ms"]))
    for t in (1, 2):
        h, a, me = rows[("heart model", "auto", t)], rows[("heart model", "auto", t)], rows[("heart model", "mesh", t)]
        lines.append("- %d thread(s): heart render / teapot render = %.2f (target <= 3); heart auto / mesh render = %.2f "
                     "(target <= 1); mug auto / mesh render = %.2f" % (
                         t, h["render_ms"] / tea[t]["render_ms"], a["render_ms"] / me["render_ms"],
                         rows[("mug_solid.igs", "auto", t)]["render_ms"] / rows[("mug_solid.igs", "mesh", t)]["render_ms"]))
    lines.append("")


def matrix_bench(lines):
    """Issue 16: matrix models (seed 003) to meshes against marching cubes on the same voxels (VTK's Flying Edges on
    the mask at iso 127.5, padded), in the same run; both of surfd's meshers."""
    shapes = [("ball r 30 in 64^3", 64, ["ball", "30"], 4 / 3 * 3.141592653589793 * 30 ** 3),
              ("ball r 60 in 128^3", 128, ["ball", "60"], 4 / 3 * 3.141592653589793 * 60 ** 3),
              ("box 40x30x20 in 48^3", 48, ["box", "4", "44", "9", "39", "14", "34"], 40 * 30 * 20),
              ("stepped pyramid in 48^3", 48, ["steps"], None),
              ("stepped pyramid in 96^3", 96, ["steps"], None)]
    tool = os.path.join(ROOT, "tests", "tools", "matrix_tool.py")
    lines.append("## Matrix models (issue 16)\n")
    lines.append("surfd: `surfd model MATRIX.json --repeat 5` (one thread, warm: the last run's timings; the best of 3 "
                 "such processes). `fragments` is the default mesher (the "
                 "seed's: a fixed fragment per cube of voxel centres, every vertex at a voxel corner); `chamfer` "
                 "(`\"mesher\": \"chamfer\"`) keeps the voxel faces with chamfered edges and corners. `mesh ms` is the "
                 "mesher alone (`timings_ms.mesh`: voxels -> closed manifold mesh, the step Flying Edges does), `build ms` "
                 "adds matrices -> voxels and the figures. VTK: Flying Edges on the same voxels as a uint8 mask (255 "
                 "inside) at iso 127.5, padded, one thread, normals on (its default), warm: the best of 5 "
                 "(`tests/bench/vtk_iso.py`); all its vertices are computed (edge crossings). Exact volume: the shape's (the ball's 4/3 pi r^3, the box's, the pyramid's "
                 "voxel count). Sizes: the matrix model as 16-bit elements (6 matrices of N^2) and as JSON, against the "
                 "mask (a byte a voxel). Targets of the issue: fewer vertices than Flying Edges, computed vertices under "
                 "12 %, volume within 3 %, faster than Flying Edges.\n")
    lines.append("| shape | mesher | vertices | computed | triangles | mesh ms | build ms | volume error | dropped voxels | "
                 "closed | matrices (16-bit / JSON) vs mask |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, n, shape, exact in shapes:
        js, raw = os.path.join(TMP, "matrix.json"), os.path.join(TMP, "mask.raw")
        subprocess.run(["python3", tool, shape[0], str(n)] + shape[1:] + [js], check=True)
        subprocess.run(["python3", tool, "mask", str(n)] + shape + [raw], check=True)
        chamfer = os.path.join(TMP, "matrix_chamfer.json")
        doc = json.load(open(js))
        doc["mesher"] = "chamfer"
        json.dump(doc, open(chamfer, "w"))
        if exact is None:
            exact = sum(open(raw, "rb").read()) / 255
        size16, size_json, mask = 6 * n * n * 2, os.path.getsize(js), n ** 3
        for mesher, path in (("fragments", js), ("chamfer", chamfer)):
            runs = [json.loads(subprocess.run([SURFD, "model", path, "--repeat", "5"], capture_output=True, text=True,
                                              check=True).stdout) for _ in range(3)]
            m = min(runs, key=lambda r: r["timings_ms"]["mesh"])
            lines.append("| %s | surfd %s | %d | %d (%.0f %%) | %d | %.2f | %.2f | %+.2f %% | %d | %s | %s |" % (
                name if mesher == "fragments" else "", mesher, m["vertices"], m["computed_vertices"],
                100 * m["computed_vertices"] / m["vertices"], m["triangles"], m["timings_ms"]["mesh"],
                m["timings_ms"]["build"], 100 * (m["volume_mm3"] / exact - 1), m["dropped_voxels"],
                "yes" if m["boundary_edges"] + m["nonmanifold_edges"] == 0 else "NO",
                "%.1fx / %.1fx smaller" % (mask / size16, mask / size_json) if mesher == "fragments" else ""))
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_iso.py"), raw, str(n), str(n),
                            str(n), "u1", "127.5", "1", "1", "1", "0", "1", "5"], capture_output=True, text=True, check=True)
        fe = json.loads(p.stdout)["flying_edges"]
        lines.append("| | VTK Flying Edges | %d | %d (100 %%) | %d | %.2f | | %+.2f %% | | | |" % (
            fe["vertices"], fe["vertices"], fe["triangles"], fe["warm_ms"], 100 * (fe["volume"] / exact - 1)))
    lines.append("")


def sharp_bench(lines):
    """Issue 15: features=sharp on CSG solids turned off the grid's axes, against plain marching cubes on the same
    samples (`tests/bench/sharp_edges.py`: true edges and corners to the mesh, volume against the exact one)."""
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "sharp_edges.py"), SURFD, TMP],
                       capture_output=True, text=True, check=True)
    rows = json.loads(p.stdout)
    lines.append("## Sharp features (issue 15)\n")
    lines.append("FRep CSG solids about 2 units across, turned by (20, 30, 10) degrees, cells of 0.04 (1/50), alpha 0 (R0): "
                 "`surfd isosurface SOLID.json --features sharp|none` (one thread, cold). Distances, in cells, from the "
                 "points of the true edges (box edges and the curves where a hole meets a face, every 1/8 cell) and from "
                 "the true corners to the mesh (VTK's cell locator). `none` is plain marching cubes on the same samples "
                 "(what Flying Edges gives there; no feature-preserving extraction is packaged in Debian to run beside "
                 "it). Targets: edges within 0.1 cell, corners 0.2, volume 0.05 %.\n")
    lines.append("| solid | features | triangles | ms | edge max | edge p99 | edge mean | corners max | volume error | "
                 "feature / face points | closed |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        for f in ("none", "sharp"):
            x = r[f]
            lines.append("| %s | %s | %d | %.0f | %.3f | %.3f | %.3f | %.3f | %+.4f %% | %d / %d | %s |" % (
                r["solid"], f, x["triangles"], x["ms"], x["edge_max"], x["edge_p99"], x["edge_mean"], x["corner_max"],
                x["volume_error_pct"], x["feature_points"], x["face_points"], "yes" if x["closed"] else "NO"))
    lines.append("")


def big_ct(path):
    """A 512x512x600 int16 CT (315 MB): the shared head CT resampled (nearest) onto it, by Debian's numpy."""
    code = ("import numpy as np, sys\n"
            "a = np.fromfile(sys.argv[1], dtype='<i2').reshape(108, 256, 256)\n"
            "z = (np.arange(600) * 108 // 600)[:, None, None]; y = (np.arange(512) // 2)[None, :, None]; "
            "x = (np.arange(512) // 2)[None, None, :]\n"
            "a[z, y, x].astype('<i2').tofile(sys.argv[2])\n")
    subprocess.run(["/usr/bin/python3", "-c", code, os.path.join(DATA, "volumes", "ct_head_256x256x108_int16.raw"), path],
                   check=True)


def post_volume(d, url, path):
    """A volume file streamed to url (`curl -T`: curl holds 1 GB of --data-binary at most): the answer's status,
    the wall seconds, its JSON, and the daemon's peak RSS in bytes after it."""
    out = os.path.join(TMP, "answer.json")
    t0 = time.monotonic()
    p = subprocess.run(["curl", "-sS", "-o", out, "-w", "%{http_code}", "-H", "Content-Type: application/octet-stream",
                        "-X", "POST", "-T", path, url], capture_output=True, text=True, check=True)
    wall = time.monotonic() - t0
    with open(out) as f:
        m = json.load(f)
    with open("/proc/%d/status" % d.pid) as f:
        hwm = int(re.search(r"VmHWM:\s+(\d+)", f.read()).group(1)) * 1024
    return p.stdout, wall, m, hwm


def big_volume_bench(lines):
    """Issue 14: the 315 MB CT through HTTP end to end, and the daemon's peak RSS against the volume and the mesh."""
    path = os.path.join(TMP, "ct512.raw")
    big_ct(path)
    size = os.path.getsize(path)
    d, base = start_node("big", None)
    try:
        http_get(base + "/livez")
        idle = rss_kb(d.pid) * 1024
        code, wall, m, hwm = post_volume(
            d, base + "/isosurface?iso=226.5&dims=512,512,600&type=int16&spacing=0.478516,0.478516,0.27", path)
        mesh = 12 * m["vertices"] * 2 + 12 * m["triangles"]  # positions, normals, triangles
        lines.append("## A 315 MB CT through HTTP (issue 14)\n")
        lines.append("512x512x600 int16 (%.0f MB, the shared CT resampled), iso 226.5, `curl -T` to POST /isosurface "
                     "(one request, synchronous): HTTP %s in %.1f s wall; the job's read %.0f ms, extract %.0f ms, measure "
                     "%.0f ms; %d triangles, %d boundary + %d non-manifold edges. Peak RSS of the daemon (VmHWM) %.0f MB: "
                     "%.0f MB idle (before any request: the libraries and the Embree device; OpenImageIO loads on the first EXR or TIFF) + %.0f MB for the request, "
                     "against volume + mesh = %.0f MB: the request %.2fx, the whole process %.2fx (target < 1.25x).\n" % (
                         size / 1e6, code, wall, m["timings_ms"]["read"], m["timings_ms"]["extract"],
                         m["timings_ms"]["measure"], m["triangles"], m["boundary_edges"], m["nonmanifold_edges"], hwm / 1e6,
                         idle / 1e6, (hwm - idle) / 1e6, (size + mesh) / 1e6, (hwm - idle) / (size + mesh),
                         hwm / (size + mesh)))
    finally:
        d.send_signal(signal.SIGTERM)
        d.wait(timeout=120)


def pieces_bench(lines):
    """Issue 48's finding 10c: a volume over SQLite's 1e9-byte value (a 1.1 GB one was extracted, then refused with a
    500), posted to POST /isosurface and kept for its edits in pieces (`store-piece`)."""
    n, r = 1040, 400
    path = os.path.join(TMP, "ball1040.raw")
    with open(path, "wb") as f:  # a ball of radius r in an n^3 uint8 field, a slice at a time
        for z in range(n):
            sl = bytearray(n * n)
            dz = z - n // 2
            for y in range(n):
                h = r * r - dz * dz - (y - n // 2) ** 2
                if h > 0:
                    w = int(h ** 0.5)
                    sl[y * n + n // 2 - w:y * n + n // 2 + w] = b"\xc8" * (2 * w)
            f.write(sl)
    size = os.path.getsize(path)
    d, base = start_node("pieces", None)
    try:
        code, wall, m, hwm = post_volume(d, base + "/isosurface?iso=100&dims=%d,%d,%d&type=uint8" % (n, n, n), path)
        one = os.path.join(TMP, "one.raw")
        with open(one, "wb") as f:
            f.write(b"\x00")
        t0 = time.monotonic()
        q = subprocess.run(["curl", "-sS", "-o", "/dev/null", "-w", "%{http_code}", "-H",
                            "Content-Type: application/octet-stream", "--data-binary", "@" + one,
                            base + "/models/%s/edit?region=0,0,0,1,1,1" % m.get("id", "")],
                           capture_output=True, text=True)
        edit = time.monotonic() - t0
        lines.append("## A volume over SQLite's largest value (issue 48)\n")
        lines.append("A ball in a %d^3 uint8 field (%.2f GB; SQLite holds at most 1e9 bytes in one value), `curl -T` "
                     "(streamed) to POST /isosurface, the embedded store: HTTP %s in %.1f s wall, %s triangles, its "
                     "volume kept for edits in pieces of 256 MB (finding 10c: a 1.1 GB volume was extracted, then refused with "
                     "a 500). Peak RSS %.0f MB. A first edit of one sample (the volume read back from its pieces: it is "
                     "over edit-memory, so not kept in memory) answered %s in %.1f s.\n" % (
                         n, size / 1e9, code, wall, m.get("triangles", "?"), hwm / 1e6, q.stdout, edit))
    finally:
        d.send_signal(signal.SIGTERM)
        d.wait(timeout=120)


def small_inputs_bench(lines):
    """Issue 48: the largest memory an input under 64 KB costs the release daemon (tests/bench/small_inputs.sh), and
    what the allocator wrappers of the memory accounts cost: nothing to see here, see the edits and the extraction."""
    p = subprocess.run(["sh", os.path.join(ROOT, "tests", "bench", "small_inputs.sh")], capture_output=True, text=True,
                       check=True)
    table = [l for l in p.stdout.splitlines() if l.startswith("|")]
    lines.append("## What an input under 64 KB can cost (issue 48)\n")
    lines.append("Release build, a fresh daemon for each input, its peak RSS (VmHWM); `tests/bench/small_inputs.sh`. The "
                 "largest found: a gzip NRRD of a striped field (every cell holds surface) just under `max-triangles` "
                 "(40 M). What one job may cost is the node's `job-memory` (by default 3/4 of the memory the process may "
                 "use, shared among the workers), decided from what the input declares where it can be (an isosurface's "
                 "triangles from its count pass, at 80 bytes each: the last row, refused before its mesh) and enforced "
                 "on every allocation of the job's own code; the mesh of the first row is kept in pieces "
                 "(`store-piece`), not refused by SQLite's 1e9-byte value. So the figure is bounded by configuration, "
                 "not by the input: a node that must not spend the first row's memory on one job sets `job-memory` (or "
                 "`max-triangles`) lower.\n")
    lines.extend(table)
    lines.append("")


def teapot_bench(lines):
    """Issue 3: the teapot at 1024x1024 by every method against POV-Ray's bicubic_patch, and the other shared
    scenes at 2 threads."""
    rows = []
    teapot, patches = scene_file("teapot.json", True)
    # POV-Ray and auto take turns, run by run: on a shared machine whose load drifts, both see
    # the same conditions
    pov_file, pov, auto = povray_scene(patches), {}, {}
    for t in (1, 2):
        turns = [(povray_once(pov_file, t), surfd_once([teapot], "auto", t)) for _ in range(REPEAT)]
        pov[t] = statistics.median(p for p, _ in turns)
        auto[t] = medians([a for _, a in turns])
    for method in ("auto", "map", "bvh", "mesh"):
        for t in (1, 2):
            r = auto[t] if method == "auto" else surfd([teapot], method, t)
            rows.append(("teapot", method, t, r))
    mc = surfd([teapot], "montecarlo", 2, 256, 256)
    lines.append("## Teapot 1024x1024, eye [7,-10,6], one shadow-casting light\n")
    lines.append("| method | threads | prepare ms | render ms | total ms | PNG share | rays | fallbacks | iterations/primary |")
    lines.append("|---|---|---|---|---|---|---|---|---|")
    by = {}
    for name, method, t, r in rows:
        by[(method, t)] = r
        share = r["encode_ms"] / (r["render_ms"] + r["encode_ms"])
        lines.append("| %s | %d | %.1f | %.1f | %.1f | %.1f %% | %d | %d | %.2f |" % (
            method, t, r["prepare_ms"], r["render_ms"], r["prepare_ms"] + r["render_ms"], 100 * share, r["rays"],
            r["misses"], r["iterations_mean"]))
    for t in (1, 2):
        lines.append("| POV-Ray 3.7 bicubic_patch | %d | | %.1f (trace time) | | | | | |" % (t, pov[t]))
    lines.append("")
    lines.append("Montecarlo (the thesis's eq. 3 search, no map) at 256x256, 2 threads: render %.0f ms "
                 "(x16 pixels would be about %.0f s at 1024x1024).\n" % (mc["render_ms"], mc["render_ms"] * 16 / 1000))
    lines.append("Targets of issue 3:\n")
    for t in (1, 2):
        a, m = by[("auto", t)], by[("mesh", t)]
        lines.append("- %d thread(s): auto / mesh render = %.2f (target <= 2); POV-Ray trace / auto render = %.1fx "
                     "(target >= 10); POV-Ray / auto incl. prepare = %.1fx" % (
                         t, a["render_ms"] / m["render_ms"], pov[t] / a["render_ms"],
                         pov[t] / (a["render_ms"] + a["prepare_ms"])))
    a = by[("auto", 2)]
    lines.append("- PNG encoding share at 2 threads: %.1f %% (target < 15 %%)" % (
        100 * a["encode_ms"] / (a["render_ms"] + a["encode_ms"])))
    lines.append("- For the record, the thesis needed 5.59 min for a 640x480 teapot.\n")
    lines.append("## Other scenes, 1024x1024, auto-framed, default lights, 2 threads\n")
    lines.append("| scene | method | prepare ms | render ms | hits | fallbacks | iterations/primary |")
    lines.append("|---|---|---|---|---|---|---|")
    sc = os.path.join(DATA, "scenes")
    others = [("teacup", [os.path.join(sc, "teacup.json")]), ("teaspoon", [os.path.join(sc, "teaspoon.json")]),
              ("duck1 (NURBS)", [os.path.join(sc, "duck1.nurbs")]), ("duck2", [os.path.join(sc, "duck2.nurbs")]),
              ("duck3", [os.path.join(sc, "duck3.nurbs")]),
              ("three ducks", [os.path.join(sc, "duck%d.nurbs" % k) for k in (1, 2, 3)])]
    for name, inputs in others:
        for method in ("auto", "bvh", "mesh"):
            r = surfd(inputs, method, 2)
            lines.append("| %s | %s | %.1f | %.1f | %d | %d | %.2f |" % (
                name, method, r["prepare_ms"], r["render_ms"], r["hits"], r["misses"], r["iterations_mean"]))
    lines.append("")


def dicom_bench(lines, n=300):
    """The DICOM network (issue 44): a 300-slice CT series (256 x 256, 39.7 MB) moved between a real
    Orthanc and surfd on this machine (tests/bench/dicom_net.sh): C-STORE from DCMTK's storescu into
    each, Orthanc's C-STORE into DCMTK's storescp (files only) and into surfd's node, WADO-RS by curl
    (the answer to one file) and by surfd's pull (each instance kept). As deployed (DCMTK's Nagle
    on, but in surfd) and with TCP_NODELAY=1 for every DCMTK process."""
    rows = {}
    for mode in ("", "nodelay"):
        out = subprocess.run(["sh", os.path.join(ROOT, "tests", "bench", "dicom_net.sh"), str(n), str(REPEAT)] +
                             ([mode] if mode else []), cwd=ROOT, capture_output=True, text=True,
                             env=dict(os.environ, SURFD_BIN=SURFD, SURFD_DATA=DATA))
        runs = {}
        for line in out.stdout.splitlines():
            k, _, v = line.partition(" ")
            if k.startswith(("storescu", "orthanc", "wado", "cget")):
                runs.setdefault(k, []).append(float(v))
        if not runs:
            lines.append("DICOM network bench failed (%s): %s\n" % (mode or "default", out.stderr.strip()[-300:]))
            return
        rows[mode] = {k: statistics.median(v) for k, v in runs.items()}
    lines.append("## The DICOM network: a 300-slice CT series in and out (issue 44)\n")
    lines.append("%d instances of 256 x 256 int16 (39.7 MB, `tests/bench/ct_series.py`), Orthanc %s with its DICOMweb "
                 "plugin and surfd (release build) on this machine, loopback; seconds, median of %d, and instances per "
                 "second. *As deployed*: DCMTK's own default, Nagle's algorithm on (storescu, storescp, Orthanc); surfd "
                 "sets `TCP_NODELAY=1` for itself. *TCP_NODELAY=1*: every DCMTK process with it, as a site should set it "
                 "(`deploy/orthanc.md`).\n" % (n, "1.10", REPEAT))
    lines.append("| transfer | as deployed | TCP_NODELAY=1 |")
    lines.append("|---|---|---|")
    names = [("storescu_orthanc", "C-STORE: storescu -> Orthanc (peer)"), ("storescu_surfd", "C-STORE: storescu -> surfd's node"),
             ("orthanc_storescp", "C-STORE: Orthanc -> storescp (files only)"), ("orthanc_surfd", "C-STORE: Orthanc -> surfd's node"),
             ("wado_curl", "WADO-RS: curl, the answer to one file"), ("wado_surfd", "WADO-RS: surfd's POST /series/pull (kept)"),
             ("cget_surfd", "C-GET: surfd's POST /series/pull from Orthanc (kept)")]
    for key, label in names:
        cells = ["%.2f s, %.0f/s" % (rows[m][key], n / rows[m][key]) if key in rows.get(m, {}) else "-" for m in ("", "nodelay")]
        lines.append("| %s | %s |" % (label, " | ".join(cells)))
    lines.append("")


def dense_distances(a, b, k=2):
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "mesh_distance_dense.py"), a, b, str(k)],
                       capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def mesh_topology(path):
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "mesh_distance_dense.py"), "--topology",
                        path], capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def merge_bench(lines):
    """Issue 45: the hierarchy's merge=pieces (a vertex per connected piece of surface in a merged cell) on the shared
    CT against its full-resolution mesh: counts, two-way distances measured densely (every triangle's points at quarters,
    both ways), topology, time against VTK's Flying Edges in the same run; VTK's quadric decimation to the same counts
    beside it."""
    name, f, dims, dtype, npt, iso, sp, pad = VOLUMES[0]
    path = os.path.join(DATA, "volumes", f)
    common = [path, "--iso", str(iso), "--dims", "%d,%d,%d" % dims, "--type", dtype, "--spacing", "%.9g,%.9g,%.9g" % sp]
    full = os.path.join(TMP, "ct_full.stl")
    m1 = json.loads(subprocess.run([SURFD, "isosurface"] + common + ["-o", full], capture_output=True, text=True,
                                   check=True).stdout)
    fe = {}
    for t in (1, 2):
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_iso.py"), path] +
                           [str(d) for d in dims] + [npt, str(iso)] + ["%.9g" % x for x in sp] + [str(pad), str(t), "5"],
                           capture_output=True, text=True, check=True)
        fe[t] = json.loads(p.stdout)["flying_edges"]["warm_ms"]
    runs = []
    for levels, me, goal in ((2, 0.5, 2.75), (3, 0.5, 3.6), (3, 1.0, 5.0), (4, 1.0, 5.5)):
        out = os.path.join(TMP, "ct_pieces_l%d_%g.stl" % (levels, me))
        opts = ["--levels", str(levels), "--max-error", str(me), "--merge", "pieces"]
        ms = {}
        for t in (1, 2):
            p = subprocess.run([SURFD, "isosurface"] + common + opts + ["--threads", str(t), "--repeat", "3", "--stats"] +
                               (["-o", out] if t == 1 else []), capture_output=True, text=True, check=True)
            m = json.loads(p.stdout) if t == 1 else m
            ms[t] = float(re.search(r"extract [\d.]+ ms cold, ([\d.]+) ms warm", p.stderr).group(1))
        runs.append((levels, me, goal, m, ms, dense_distances(out, full)))
    v = json.loads(subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_decimate.py"), path] +
                                  [str(d) for d in dims] + [npt, str(iso)] + ["%.9g" % x for x in sp] +
                                  [str(pad), os.path.join(TMP, "vtkm")] + [str(r[3]["triangles"]) for r in runs],
                                  capture_output=True, text=True, check=True).stdout)
    fe_top = mesh_topology(os.path.join(TMP, "vtkm_fe.stl"))
    lines.append("## The hierarchy's merge=pieces (issue 45) on the %s, iso %g\n" % (name, iso))
    lines.append("surfd `isosurface --levels L --max-error MM --merge pieces` against its own full-resolution mesh (%d "
                 "triangles, %d components, Euler characteristic %d). Distances (mm) measured densely both ways by "
                 "`tests/bench/mesh_distance_dense.py` (each mesh's triangles cut twice in four: every corner, edge and "
                 "inside point at quarters, to the other mesh's surface through VTK's exact point-to-triangle distance). "
                 "ms: warm (best of 3) extraction on 1 / 2 threads; Flying Edges (VTK 9, normals on, warm best of 5) in "
                 "the same run: %.1f / %.1f ms. Topology: closed and manifold (no boundary or non-manifold edge), "
                 "components, Euler characteristic. VTK: Flying Edges then vtkQuadricDecimation to the same count "
                 "(`tests/bench/vtk_decimate.py`), its distances to Flying Edges' mesh measured alike.\n" % (
                     m1["triangles"], m1["components"], m1["euler_characteristic"], fe[1], fe[2]))
    lines.append("| pipeline | triangles | fewer than full | target | p99 to full | p99 from full | max to full | "
                 "max from full | ms 1 / 2 threads | x Flying Edges 1 / 2 | closed, manifold | components | Euler | "
                 "vertices by level |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (levels, me, goal, m, ms, d), dec in zip(runs, v["decimated"]):
        lines.append("| surfd levels=%d max_error=%g merge=pieces | %d | %.2fx | %gx | %.3f | %.3f | %.3f | %.3f | %.0f / %.0f "
                     "| %.1f / %.1f | %s | %d | %d | %s |" % (
                         levels, me, m["triangles"], m1["triangles"] / m["triangles"], goal, d["a_to_b"]["p99"],
                         d["b_to_a"]["p99"], d["a_to_b"]["max"], d["b_to_a"]["max"], ms[1], ms[2], ms[1] / fe[1],
                         ms[2] / fe[2], "yes" if m["boundary_edges"] + m["nonmanifold_edges"] == 0 else "NO",
                         m["components"], m["euler_characteristic"], m["cells_by_level"]))
        dpath = os.path.join(TMP, "vtkm_%d.stl" % dec["target"])
        dd, top = dense_distances(dpath, os.path.join(TMP, "vtkm_fe.stl")), mesh_topology(dpath)
        lines.append("| VTK FE + quadric decimation | %d | %.2fx | | %.3f | %.3f | %.3f | %.3f | %.0f + %.0f | | %s | %d | %d "
                     "| |" % (dec["triangles"], v["fe_triangles"] / dec["triangles"], dd["a_to_b"]["p99"],
                              dd["b_to_a"]["p99"], dd["a_to_b"]["max"], dd["b_to_a"]["max"], v["fe_ms"], dec["ms"],
                              "yes" if top["boundary_edges"] + top["nonmanifold_edges"] == 0 else
                              "NO (%d boundary, %d non-manifold edges)" % (top["boundary_edges"], top["nonmanifold_edges"]),
                              top["components"], top["euler_characteristic"]))
    lines.append("\nFlying Edges' own mesh: %d triangles, %d components, Euler characteristic %d.\n" % (
        fe_top["triangles"], fe_top["components"], fe_top["euler_characteristic"]))


def vdb_bench(lines):
    """Issue 45: OpenVDB's adaptive volumeToMesh on the shared CT (tests/bench/vdb_adaptive.cpp, built here when
    Debian's libopenvdb-dev is installed): counts, dense two-way distances to its own full-resolution mesh, topology,
    time against Flying Edges in the same run."""
    name, f, dims, dtype, npt, iso, sp, pad = VOLUMES[0]
    path = os.path.join(DATA, "volumes", f)
    exe = os.path.join(TMP, "vdb_adaptive")
    try:
        subprocess.run(["g++", "-O2", "-std=c++17", os.path.join(ROOT, "tests", "bench", "vdb_adaptive.cpp"), "-o", exe,
                        "-lopenvdb", "-ltbb", "-lImath-3_1"], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        lines.append("OpenVDB's adaptive meshing was not measured: `tests/bench/vdb_adaptive.cpp` does not build here "
                     "(Debian's libopenvdb-dev, libboost-dev, libtbb-dev).\n")
        return
    fe, runs = {}, {}
    for t in (1, 2):
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "bench", "vtk_iso.py"), path] +
                           [str(d) for d in dims] + [npt, str(iso)] + ["%.9g" % x for x in sp] + [str(pad), str(t), "5"],
                           capture_output=True, text=True, check=True)
        fe[t] = json.loads(p.stdout)["flying_edges"]["warm_ms"]
        p = subprocess.run([exe, path] + [str(d) for d in dims] + [str(iso)] + ["%.9g" % x for x in sp] +
                           [str(pad), str(t), os.path.join(TMP, "vdb%d" % t), "0", "0.3", "0.6", "1"],
                           capture_output=True, text=True, check=True)
        runs[t] = json.loads(p.stdout)["runs"]
    full = runs[1][0]
    lines.append("## OpenVDB's adaptive volumeToMesh (issue 45) on the %s, iso %g\n" % (name, iso))
    lines.append("`tests/bench/vdb_adaptive.cpp` (OpenVDB 10, Debian): the samples in a FloatGrid, background %g, "
                 "`volumeToMesh(grid, points, triangles, quads, iso, adaptivity)`, quads cut in two; ms the best of 3 on "
                 "1 / 2 threads (TBB limited), Flying Edges in the same run %.1f / %.1f ms. Distances: densely both ways "
                 "(`mesh_distance_dense.py`, k=2) to its own mesh at adaptivity 0 (%d triangles).\n" % (
                     pad, fe[1], fe[2], full["triangles"]))
    lines.append("| adaptivity | triangles | fewer than its full | p99 to full | p99 from full | max to full | max from full | "
                 "ms 1 / 2 threads | x Flying Edges 1 / 2 | closed, manifold | components | Euler |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r1, r2 in zip(runs[1], runs[2]):
        top = mesh_topology(r1["stl"])
        d = dense_distances(r1["stl"], full["stl"]) if r1["adaptivity"] > 0 else None
        lines.append("| %g | %d | %.2fx | %s | %.0f / %.0f | %.1f / %.1f | %s | %d | %d |" % (
            r1["adaptivity"], r1["triangles"], full["triangles"] / r1["triangles"],
            " | ".join("%.3f" % x for x in (d["a_to_b"]["p99"], d["b_to_a"]["p99"], d["a_to_b"]["max"], d["b_to_a"]["max"]))
            if d else " | | | ", r1["ms"], r2["ms"], r1["ms"] / fe[1], r2["ms"] / fe[2],
            "yes" if top["boundary_edges"] + top["nonmanifold_edges"] == 0 else "NO", top["components"],
            top["euler_characteristic"]))
    lines.append("")


def main():
    parts = {"teapot": (teapot_bench,),
             "iso": (iso_bench, adapt_bench, edit_bench, sharp_bench, big_volume_bench), "adapt": (adapt_bench,),
             "edit": (edit_bench,), "kept": (kept_bench,), "matrix": (matrix_bench,), "aa": (aa_bench,), "views": (views_bench,),
             "cad": (cad_bench,), "shell": (shell_bench,),
             "sharp": (sharp_bench,), "cluster": (cluster_bench,),
             "contours": (contour_bench,), "http": (http_bench,), "small": (small_inputs_bench,),
             "pieces": (pieces_bench,), "dicom": (dicom_bench,), "merge": (merge_bench,), "vdb": (vdb_bench,)}
    only = os.environ.get("BENCH_ONLY")
    if only in parts:  # one part, printed, RESULTS.md left as it is
        lines = []
        for part in parts[only]:
            part(lines)
        print("\n".join(lines))
        return
    lines = []
    lines.append("# Benchmarks\n")
    lines.append("Written by `make bench` (`tests/bench/run.sh` -> `tests/bench/bench.py`); every figure is the median "
                 "of %d runs on this machine, all in one run (POV-Ray's and auto's teapot runs take turns, so that both "
                 "see the same load). Machine: %s, %d cores. render = tracing and shading "
                 "(`render_ms`); prepare = patch extraction, hierarchy, map or mesh (`prepare_ms`); PNG = encoding "
                 "share of render + encode.\n" % (REPEAT, platform.processor() or platform.machine(), os.cpu_count()))
    teapot_bench(lines)
    contour_bench(lines)
    http_bench(lines)
    cluster_bench(lines)
    iso_bench(lines)
    adapt_bench(lines)
    merge_bench(lines)
    vdb_bench(lines)
    edit_bench(lines)
    kept_bench(lines)
    sharp_bench(lines)
    matrix_bench(lines)
    aa_bench(lines)
    cad_bench(lines)
    shell_bench(lines)
    views_bench(lines)
    big_volume_bench(lines)
    small_inputs_bench(lines)
    pieces_bench(lines)
    dicom_bench(lines)
    lines.append("Command: `make bench` (or `BENCH_REPEAT=5 tests/bench/run.sh`; `BENCH_ONLY=teapot`, `BENCH_ONLY=http`, `BENCH_ONLY=contours`, "
                 "`BENCH_ONLY=cluster`, `BENCH_ONLY=iso`, `BENCH_ONLY=adapt`, `BENCH_ONLY=merge`, `BENCH_ONLY=vdb`, `BENCH_ONLY=edit`, `BENCH_ONLY=kept`, `BENCH_ONLY=sharp`, `BENCH_ONLY=matrix`, `BENCH_ONLY=aa`, `BENCH_ONLY=cad`, `BENCH_ONLY=shell`, `BENCH_ONLY=views`, `BENCH_ONLY=small`, `BENCH_ONLY=pieces` or `BENCH_ONLY=dicom` for one part).")
    out = os.path.join(ROOT, "tests", "bench", "RESULTS.md")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
