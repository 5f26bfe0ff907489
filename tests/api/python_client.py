"""python_client.py - client/python/surfd.py against the real daemon (tests/api/python_client.sh):
every route it wraps, and each kind of error as one SurfdError with the problem's status and
pointer. Prints PASS/FAIL lines. Environment: SURFD_URL, SURFD_TOKEN, SURFD_DATA, T (a temp dir)."""
import os
import struct
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "client", "python"))
import surfd  # noqa: E402

DATA = os.environ.get("SURFD_DATA", "../shared/data")
T = os.environ["T"]
failures = 0


def check(name, ok, detail=""):
    global failures
    print(("PASS: " if ok else "FAIL: ") + name + ("" if ok or not detail else ": " + str(detail)))
    failures += not ok


def refused(fn, status, pointer=None):
    try:
        fn()
    except surfd.SurfdError as e:
        return e.status == status and (pointer is None or e.pointer == pointer), e
    return False, "no error"


def stl_closed(data):
    n = struct.unpack_from("<I", data, 80)[0]
    edges = {}
    for k in range(n):
        v = struct.unpack_from("<12f", data, 84 + 50 * k)[3:]
        p = [tuple(v[3 * i:3 * i + 3]) for i in range(3)]
        for i in range(3):
            e = (p[i], p[(i + 1) % 3])
            edges[e] = edges.get(e, 0) + 1
    return n > 0 and all(edges.get((b, a), 0) == c for (a, b), c in edges.items())


c = surfd.Client(progress=lambda job: None)
check("version", c.version()["name"] == "surfd")
ell = os.path.join(DATA, "contours", "synthetic_ellipsoid.json")
m = c.model(ell, caps="dome")
check("model(path, caps=): the resource", m["caps"] == "dome" and len(m["id"]) == 32, m)
v = c.volume(ell, caps="dome")
check("volume(): the same volume, nothing stored", abs(v["volume_mm3"] - m["volume_mm3"]) < 1e-6 and "id" not in v)
check("models() lists it, get_model() shows it",
      any(x["id"] == m["id"] for x in c.models()) and c.get_model(m["id"])["volume_mm3"] == m["volume_mm3"])
stl = c.mesh(m["id"], format="stl", tolerance=0.01)
check("mesh(format=stl): bytes of a closed mesh", isinstance(stl, bytes) and stl_closed(stl))
check("mesh(format=vtp): VTK XML", b"VTKFile" in c.mesh(m["id"], format="vtp")[:300])
png = c.view(m["id"], width=80, height=60, projection="orthographic", view="+z")
check("view(projection=, view=+z): a PNG", png[:4] == b"\x89PNG")
check("patches(): a scene of patches", len(c.patches(m["id"]).get("objects", [])) > 0)
rt = c.rtstruct(m["id"], spacing=5)
check("rtstruct(spacing=5): bytes of a DICOM RT Structure Set", rt[128:132] == b"DICM" and b"RTSTRUCT" in rt)
png = c.render(os.path.join(DATA, "scenes", "teapot.bpt"), width=64, height=48, eye=(6, -6, 5), target=(0, 0, 1))
check("render(.bpt, eye=(...), target=(...)): a PNG", png[:4] == b"\x89PNG")
mm = c.matrix(model=m["id"], size=(20, 13, 15))
check("matrix(model=, size=): six matrices", mm["matrix_model"]["size"] == [20, 13, 15] and "exact" in mm)
frep = '{"bounds": [[-1.2, -1.2, -1.2], [1.2, 1.2, 1.2]], "cell": 0.1, "frep": {"sphere": {"center": [0, 0, 0], "radius": 1}}}'
iso = c.isosurface(frep)
check("isosurface(FRep text): a closed model", iso["source"] == "frep" and iso["boundary_edges"] == 0, iso.get("source"))
ed = c.edit(iso["id"], frep={"op": "subtract", "object": {"box": {"min": [0, 0, 0], "max": [2, 2, 2]}}})
check("edit(frep=): the updated model", ed["volume_mm3"] < iso["volume_mm3"] and "edit" in ed)
jid = c.submit("/render", os.path.join(DATA, "scenes", "teapot.json"), width=3000, height=3000, method="montecarlo")
c.cancel(jid)
ok, e = refused(lambda: c.wait(jid), 409)
check("a cancelled job: wait() raises SurfdError 409 with the job's id", ok and e.job == jid, e)
check("jobs(state=) lists jobs", any(j["id"] == jid for j in c.jobs()))
ok, e = refused(lambda: c.model('{"slices": []}'), 422, "/slices")
check("bad contours: SurfdError 422 at /slices", ok, e)
ok, e = refused(lambda: c.render("{not json"), 400)
check("bad JSON: SurfdError 400", ok, e)
ok, e = refused(lambda: c.get_model("0123456789abcdef0123456789abcdef"), 404)
check("no such model: SurfdError 404", ok, e)
ok, e = refused(lambda: c.isosurface(os.path.join(DATA, "volumes", "ct_head_crop64_int16.raw"), dims=(64, 64, 64), type="int16"), 422, "?iso")
check("isosurface without iso: SurfdError 422 at ?iso", ok, e)
ok, e = refused(lambda: surfd.Client(token="wrong").models(), 401)
check("a wrong token: SurfdError 401", ok, e)
ok, e = refused(lambda: surfd.Client(url="http://127.0.0.1:9").models(), 0)
check("surfd unreachable: SurfdError with status 0", ok, e)
c.delete_model(m["id"])
ok, e = refused(lambda: c.get_model(m["id"]), 404)
check("delete_model(): gone", ok, e)
print("%d failed" % failures)
sys.exit(1 if failures else 0)
