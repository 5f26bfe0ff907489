#!/usr/bin/env python3
"""Render benchmarks of issue 3, written to tests/bench/RESULTS.md.

Teapot 1024x1024 (eye [7,-10,6], target [0.2,0,1.3], up z, fov 30°), primary rays + shading with
one shadow-casting light, at 1 and 2 threads, every method; teacup, teaspoon and the three ducks
(auto-framed). In the same run: POV-Ray 3.7 on the same Bézier patches and camera
(bicubic_patch type 1, flatness 0, u_steps 5, v_steps 5; its own "Trace Time"), and surfd's mesh
method. Each figure is the median of REPEAT runs."""
import json, os, platform, re, statistics, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.environ.get("SURFD_DATA", os.path.join(ROOT, "..", "shared", "data"))
SURFD = os.path.join(ROOT, "build", "surfd")
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


def surfd(inputs, method, threads, w=W, h=H):
    runs = []
    for _ in range(REPEAT):
        out = os.path.join(TMP, "out.png")
        p = subprocess.run([SURFD, "render", *inputs, "-o", out, "--method", method, "--threads", str(threads),
                            "--width", str(w), "--height", str(h), "--stats"], capture_output=True, text=True)
        if p.returncode:
            sys.exit(f"surfd failed: {p.stderr}")
        runs.append(json.loads(p.stderr.strip().splitlines()[-1]))
    med = lambda k: statistics.median(r[k] for r in runs)
    r = dict(runs[0])
    for k in ("prepare_ms", "render_ms", "encode_ms"):
        r[k] = med(k)
    return r


def povray(patches, threads):
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
    times = []
    for _ in range(REPEAT):
        p = subprocess.run(["povray", "+I" + pov, "+O" + os.path.join(TMP, "pov.png"), "+W%d" % W, "+H%d" % H,
                            "-D", "+WT%d" % threads, "-V"], capture_output=True, text=True)
        m = re.search(r"Trace Time:.*\(([\d.]+) seconds\)", p.stderr)
        if not m:
            sys.exit("povray: no trace time\n" + p.stderr[-2000:])
        times.append(float(m.group(1)) * 1000)
    return statistics.median(times)


def main():
    rows, notes = [], []
    teapot, patches = scene_file("teapot.json", True)
    pov = {t: povray(patches, t) for t in (1, 2)}
    for method in ("auto", "map", "bvh", "mesh"):
        for t in (1, 2):
            r = surfd([teapot], method, t)
            rows.append(("teapot", method, t, r))
    mc = surfd([teapot], "montecarlo", 2, 256, 256)
    lines = []
    lines.append("# Benchmarks\n")
    lines.append("Written by `make bench` (`tests/bench/run.sh` -> `tests/bench/bench.py`); every figure is the median "
                 "of %d runs on this machine, all in one run. Machine: %s, %d cores. render = tracing and shading "
                 "(`render_ms`); prepare = patch extraction, hierarchy, map or mesh (`prepare_ms`); PNG = encoding "
                 "share of render + encode.\n" % (REPEAT, platform.processor() or platform.machine(), os.cpu_count()))
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
    lines.append("Command: `make bench` (or `BENCH_REPEAT=5 tests/bench/run.sh`).")
    out = os.path.join(ROOT, "tests", "bench", "RESULTS.md")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
