"""The ParaView sidecar: an XDMF file that shows the snapshots as a time series of points.

Each output file with particles is one grid of the temporal collection;
the profile and its error travel as an Information element, so that scripts
can compare ParaView's view of the particles with parsph's profile.

Every grid's topology is N one-point cells (Polyvertex) with an explicit
connectivity 0 .. N-1, held once per run in ``<name>.cells.h5``: without a
connectivity ParaView's default reader (Xdmf3ReaderS) builds the points but no
cells, and draws nothing.

Outputs of a solved gas also hold its grid (``/grid``); a second temporal collection, "gas grid", shows
its cells with theta and p' as cell data, and u_g and j as cell vectors (from the files' display copies
``/grid/u_g_xyz``, ``/grid/j_xyz``: 3 components, in the frame ParaView draws). Its topology is a
structured mesh (2DSMesh; 3DSMesh in 3-D) whose nodes, (x_i, y_j[, z_k]) = (i h_x, j h_y[, k h_z]), are
written once in ``<name>.cells.h5:/grid_nodes``: the arrays are (n_x, n_y[, n_z]) with x the slow index, and the explicit nodes
place the cells as the particles are placed (below), so that the cells lie under the particles.

A layer or bed (gravity along -x: the outputs carry ``H0``) opens upright: ParaView's X is the file's y and
its Y the file's x (the height), for the particles (the files' display copy ``position_view``, (y, x, z):
ParaView 5.11's Xdmf3 reader crashes on a geometry X_Y of two columns), their ``velocity`` vector (the display
copy ``velocity_xyz``, written in that frame: (v_y, v_x, v_z)) and the gas grid's nodes alike. That swap
mirrors the periodic width, which changes nothing; the arrays keep the files' meaning (``vx`` is still the
velocity along the height) and the files keep their coordinates.
"""
import json
import os
import xml.etree.ElementTree as ET

import h5py
import numpy as np

from .layout import FILE_DTYPES


def snapshot_entry(name, time, snapshot, n, dim, field, scale, L, exact, err_max, err_rms, grid=None,
                   upright=False):
    """What the sidecar says of one output file (a dict; ``profile`` travels as an Information
    element so that scripts can compare ParaView's view of the particles with parsph's profile, its
    ``axis`` the ParaView axis of the file's x; ``grid``: (n_x, n_y[, n_z], h_x, h_y[, h_z]) of the gas grid the
    file holds, or None; ``upright``: a layer, drawn with its height along ParaView's Y)."""
    return {"name": name, "time": float(time), "snapshot": bool(snapshot), "n": int(n), "dim": int(dim),
            "upright": bool(upright),
            "profile": {"field": str(field), "scale": float(scale), "L": float(L), "bins": len(exact),
                        "exact": [float(v) for v in exact], "err_max": float(err_max),
                        "err_rms": float(err_rms), "axis": 1 if upright else 0},
            "grid": None if grid is None else ([int(v) for v in grid[:len(grid) // 2]]
                                               + [float(v) for v in grid[len(grid) // 2:]])}


def entry_from_file(f, name):
    """The sidecar entry of an output file already written (a restart continues the series)."""
    a = f.attrs
    field = str(a.get("error_field", "vy"))
    g = f["profile"]
    grid = None
    if "grid" in f and "theta" in f["grid"]:
        grid = (*f["grid/theta"].shape, *f["grid"].attrs["cell"])
    return snapshot_entry(name, a["time"], "particles" in f, a["n_particles"], a["dim"], field,
                          a["error_scale"] if "error_scale" in a else a["V_w"], a["L"], g[field + "_exact"][()],
                          g.attrs["err_max"], g.attrs["err_rms"], grid, upright="H0" in a)


NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}
UPRIGHT = (1, 0, 2)  # the file's columns along ParaView's X, Y, Z for a layer (its height x along Y)
VECTORS = ("u_g", "j")  # the gas grid's vectors, shown from their display copies /grid/<name>_xyz


def _data_item(parent, fname, path, shape, dtype, column=None):
    """An HDF DataItem for ``fname:path`` of ``shape``; ``column`` c: that column of an
    (N, k) dataset, as Xdmf3's hyperslab syntax ``path|start:stride:count:dims``
    (ParaView's default reader skips ItemType="HyperSlab" items: their type is unknown
    before they are read)."""
    dtype = np.dtype(dtype)
    ntype = NUMBER_TYPES[dtype.kind]
    if dtype.itemsize == 1:
        ntype = {"Int": "Char", "UInt": "UChar"}[ntype]
    text = f"{fname}:{path}"
    dims = shape
    if column is not None:
        n, k = shape
        text += f"|0 {column}:1 1:{n} 1:{n} {k}"
        dims = (n,)
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, dims)), NumberType=ntype,
                         Precision=str(dtype.itemsize), Format="HDF")
    item.text = text
    return item


CELLS_DATASET = "/connectivity"
CELLS_CHUNK = 1 << 22   # rows written at a time: rank 0's memory stays small for any N


def cells_name(stem):
    """The file of a run's connectivity, beside its sidecar ``<stem>.xdmf``."""
    return stem + ".cells.h5"


def cells_dtype(n):
    return np.dtype(np.int32 if n < 2 ** 31 else np.int64)


def write_cells(path, n):
    """``path``:/connectivity = 0 .. n-1 (one Polyvertex cell per particle), unless it holds that already."""
    dtype = cells_dtype(n)
    try:
        with h5py.File(path, "r") as f:
            d = f[CELLS_DATASET]
            if d.shape == (n,) and d.dtype == dtype:
                return
    except (OSError, KeyError):
        pass
    with h5py.File(path + ".part", "w") as f:
        d = f.create_dataset(CELLS_DATASET, (n,), dtype=dtype)
        d.attrs["content"] = "XDMF Polyvertex connectivity: cell k is particle row k of every output file"
        for a in range(0, n, CELLS_CHUNK):
            b = min(n, a + CELLS_CHUNK)
            d[a:b] = np.arange(a, b, dtype=dtype)
    os.replace(path + ".part", path)


def xdmf_grid(entry, cells=None, ncells=None):
    """One time step: N points with id, kind, theta, the velocity vector and its components, and N
    one-point cells whose connectivity is ``cells``:/connectivity (of length ``ncells``, at least N)."""
    fname, n, dim = entry["name"], entry["n"], entry["dim"]
    grid = ET.Element("Grid", Name=fname, GridType="Uniform")
    ET.SubElement(grid, "Time", Value=repr(entry["time"]))
    # Xdmf3 requires the Value attribute (text content aborts ParaView's default reader)
    ET.SubElement(grid, "Information", Name="parsph.profile", Value=json.dumps(entry["profile"]))
    topo = ET.SubElement(grid, "Topology", TopologyType="Polyvertex", NumberOfElements=str(n), NodesPerElement="1")
    if cells is not None:
        ncells = n if ncells is None else ncells
        item = _data_item(topo, cells, CELLS_DATASET, (n,), cells_dtype(ncells))
        if ncells != n:  # the first n rows of a longer connectivity
            item.text += f"|0:1:{n}:{ncells}"
    upright = entry.get("upright", False)
    geom = ET.SubElement(grid, "Geometry", GeometryType="XY" if dim == 2 else "XYZ")
    # a layer: ParaView's X, Y(, Z) = the file's y, x(, z), the height up (the files' display copy)
    _data_item(geom, fname, "/particles/position_view" if upright else "/particles/position", (n, dim),
               np.float64 if upright else FILE_DTYPES["position"])

    def attribute(name, kind="Scalar"):
        return ET.SubElement(grid, "Attribute", Name=name, AttributeType=kind, Center="Node")

    for key in ("id", "kind", "theta"):
        _data_item(attribute(key), fname, f"/particles/{key}", (n,), FILE_DTYPES[key])
    if dim == 3 and not upright:
        _data_item(attribute("velocity", "Vector"), fname, "/particles/velocity", (n, 3), np.float64)
    else:  # the files' display copy, in ParaView's frame ((v_y, v_x, v_z) for a layer)
        _data_item(attribute("velocity", "Vector"), fname, "/particles/velocity_xyz", (n, 3), np.float32)
    for c in range(dim):
        _data_item(attribute("v" + "xyz"[c]), fname, "/particles/velocity", (n, dim), np.float64, column=c)
    return grid


GRID_NODES = "/grid_nodes"


def write_grid_nodes(path, grid, upright=False):
    """``path``:/grid_nodes = the (n_x + 1)(n_y + 1)[(n_z + 1)] nodes (x_i, y_j[, z_k]) of the gas grid
    ``grid`` = (n_x, n_y[, n_z], h_x, h_y[, h_z]), x slow, as ParaView places them ((y_j, x_i[, z_k])
    ``upright``) (the file made or extended beside the connectivity)."""
    dim = len(grid) // 2
    axes = np.meshgrid(*[np.arange(grid[a] + 1) * grid[dim + a] for a in range(dim)], indexing="ij")
    cols = [a.ravel() for a in axes]
    if upright:
        cols[0], cols[1] = cols[1], cols[0]
    nodes = np.stack(cols, axis=1)
    with h5py.File(path, "a") as f:
        if GRID_NODES in f:
            if f[GRID_NODES].shape == nodes.shape and np.array_equal(f[GRID_NODES][()], nodes):
                return
            del f[GRID_NODES]
        d = f.create_dataset(GRID_NODES, data=nodes)
        d.attrs["content"] = ("XDMF 2DSMesh nodes of the gas grid: (x_i, y_j), i slow" if dim == 2 else
                              "XDMF 3DSMesh nodes of the gas grid: (x_i, y_j, z_k), i slow, k fast")


def xdmf_gas_grid(entry, nodes_file):
    """One time step of the gas grid: its cells with theta and p' as cell data, u_g and j as cell vectors."""
    fname = entry["name"]
    dim = len(entry["grid"]) // 2
    ns = entry["grid"][:dim]
    grid = ET.Element("Grid", Name=fname + ":grid", GridType="Uniform")
    ET.SubElement(grid, "Time", Value=repr(entry["time"]))
    ET.SubElement(grid, "Topology", TopologyType=f"{dim}DSMesh", Dimensions=" ".join(str(n + 1) for n in ns))
    geom = ET.SubElement(grid, "Geometry", GeometryType="XY" if dim == 2 else "XYZ")
    _data_item(geom, nodes_file, GRID_NODES, (int(np.prod([n + 1 for n in ns])), dim), np.float64)
    for key in ("theta", "p"):
        attr = ET.SubElement(grid, "Attribute", Name=key, AttributeType="Scalar", Center="Cell")
        _data_item(attr, fname, f"/grid/{key}", tuple(ns), np.float64)
    for key in VECTORS:
        attr = ET.SubElement(grid, "Attribute", Name=key, AttributeType="Vector", Center="Cell")
        _data_item(attr, fname, f"/grid/{key}_xyz", tuple(ns) + (3,), np.float64)
    return grid


def write_xdmf(path, entries):
    """Rewrite the ParaView sidecar ``<stem>.xdmf``: one point set per snapshot, in time order (atomic
    rename); ``<stem>.cells.h5`` gets the connectivity when it does not hold it yet."""
    root = ET.Element("Xdmf", Version="3.0")
    series = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="particles", GridType="Collection",
                           CollectionType="Temporal")
    snaps = [e for e in sorted(entries, key=lambda e: e["time"]) if e["snapshot"]]
    cells = cells_name(os.path.splitext(os.path.basename(path))[0])
    if snaps:
        ncells = max(e["n"] for e in snaps)
        write_cells(os.path.join(os.path.dirname(path), cells), ncells)
        for entry in snaps:
            series.append(xdmf_grid(entry, cells, ncells))
    gridded = [e for e in sorted(entries, key=lambda e: e["time"]) if e.get("grid")]
    if gridded:
        write_grid_nodes(os.path.join(os.path.dirname(path), cells), gridded[-1]["grid"],
                         upright=gridded[-1].get("upright", False))
        gas = ET.SubElement(root.find("Domain"), "Grid", Name="gas grid", GridType="Collection",
                            CollectionType="Temporal")
        for entry in gridded:
            gas.append(xdmf_gas_grid(entry, cells))
    ET.indent(root)
    with open(path + ".part", "wb") as fh:
        ET.ElementTree(root).write(fh, encoding="utf-8", xml_declaration=True)
        fh.write(b"\n")
    os.replace(path + ".part", path)
