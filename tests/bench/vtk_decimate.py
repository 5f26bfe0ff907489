#!/usr/bin/python3
"""vtk_decimate.py RAW NX NY NZ DTYPE ISO SX SY SZ PAD OUT_PREFIX N1 [N2 ...]: VTK's pipeline that surfd's adaptive
hierarchy is set against (issue 15): vtkFlyingEdges3D on the padded volume (as vtk_iso.py), then vtkQuadricDecimation
of its mesh to each triangle count N. Writes OUT_PREFIX_fe.stl and OUT_PREFIX_N.stl; prints JSON: Flying Edges' time
and triangles, and per N the decimation's time and the triangles it reached. Run with Debian's python3."""
import json, sys, time
import vtk

from vtk_volume import padded_image

path = sys.argv[1]
nx, ny, nz = map(int, sys.argv[2:5])
dtype, iso = sys.argv[5], float(sys.argv[6])
sp = list(map(float, sys.argv[7:10]))
pad, prefix, targets = float(sys.argv[10]), sys.argv[11], list(map(int, sys.argv[12:]))
img = padded_image(path, nx, ny, nz, dtype, sp, pad)


def write(poly, name):
    w = vtk.vtkSTLWriter()
    w.SetFileName(name)
    w.SetFileTypeToBinary()
    w.SetInputData(poly)
    w.Write()


fe = vtk.vtkFlyingEdges3D()
fe.SetInputData(img)
fe.SetValue(0, iso)
fe.ComputeNormalsOff()
t0 = time.perf_counter()
fe.Update()
out = {"fe_ms": (time.perf_counter() - t0) * 1000, "fe_triangles": fe.GetOutput().GetNumberOfPolys(), "decimated": []}
write(fe.GetOutput(), prefix + "_fe.stl")
n = fe.GetOutput().GetNumberOfPolys()
for target in targets:
    d = vtk.vtkQuadricDecimation()
    d.SetInputData(fe.GetOutput())
    d.SetTargetReduction(1 - target / n)
    t0 = time.perf_counter()
    d.Update()
    ms = (time.perf_counter() - t0) * 1000
    write(d.GetOutput(), "%s_%d.stl" % (prefix, target))
    out["decimated"].append({"target": target, "ms": ms, "triangles": d.GetOutput().GetNumberOfPolys()})
print(json.dumps(out))
