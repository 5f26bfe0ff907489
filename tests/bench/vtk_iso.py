#!/usr/bin/python3
"""vtk_iso.py RAW NX NY NZ DTYPE ISO SX SY SZ PAD THREADS REPEAT: VTK's vtkFlyingEdges3D and vtkMarchingCubes
on the raw volume padded with one layer of PAD (as tests/bench/bench.py and ../shared/data/volumes/README.md pad),
normals computed as surfd computes them. Prints JSON: per filter the first (cold) and the best (warm) Update() time
in ms, the triangle and vertex counts and the volume (vtkMassProperties). Run with Debian's python3 (python3-vtk9)."""
import json, sys, time
import vtk

from vtk_volume import padded_image

path = sys.argv[1]
nx, ny, nz = map(int, sys.argv[2:5])
dtype, iso = sys.argv[5], float(sys.argv[6])
sp = list(map(float, sys.argv[7:10]))
pad, threads, repeat = float(sys.argv[10]), int(sys.argv[11]), int(sys.argv[12])
img = padded_image(path, nx, ny, nz, dtype, sp, pad)
vtk.vtkSMPTools.Initialize(threads)
out = {}
for name, cls in (("flying_edges", vtk.vtkFlyingEdges3D), ("marching_cubes", vtk.vtkMarchingCubes)):
    times = []
    for _ in range(repeat):
        f = cls()
        f.SetInputData(img)
        f.SetValue(0, iso)
        f.ComputeNormalsOn()
        f.ComputeGradientsOff()
        f.ComputeScalarsOff()
        t0 = time.perf_counter()
        f.Update()
        times.append((time.perf_counter() - t0) * 1000)
    mp = vtk.vtkMassProperties()
    mp.SetInputData(f.GetOutput())
    mp.Update()
    out[name] = {"cold_ms": times[0], "warm_ms": min(times), "triangles": f.GetOutput().GetNumberOfPolys(),
                 "vertices": f.GetOutput().GetNumberOfPoints(), "volume": mp.GetVolume()}
print(json.dumps(out))
