#!/usr/bin/python3
"""Reads a mesh file with VTK (Debian's python3-vtk9) as ParaView and 3D Slicer would: .vtp by
vtkXMLPolyDataReader, .vtk by vtkPolyDataReader. Prints {"triangles", "points", "normals",
"boundary_edges", "volume"} as JSON; exit 1 when VTK cannot read it.

  vtk_check.py FILE"""
import json
import sys

import vtk

path = sys.argv[1]
reader = vtk.vtkXMLPolyDataReader() if path.endswith(".vtp") else vtk.vtkPolyDataReader()
reader.SetFileName(path)
reader.Update()
pd = reader.GetOutput()
if pd is None or pd.GetNumberOfPoints() == 0:
    sys.exit(1)
edges = vtk.vtkFeatureEdges()
edges.SetInputData(pd)
edges.BoundaryEdgesOn()
edges.FeatureEdgesOff()
edges.ManifoldEdgesOff()
edges.NonManifoldEdgesOff()
edges.Update()
mass = vtk.vtkMassProperties()
mass.SetInputData(pd)
mass.Update()
normals = pd.GetPointData().GetNormals()
print(json.dumps({"triangles": pd.GetNumberOfPolys(), "points": pd.GetNumberOfPoints(),
                  "normals": normals is not None and normals.GetNumberOfTuples() == pd.GetNumberOfPoints(),
                  "boundary_edges": edges.GetOutput().GetNumberOfCells(), "volume": mass.GetVolume()}))
