"""The halo's message rows: numba loops that pack the owned particles' rows into the send buffers and
unpack the received rows as ghosts, then refresh the periodic images from their originals.

A forward row is (position, velocity, displacement); a scalar row one
number (rho). Used by :class:`parsph.parallel.slab_ring.SlabRing` between rebuilds.
At a rebuild a ghost row is a whole ghost: (gid, kind, mass, position,
velocity, rho, reference position, cell coordinates), 7 + 3d float64 (ids
and cells are exact below 2^53).
"""
import numpy as np
from numba import njit


@njit(cache=True)
def pack_forward(pos, vel, disp, up, out_up, down, out_down):
    """Rows (pos, vel, disp) of the owned particles ``up`` and ``down`` into the two send buffers."""
    d = pos.shape[1]
    for idx, out in ((up, out_up), (down, out_down)):
        for r in range(idx.shape[0]):
            i = idx[r]
            for c in range(d):
                out[r, c] = pos[i, c]
                out[r, d + c] = vel[i, c]
                out[r, 2 * d + c] = disp[i, c]


@njit(cache=True)
def unpack_forward(below, above, start, shift_below, shift_above, pos, vel, disp,
                    img_src, img_axis, img_shift, img_start):
    """Ghost rows from below then above into place ``start``; y shifted; then the periodic images."""
    d = pos.shape[1]
    i = start
    for rows, shift in ((below, shift_below), (above, shift_above)):
        for r in range(rows.shape[0]):
            for c in range(d):
                pos[i, c] = rows[r, c]
                vel[i, c] = rows[r, d + c]
                disp[i, c] = rows[r, 2 * d + c]
            pos[i, 1] += shift
            i += 1
    for q in range(img_src.shape[0]):
        s = img_src[q]
        j = img_start + q
        for c in range(d):
            pos[j, c] = pos[s, c]
            vel[j, c] = vel[s, c]
            disp[j, c] = disp[s, c]
        pos[j, img_axis[q]] += img_shift[q]


@njit(cache=True)
def pack_scalar(arr, up, out_up, down, out_down):
    """The scalar ``arr`` of the owned particles ``up`` and ``down`` into the two send buffers."""
    for r in range(up.shape[0]):
        out_up[r] = arr[up[r]]
    for r in range(down.shape[0]):
        out_down[r] = arr[down[r]]


@njit(cache=True)
def unpack_scalar(below, above, start, arr, img_src, img_start):
    """Ghost values from below then above into place ``start``; then the periodic images."""
    i = start
    for r in range(below.shape[0]):
        arr[i] = below[r]
        i += 1
    for r in range(above.shape[0]):
        arr[i] = above[r]
        i += 1
    for q in range(img_src.shape[0]):
        arr[img_start + q] = arr[img_src[q]]


@njit(cache=True)
def pack_ghosts(idx, gid, kind, mass, pos, vel, rho, ref, coords, out):
    """Ghost rows of the owned particles ``idx`` into ``out`` ((len(idx), 7 + 3d))."""
    d = pos.shape[1]
    for r in range(idx.shape[0]):
        i = idx[r]
        out[r, 0] = gid[i]
        out[r, 1] = kind[i]
        out[r, 2] = mass[i]
        for c in range(d):
            out[r, 3 + c] = pos[i, c]
            out[r, 3 + d + c] = vel[i, c]
            out[r, 4 + 2 * d + c] = ref[i, c]
        out[r, 3 + 2 * d] = rho[i]
        for c in range(3):
            out[r, 4 + 3 * d + c] = coords[i, c]


@njit(cache=True)
def unpack_ghosts(rows, start, shift, row_shift, gid, kind, mass, pos, vel, rho, ref, coords):
    """Ghost rows as particles start, start + 1, ...: y of pos and ref shifted by ``shift``, the cell row
    by ``row_shift`` (across y = 0 or y = Ly)."""
    d = pos.shape[1]
    for r in range(rows.shape[0]):
        i = start + r
        gid[i] = np.int64(rows[r, 0])
        kind[i] = np.int64(rows[r, 1])
        mass[i] = rows[r, 2]
        for c in range(d):
            pos[i, c] = rows[r, 3 + c]
            vel[i, c] = rows[r, 3 + d + c]
            ref[i, c] = rows[r, 4 + 2 * d + c]
        rho[i] = rows[r, 3 + 2 * d]
        for c in range(3):
            coords[i, c] = np.int64(rows[r, 4 + 3 * d + c])
        pos[i, 1] += shift
        ref[i, 1] += shift
        coords[i, 1] += row_shift


@njit(cache=True)
def copy_images(src, start, axis, shift, cells, gid, kind, mass, pos, vel, rho, ref, coords):
    """Periodic images of particles ``src`` as start, start + 1, ...: pos and ref moved by ``shift[q]``
    along ``axis``, their cell by +cells (shift > 0) or -cells."""
    d = pos.shape[1]
    for q in range(src.shape[0]):
        s = src[q]
        i = start + q
        gid[i] = gid[s]
        kind[i] = kind[s]
        mass[i] = mass[s]
        rho[i] = rho[s]
        for c in range(d):
            pos[i, c] = pos[s, c]
            vel[i, c] = vel[s, c]
            ref[i, c] = ref[s, c]
        for c in range(3):
            coords[i, c] = coords[s, c]
        pos[i, axis] += shift[q]
        ref[i, axis] += shift[q]
        coords[i, axis] += cells if shift[q] > 0 else -cells
