"""Structural check of a parsph XDMF sidecar against the HDF5 files it names (serial h5py).

Used by test_xdmf.py (always runs) and test_mpi_io.py (on the outputs of real runs).
What ParaView 5.11's default reader (Xdmf3ReaderS) accepts, found with pvpython:
plain HDF DataItems with NumberType and Precision, hyperslabs only in Xdmf3's
content syntax ``file:path|start:stride:count:dims`` (ItemType="HyperSlab" and
"Function" items are skipped: their type is unknown before they are read), and an
Information element only with a Value attribute; and it makes cells only from an
explicit connectivity (a Polyvertex topology without one gives N points, 0 cells
and an empty render view).
"""
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np

UPRIGHT = (1, 0, 2)  # a layer's columns along ParaView's X, Y, Z: written out here, not imported

NUMBER_TYPES = {("f", 8): "Float", ("f", 4): "Float", ("i", 8): "Int", ("i", 4): "Int", ("i", 1): "Char",
                ("u", 1): "UChar"}


def parse_item(item):
    """(file, dataset path, hyperslab (start, stride, count, dims) or None) of an HDF DataItem."""
    text = item.text.strip()
    fname, _, rest = text.partition(":")
    path, bar, slab = rest.partition("|")
    if not bar:
        return fname, path, None
    parts = [tuple(int(v) for v in p.split()) for p in slab.split(":")]
    assert len(parts) == 4, text
    return fname, path, tuple(parts)


def check_sidecar(xdmf, files, n, dim):
    """Assert the sidecar lists ``files`` (in time order) as ``n`` points in ``dim`` D each,
    with every array readable as it states and meaning what its name says."""
    xdmf = Path(xdmf)
    root = ET.parse(xdmf).getroot()  # well-formed XML
    assert root.tag == "Xdmf" and root.get("Version") == "3.0"
    for el in root.iter():
        assert el.get("ItemType") is None, f"{el.tag} {el.attrib}: ParaView's default reader skips ItemType items"
    collection = [g for g in root.iter("Grid") if g.get("GridType") == "Collection"]
    assert len(collection) == 1 and collection[0].get("CollectionType") == "Temporal"
    grids = [g for g in root.iter("Grid") if g.get("GridType") == "Uniform"]
    assert [g.get("Name") for g in grids] == list(files)
    cells_file = xdmf.stem + ".cells.h5"
    times = [float(g.find("Time").get("Value")) for g in grids]
    assert times == sorted(times)
    comps = ["v" + c for c in "xyz"[:dim]]
    for g, fname in zip(grids, files):
        with h5py.File(xdmf.parent / fname, "r") as f:
            assert float(g.find("Time").get("Value")) == f.attrs["time"]
            topo = g.find("Topology")
            assert topo.get("TopologyType") == "Polyvertex" and topo.get("NumberOfElements") == str(n)
            assert topo.get("NodesPerElement") == "1"
            # one cell per point, listed explicitly: without it ParaView's default reader draws nothing
            items = topo.findall("DataItem")
            assert len(items) == 1, "the topology has no connectivity"
            cfile, cpath, slab = parse_item(items[0])
            assert cfile == cells_file and cpath == "/connectivity" and slab is None, items[0].text
            assert items[0].get("Format") == "HDF" and items[0].get("Dimensions") == str(n)
            with h5py.File(xdmf.parent / cfile, "r") as c:
                conn = c[cpath][()]
            assert items[0].get("NumberType") == NUMBER_TYPES[(conn.dtype.kind, conn.dtype.itemsize)]
            assert int(items[0].get("Precision")) == conn.dtype.itemsize
            assert np.array_equal(conn, np.arange(n)), "cell k must be the particle of row k"
            # a layer (H0 among the root attributes) opens upright: ParaView's X, Y(, Z) = the file's y, x(, z)
            upright = "H0" in f.attrs
            geometry = g.find("Geometry")
            assert geometry.get("GeometryType") == ("XY" if dim == 2 else "XYZ")
            # the profile Information: what a script needs to recompute parsph's error from the points
            info = [i for i in g.findall("Information") if i.get("Name") == "parsph.profile"]
            assert len(info) == 1 and info[0].text is None  # Xdmf3 aborts on an Information without Value
            prof = json.loads(info[0].get("Value"))
            field = f.attrs["error_field"]
            assert prof["field"] == field and prof["scale"] == f.attrs["error_scale"]
            assert prof["L"] == f.attrs["L"] and prof["bins"] == f["profile/x"].shape[0]
            assert np.array_equal(np.array(prof["exact"], dtype=float), f[f"profile/{field}_exact"][()],
                                  equal_nan=True)
            assert prof["err_max"] == f["profile"].attrs["err_max"]
            assert prof["err_rms"] == f["profile"].attrs["err_rms"]

            attrs = {a.get("Name"): a for a in g.findall("Attribute")}
            assert set(attrs) == {"id", "kind", "theta", "velocity", *comps}, sorted(attrs)
            velocity = f["particles/velocity"][()]
            assert velocity.shape == (n, dim)
            holders = [("geometry", geometry)] + list(attrs.items())
            for name, holder in holders:
                items = holder.findall("DataItem")
                assert len(items) == 1, name
                item = items[0]
                assert item.get("Format") == "HDF", name
                ref, path, slab = parse_item(item)
                assert ref == fname, f"{name}: grid {fname} names {ref}"  # relative to the sidecar
                assert path.startswith("/particles/") and path in f, f"{path} is not in {fname}"
                ds = f[path]
                assert item.get("NumberType") == NUMBER_TYPES[(ds.dtype.kind, ds.dtype.itemsize)], name
                assert int(item.get("Precision")) == ds.dtype.itemsize, name
                dims = tuple(int(v) for v in item.get("Dimensions").split())
                if slab is None:
                    assert dims == ds.shape, name
                    data = ds[()]
                else:
                    start, stride, count, space = slab
                    assert space == ds.shape and stride == (1, 1) and count == (n, 1) and dims == (n,), name
                    assert start[0] == 0 and 0 <= start[1] < ds.shape[1], name
                    data = ds[:, start[1]]
                if name != "geometry":
                    assert holder.get("Center") == "Node", name
                    assert holder.get("AttributeType") == ("Vector" if name == "velocity" else "Scalar"), name
                # each array means what its name says
                if name == "geometry":
                    position = f["particles/position"][()]
                    if upright:  # the display copy: the columns (y, x[, z])
                        assert path == "/particles/position_view"
                        assert np.array_equal(data, position[:, list(UPRIGHT[:dim])])
                    else:
                        assert path == "/particles/position" and np.array_equal(data, position)
                elif name in comps:
                    assert np.array_equal(data, velocity[:, comps.index(name)]), name
                elif name == "velocity":
                    assert data.shape == (n, 3)
                    if dim == 3 and not upright:
                        assert path == "/particles/velocity"
                        assert np.array_equal(data, velocity)
                    else:  # a float32 copy in ParaView's frame, padded with 0: glyphs need 3 components
                        assert path == "/particles/velocity_xyz" and data.dtype == np.float32
                        cols = UPRIGHT if upright else (0, 1, 2)
                        for k, c in enumerate(cols):
                            want = velocity[:, c].astype(np.float32) if c < dim else 0.0
                            assert np.all(data[:, k] == want), (name, k)
                else:
                    assert path == f"/particles/{name}" and data.shape == (n,), name
    return grids
