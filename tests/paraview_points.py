"""Under pvpython: print the bounds (x0 x1 y0 y1) of the first block ParaView's default reader makes of a run's
sidecar at its last time (tests/test_paraview.py)."""
import glob
import os
import sys

from paraview.simple import OpenDataFile

path = sys.argv[1]
xdmf = os.path.abspath(glob.glob(os.path.join(path, "*.xdmf"))[0] if os.path.isdir(path) else path)
reader = OpenDataFile(xdmf)
times = reader.TimestepValues  # a float where the run has one step
reader.UpdatePipeline(max(times) if isinstance(times, (list, tuple)) and times else float(times or 0.0))
data = reader.GetClientSideObject().GetOutputDataObject(0)
if data.IsA("vtkCompositeDataSet"):
    it = data.NewIterator()
    it.InitTraversal()
    data = it.GetCurrentDataObject()
print("bounds", " ".join(repr(v) for v in data.GetBounds()[:4]))
