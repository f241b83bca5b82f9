"""PNG files as numpy arrays, for the export tests (test_consumers, test_page)."""
import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOImage import vtkPNGReader


def png(path):
    """The image's RGB, rows top to bottom, as int32 (h, w, 3)."""
    r = vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    w, h, _ = r.GetOutput().GetDimensions()
    a = vtk_to_numpy(r.GetOutput().GetPointData().GetScalars())
    return a.reshape(h, w, -1)[::-1, :, :3].astype(np.int32)
