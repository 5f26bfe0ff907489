#!/usr/bin/python3
"""Sharp features (issue 15): CSG solids turned off the grid's axes, polygonised by surfd with
features=none and features=sharp at cells of 1/50 of their size; for each, the distance from
points of the true edges (box edges, and the curves where a hole meets a face), every cell/8
along them, and from the true corners to the mesh (VTK's cell locator), in cells, and the mesh's
volume against the exact one. Prints JSON, one object per solid.

usage: sharp_edges.py SURFD TMPDIR"""
import json, math, os, subprocess, sys

import numpy as np

from mesh_distance import read as read_stl, to_surface as distances

ROT = (20.0, 30.0, 10.0)  # degrees about x, then y, then z (the FRep transform's order)


def rotation(deg):
    a, b, c = (math.radians(d) for d in deg)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx


def box(lo, hi):
    return {"box": {"min": list(lo), "max": list(hi)}}


def cylinder(base, axis, r, length):
    return {"cylinder": {"base": list(base), "axis": list(axis), "radius": r, "length": length}}


def segment(p, q, step):
    p, q = np.array(p, float), np.array(q, float)
    n = max(2, int(math.ceil(np.linalg.norm(q - p) / step)) + 1)
    return [p + (q - p) * t for t in np.linspace(0, 1, n)]


def circle(centre, u, v, r, step):
    n = max(8, int(math.ceil(2 * math.pi * r / step)))
    c, u, v = np.array(centre, float), np.array(u, float), np.array(v, float)
    return [c + r * (math.cos(t) * u + math.sin(t) * v) for t in np.linspace(0, 2 * math.pi, n, endpoint=False)]


def box_edges(lo, hi, step):
    pts, corners = [], []
    for k in range(8):
        corners.append([hi[d] if k >> d & 1 else lo[d] for d in range(3)])
    for k in range(8):
        for d in range(3):
            if not k >> d & 1:
                pts += segment(corners[k], corners[k | 1 << d], step)
    return pts, corners


def solids(step):
    """(name, FRep tree in its own frame, exact volume, edge points, corners), each about 2 units across."""
    out = []
    lo, hi = (-1, -0.7, -0.5), (1, 0.7, 0.5)
    e, c = box_edges(lo, hi, step)
    r = 0.35
    e2 = e + circle((0, 0, -0.5), (1, 0, 0), (0, 1, 0), r, step) + circle((0, 0, 0.5), (1, 0, 0), (0, 1, 0), r, step)
    out.append(("box minus cylinder", {"subtract": [box(lo, hi), cylinder((0, 0, -1), (0, 0, 1), r, 2)]},
                2 * 1.4 * 1.0 - math.pi * r * r * 1.0, e2, c))
    rb = 0.3
    e3 = e + circle((0.4, 0.2, 0.5), (1, 0, 0), (0, 1, 0), rb, step)
    out.append(("box minus ball", {"subtract": [box(lo, hi), {"sphere": {"center": [0.4, 0.2, 0.5], "radius": rb}}]},
                2 * 1.4 * 1.0 - 2 / 3 * math.pi * rb ** 3, e3, c))
    # a bracket: an L of a base plate and an upright, a hole through each
    prof = [(-1, -0.5), (1, -0.5), (1, -0.2), (-0.7, -0.2), (-0.7, 0.8), (-1, 0.8)]  # (x, z)
    pts, corners = [], []
    for i, (x, z) in enumerate(prof):
        x2, z2 = prof[(i + 1) % len(prof)]
        pts += segment((x, -0.6, z), (x, 0.6, z), step)
        for y in (-0.6, 0.6):
            pts += segment((x, y, z), (x2, y, z2), step)
            corners.append((x, y, z))
    r1, r2 = 0.25, 0.2
    pts += circle((0.4, 0, -0.5), (1, 0, 0), (0, 1, 0), r1, step) + circle((0.4, 0, -0.2), (1, 0, 0), (0, 1, 0), r1, step)
    pts += circle((-1, 0, 0.4), (0, 1, 0), (0, 0, 1), r2, step) + circle((-0.7, 0, 0.4), (0, 1, 0), (0, 0, 1), r2, step)
    tree = {"subtract": [{"union": [box((-1, -0.6, -0.5), (1, 0.6, -0.2)), box((-1, -0.6, -0.5), (-0.7, 0.6, 0.8))]},
                         cylinder((0.4, 0, -1), (0, 0, 1), r1, 2), cylinder((-1.5, 0, 0.4), (1, 0, 0), r2, 2)]}
    vol = 2 * 1.2 * 0.3 + 0.3 * 1.2 * 1.0 - math.pi * r1 * r1 * 0.3 - math.pi * r2 * r2 * 0.3
    out.append(("bracket", tree, vol, pts, corners))
    return out


def main():
    surfd, tmp = sys.argv[1], sys.argv[2]
    cell = 2.0 / 50
    R = rotation(ROT)
    res = []
    for name, tree, vol, edges, corners in solids(cell / 8):
        req = {"name": name, "bounds": [[-1.6] * 3, [1.6] * 3], "cell": cell, "alpha": 0,
               "frep": {"transform": {"rotate_deg": list(ROT), "object": tree}}}
        path = os.path.join(tmp, "sharp.json")
        with open(path, "w") as f:
            json.dump(req, f)
        row = {"solid": name, "cell": cell, "edge_points": len(edges), "corners": len(corners), "exact_volume": vol}
        for features in ("none", "sharp"):
            stl = os.path.join(tmp, "sharp_%s.stl" % features)
            p = subprocess.run([surfd, "isosurface", path, "--features", features, "-o", stl], capture_output=True,
                               text=True, check=True)
            m = json.loads(p.stdout)
            mesh = read_stl(stl)
            de = distances(mesh, [R @ q for q in edges]) / cell
            dc = distances(mesh, [R @ np.array(q, float) for q in corners]) / cell
            row[features] = {"triangles": m["triangles"], "ms": m["timings_ms"]["extract"],
                             "closed": m["boundary_edges"] + m["nonmanifold_edges"] == 0,
                             "edge_max": float(de.max()), "edge_p99": float(np.percentile(de, 99)),
                             "edge_mean": float(de.mean()), "corner_max": float(dc.max()),
                             "volume_error_pct": 100 * (m["volume_mm3"] / vol - 1),
                             "feature_points": m.get("feature_points", 0), "face_points": m.get("face_points", 0)}
        res.append(row)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
