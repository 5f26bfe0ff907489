"""The shared CT or MRI as VTK sees it in the bench: the raw samples padded with one layer of PAD (as
tests/bench/bench.py and ../shared/data/volumes/README.md pad), as vtkImageData (imported by vtk_iso.py and
vtk_decimate.py)."""
import numpy as np
import vtk
from vtk.util import numpy_support as ns


def padded_image(path, nx, ny, nz, dtype, sp, pad):
    a = np.pad(np.fromfile(path, dtype=dtype).reshape(nz, ny, nx), 1, constant_values=pad)
    img = vtk.vtkImageData()
    img.SetDimensions(nx + 2, ny + 2, nz + 2)
    img.SetSpacing(*sp)
    img.SetOrigin(-sp[0], -sp[1], -sp[2])
    img.GetPointData().SetScalars(ns.numpy_to_vtk(a.ravel(), deep=True))
    return img
