#!/usr/bin/python3
"""Two-way distances between two meshes, densely: each mesh's points of its triangles cut k times
in four (every vertex, the points at 1/2^k steps of every edge, the lattice points inside every
triangle) and the distance from every point of that to the other mesh's surface (vtkImplicitPolyDataDistance, an
exact point-to-triangle distance through a cell locator). Independent of surfd's own bounds.
Prints JSON: p50, p99, max each way and the points measured, in the meshes' units.

usage: mesh_distance_dense.py A.stl B.stl [k=2]
       mesh_distance_dense.py --topology A.stl: boundary and non-manifold edges, components, Euler
       characteristic (corners welded by position) as JSON"""
import json, sys

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy


def read(path):
    r = vtk.vtkSTLReader()
    r.SetFileName(path)
    r.Update()
    c = vtk.vtkCleanPolyData()  # STL repeats each corner: weld them, so the subdivision shares edge points
    c.SetInputData(r.GetOutput())
    c.Update()
    return c.GetOutput()


def dense(mesh, k):
    """Every vertex, the points at 1/2^k steps along every edge and the lattice points inside every
    triangle (the points of k linear subdivisions, taken on non-manifold meshes too)."""
    pts = vtk_to_numpy(mesh.GetPoints().GetData()).astype(float)
    n = 1 << k
    if n == 1:
        return pts
    tri = vtk_to_numpy(mesh.GetPolys().GetData()).reshape(-1, 4)[:, 1:]
    e = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1), axis=0)
    out = [pts]
    for j in range(1, n):
        out.append(pts[e[:, 0]] * (1 - j / n) + pts[e[:, 1]] * (j / n))
    for a in range(1, n):
        for b in range(1, n - a):
            c = n - a - b
            out.append((pts[tri[:, 0]] * a + pts[tri[:, 1]] * b + pts[tri[:, 2]] * c) / n)
    return np.concatenate(out)


def to_surface(mesh, pts):
    f = vtk.vtkImplicitPolyDataDistance()
    f.SetInput(mesh)
    arr = vtk.vtkDoubleArray()
    arr.SetNumberOfTuples(len(pts))
    from vtk.util.numpy_support import numpy_to_vtk
    v = numpy_to_vtk(np.ascontiguousarray(pts), deep=1)
    out = vtk.vtkDoubleArray()
    f.FunctionValue(v, out)
    return np.abs(vtk_to_numpy(out))


def topology(mesh):
    """Edges of one triangle and of three or more, components by shared edges, V - E + F."""
    tri = vtk_to_numpy(mesh.GetPolys().GetData()).reshape(-1, 4)[:, 1:]
    e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    keys, counts = np.unique(e[:, 0].astype(np.int64) * (1 << 32) + e[:, 1], return_counts=True)
    parent = np.arange(mesh.GetNumberOfPoints())

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x
    for a, b in e:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    used = np.unique(tri)
    comps = len({find(v) for v in used})
    return {"boundary_edges": int((counts == 1).sum()), "nonmanifold_edges": int((counts > 2).sum()),
            "components": comps, "euler_characteristic": int(len(used) - len(keys) + len(tri)),
            "triangles": int(len(tri))}


def main():
    if sys.argv[1] == "--topology":
        print(json.dumps(topology(read(sys.argv[2]))))
        return
    a, b = read(sys.argv[1]), read(sys.argv[2])
    k = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    res = {}
    for name, src, dst in (("a_to_b", a, b), ("b_to_a", b, a)):
        d = to_surface(dst, dense(src, k))
        res[name] = {"p50": float(np.percentile(d, 50)), "p99": float(np.percentile(d, 99)), "max": float(d.max()),
                     "n": int(len(d))}
    print(json.dumps(res))


if __name__ == "__main__":
    main()
