"""HDF5 through h5py's low-level API: one collective read or write of row ranges per dataset, the y-bins of
the restart layout, and the rename that makes a finished file durable.

With a collective transfer list every rank calls each read or write, a rank
without rows with an empty selection (a skipped call would hang the others).
"""
import os

import h5py
import numpy as np
from h5py import h5fd, h5p, h5s

SERIAL_ENV = "PARSPH_SERIAL_HDF5"  # set to 1 to force the gather-to-rank-0 path


def parallel_hdf5_available():
    return bool(h5py.get_config().mpi) and os.environ.get(SERIAL_ENV, "") in ("", "0")


def collective_dxpl():
    """A transfer property list for collective MPI-IO (every rank calls H5Dread/H5Dwrite)."""
    dxpl = h5p.create(h5p.DATASET_XFER)
    dxpl.set_dxpl_mpio(h5fd.MPIO_COLLECTIVE)
    return dxpl


def write_rows(dset, start, arr, dxpl=None):
    """Write ``arr`` into rows ``start ..`` of ``dset`` in one H5Dwrite.

    With a collective ``dxpl`` every rank must call this once per dataset; a rank
    without rows selects nothing instead of skipping the call. ``arr`` must have the
    dataset's dtype (a conversion would make HDF5 fall back to independent I/O).
    """
    fspace = dset.id.get_space()
    if len(arr):
        arr = np.ascontiguousarray(arr)
        fspace.select_hyperslab((start,) + (0,) * (arr.ndim - 1), arr.shape)
        mspace = h5s.create_simple(arr.shape)
    else:
        fspace.select_none()
        arr = np.zeros((1,) + dset.shape[1:], dset.dtype)
        mspace = h5s.create_simple(arr.shape)
        mspace.select_none()
    dset.id.write(mspace, fspace, arr, dxpl=dxpl)


def read_rows(dset, ranges, dxpl=None):
    """Rows ``a .. b-1`` for each (a, b) in ``ranges`` (ascending, disjoint), in one H5Dread;
    collective like ``write_rows`` (an empty ``ranges`` selects nothing)."""
    rows = sum(b - a for a, b in ranges)
    rest = dset.shape[1:]
    fspace = dset.id.get_space()
    fspace.select_none()
    for a, b in ranges:
        if b > a:
            fspace.select_hyperslab((a,) + (0,) * len(rest), (b - a,) + rest, op=h5s.SELECT_OR)
    out = np.empty((rows,) + rest, dset.dtype)
    buf = out if rows else np.zeros((1,) + rest, dset.dtype)
    mspace = h5s.create_simple(buf.shape)
    if not rows:
        mspace.select_none()
    dset.id.read(mspace, fspace, buf, dxpl=dxpl)
    return out


def y_bins(y, y_min, y_max, nbins):
    """Bin of each y among ``nbins`` equal bins of [y_min, y_max] (clipped to the ends).

    Monotone in y, and the writer and the reader evaluate it alike, so the bins
    of the ends of a y-range bracket the bins of every y inside it.
    """
    y = np.asarray(y, dtype=np.float64)
    span = y_max - y_min
    if not span > 0:
        return np.zeros(y.shape, np.uint16)
    k = y - y_min
    k *= nbins / span
    np.floor(k, out=k)
    np.clip(k, 0, nbins - 1, out=k)
    return k.astype(np.uint16)


def durable_rename(part, final):
    """Rename a closed ``part`` file to ``final`` so that a crash of the machine cannot leave
    ``final`` naming a file whose data never reached the disk: fsync the data, rename, then
    fsync the directory that holds the new name."""
    fd = os.open(part, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(part, final)
    try:
        fd = os.open(os.path.dirname(os.path.abspath(final)), os.O_RDONLY)
    except OSError:  # a file system whose directories cannot be opened: the rename stands
        return
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on a directory
        pass
    finally:
        os.close(fd)
