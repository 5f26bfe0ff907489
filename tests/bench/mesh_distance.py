#!/usr/bin/python3
"""Distances between two meshes, both ways: for every vertex of each, the distance to the nearest
point of the other's surface (VTK's cell locator). Prints JSON: p50, p99, max each way, in the
meshes' units. Used by the bench for the adaptive hierarchy's max_error (issue 15).

usage: mesh_distance.py A.stl B.stl"""
import json, sys

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy


def read(path):
    r = vtk.vtkSTLReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def to_surface(mesh, pts):
    """The distance from each of pts to mesh's surface."""
    loc = vtk.vtkStaticCellLocator()
    loc.SetDataSet(mesh)
    loc.BuildLocator()
    out = np.empty(len(pts))
    c, cell, sub, d2 = [0.0, 0.0, 0.0], vtk.reference(0), vtk.reference(0), vtk.reference(0.0)
    for i, p in enumerate(pts):
        loc.FindClosestPoint(list(p), c, cell, sub, d2)
        out[i] = d2.get() ** 0.5
    return out


def one_way(a, b):
    return to_surface(b, vtk_to_numpy(a.GetPoints().GetData()).astype(float))


def main():
    a, b = read(sys.argv[1]), read(sys.argv[2])
    res = {}
    for name, d in (("a_to_b", one_way(a, b)), ("b_to_a", one_way(b, a))):
        res[name] = {"p50": float(np.percentile(d, 50)), "p99": float(np.percentile(d, 99)), "max": float(d.max()),
                     "n": int(len(d))}
    print(json.dumps(res))


if __name__ == "__main__":
    main()
