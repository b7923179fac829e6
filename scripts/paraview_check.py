"""Open a run's XDMF sidecar in ParaView's default reader and print what it shows.

    pvpython scripts/paraview_check.py OUT/couette_paper.xdmf     (or the output directory)
    xvfb-run -a pvpython scripts/paraview_check.py --screenshot FILE.png OUT

Runs under ParaView's Python (Debian: ``apt-get install paraview python3-paraview``),
not parsph's virtual environment. For every time step it prints the points and
cells ParaView builds (one cell per point: without cells the render view stays
empty), the point arrays it reads (components and range), and checks that id,
kind, theta, vx, vy (vz in 3-D) and the 3-component ``velocity`` vector (the
active vectors, for glyphs) are there, and that the Glyph filter accepts
``velocity`` as its orientation; for a layer, drawn upright, that ``velocity``
is (vy, vx, .) in ParaView's frame. For the last step it bins the fluid points in
x (ParaView's Y for a layer) as parsph's profile does (bins of L / Nx; Eq. (8)'s reference and the scale
come with the step's ``parsph.profile`` Information element) and prints the max
and RMS error of the scene's error field computed from ParaView's arrays,
beside the error parsph recorded. ``--screenshot FILE.png`` renders the last
step as a user sees it after Apply (the default representation, coloured by
vy, camera reset; no axes, no colour bar) and prints the fraction of its pixels
that differ from the background (it needs a display: xvfb-run on a server).
Exit status: 0 when every step shows every array in one cell per point, 1
otherwise, 2 on bad input.
"""
import glob
import json
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np


def sidecar(path):
    """The .xdmf file named by ``path`` (a file or a directory holding exactly one)."""
    if os.path.isdir(path):
        found = glob.glob(os.path.join(path, "*.xdmf"))
        if len(found) != 1:
            raise SystemExit(f"paraview_check: {path} holds {len(found)} .xdmf files; name one")
        path = found[0]
    if not os.path.isfile(path):
        raise SystemExit(f"paraview_check: no such file {path}")
    return os.path.abspath(path)  # Xdmf3 joins a bare relative name wrongly with the HDF5 names


def steps_of(xdmf):
    """(time, dim, profile dict) of each uniform grid of the sidecar, in time order."""
    out = []
    for grid in ET.parse(xdmf).getroot().iter("Grid"):
        if grid.get("GridType") != "Uniform" or grid.get("Name", "").endswith(":grid"):
            continue  # the solved gas's grid (its own collection) is not a point set
        info = {i.get("Name"): i.get("Value") for i in grid.findall("Information")}
        dim = 2 if grid.find("Geometry").get("GeometryType") in ("XY", "X_Y") else 3
        out.append((float(grid.find("Time").get("Value")), dim, json.loads(info["parsph.profile"])))
    return sorted(out, key=lambda s: s[0])


def point_data(reader, t):
    """The reader's output at time t as (points (N, 3), {name: array}, active vectors name, cells)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    reader.UpdatePipeline(t)
    data = reader.GetClientSideObject().GetOutputDataObject(0)
    if data.IsA("vtkCompositeDataSet"):  # one block per step is expected; take the first leaf
        it = data.NewIterator()
        it.InitTraversal()
        data = it.GetCurrentDataObject()
    pd = data.GetPointData()
    arrays = {pd.GetArrayName(i): vtk_to_numpy(pd.GetArray(i)) for i in range(pd.GetNumberOfArrays())}
    vectors = pd.GetVectors().GetName() if pd.GetVectors() is not None else None
    return vtk_to_numpy(data.GetPoints().GetData()), arrays, vectors, data.GetNumberOfCells()


def screenshot(reader, t, png):
    """Render step t as the GUI shows it after Apply (default representation, coloured by vy), save
    it to ``png`` and return the fraction of its pixels that differ from the background colour."""
    import numpy as np
    from paraview.simple import ColorBy, CreateView, Delete, SaveScreenshot, Show
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOImage import vtkPNGReader
    view = CreateView("RenderView")
    view.OrientationAxesVisibility = 0
    view.ViewSize = [640, 480]
    view.ViewTime = t
    rep = Show(reader, view)
    ColorBy(rep, ("POINTS", "vy"))
    rep.SetScalarBarVisibility(view, False)
    view.ResetCamera()
    SaveScreenshot(png, view, ImageResolution=[640, 480], TransparentBackground=0)
    r = vtkPNGReader()
    r.SetFileName(png)
    r.Update()
    img = r.GetOutput()
    w, h, _ = img.GetDimensions()
    pixels = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h * w, -1)[:, :3].astype(float)
    background = np.array(view.Background) * 255.0
    Delete(rep)
    Delete(view)  # a view left at exit aborts the process (GLXBadContext) under xvfb
    return float(np.mean(np.abs(pixels - background).max(axis=1) > 8.0))


def glyph_points(reader, t):
    """Points of ParaView's Glyph filter (arrows) oriented by ``velocity``; 0 when ParaView does not
    offer ``velocity`` as an orientation array (it offers only 3-component arrays)."""
    from paraview.simple import Delete, Glyph
    g = Glyph(Input=reader, GlyphType="Arrow")
    domain = g.GetProperty("OrientationArray").SMProperty.FindDomain("vtkSMArrayListDomain")
    offered = [domain.GetString(i) for i in range(domain.GetNumberOfStrings())]
    n = 0
    if "velocity" in offered:
        g.OrientationArray = ["POINTS", "velocity"]
        g.ScaleArray = ["POINTS", "No scale array"]
        g.UpdatePipeline(t)
        n = g.GetClientSideObject().GetOutputDataObject(0).GetNumberOfPoints()
    Delete(g)
    return n


def profile_error(points, arrays, prof):
    """(max, rms) of |mean field per x bin - reference| / scale over the fluid points (kind 0); x is
    ParaView's axis ``prof["axis"]`` (Y for a layer, drawn upright)."""
    fluid = arrays["kind"] == 0
    x = points[fluid, prof.get("axis", 0)]
    f = arrays[prof["field"]][fluid]
    nb = prof["bins"]
    b = np.clip(np.trunc(x / (prof["L"] / nb)).astype(np.int64), 0, nb - 1)
    count = np.bincount(b, minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.bincount(b, weights=f, minlength=nb) / count
        e = np.abs(mean - np.array(prof["exact"], dtype=float)) / abs(prof["scale"])
    e = e[np.isfinite(e)]
    if e.size == 0:
        return float("nan"), float("nan")
    return float(e.max()), float(np.sqrt(np.mean(e * e)))


def prof_of(steps, t):
    return next(p for s, _, p in steps if s == t)


def main(argv):
    png = None
    if len(argv) == 3 and argv[0] == "--screenshot":
        png, argv = argv[1], argv[2:]
    if len(argv) != 1 or argv[0].startswith("-"):
        print(__doc__.strip().split("\n\n")[1], file=sys.stderr)
        return 2
    xdmf = sidecar(argv[0])
    from paraview.simple import GetParaViewSourceVersion, OpenDataFile
    steps = steps_of(xdmf)
    reader = OpenDataFile(xdmf)
    print(f"reader: {reader.GetXMLName()} ({GetParaViewSourceVersion()}; OpenDataFile's default for .xdmf)")
    print(f"file: {xdmf}: {len(steps)} time step(s)")
    ok = True
    for t, dim, _ in steps:
        points, arrays, vectors, cells = point_data(reader, t)
        want = ["id", "kind", "theta", "velocity"] + ["v" + c for c in "xyz"[:dim]]
        missing = [a for a in want if a not in arrays]
        bad_vector = "velocity" in arrays and (arrays["velocity"].ndim != 2 or arrays["velocity"].shape[1] != 3)
        shown = []
        for name, a in arrays.items():
            comps = 1 if a.ndim == 1 else a.shape[1]
            lo, hi = (float(a.min()), float(a.max())) if a.size else (float("nan"),) * 2
            shown.append(f"{name} ({comps}{', vectors' if name == vectors else ''}) [{lo:.6g}, {hi:.6g}]")
        print(f"t = {t!r} s: {len(points)} points, {cells} cells; " + "; ".join(shown))
        if cells != len(points):
            ok = False
            print(f"  {cells} cells for {len(points)} points: ParaView draws only cells")
        if missing or bad_vector or vectors != "velocity":
            ok = False
            print(f"  missing: {', '.join(missing) or 'none'}; velocity is the active 3-component vector: "
                  f"{not bad_vector and vectors == 'velocity'}")
        elif prof_of(steps, t).get("axis", 0) == 1:  # upright: ParaView's frame is the file's (y, x, z)
            v = arrays["velocity"]
            turned = (np.array_equal(v[:, 0], arrays["vy"].astype(v.dtype))
                      and np.array_equal(v[:, 1], arrays["vx"].astype(v.dtype)))
            print(f"  upright (the height along Y): velocity = (vy, vx, .) on every point: {turned}")
            ok = ok and turned
    if steps:
        t, _, prof = steps[-1]
        glyphs = glyph_points(reader, t)
        print(f"Glyph filter oriented by velocity at t = {t!r} s: {glyphs} points of arrows")
        ok = ok and glyphs > 0
        points, arrays, _, _ = point_data(reader, t)
        if not np.isfinite(np.array(prof["exact"], dtype=float)).any():
            print(f"profile error at t = {t!r} s: the scene has no reference")
        else:
            emax, erms = profile_error(points, arrays, prof)
            print(f"profile error of {prof['field']} at t = {t!r} s (last step), relative to {prof['scale']:.4g}: "
                  f"max {emax:.6e}, rms {erms:.6e} from ParaView's points; "
                  f"parsph: max {prof['err_max']:.6e}, rms {prof['err_rms']:.6e}")
        if png is not None:
            drawn = screenshot(reader, t, png)
            print(f"screenshot of t = {t!r} s: {png}: {drawn:.4f} of the pixels differ from the background")
    print("all arrays present on every step" if ok else "some arrays are missing")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
