"""A ghost round between list builds, written once: the rows of a build's plan (:class:`HaloPlan`,
made by :meth:`parsph.parallel.slab_ring.SlabRing.plan`) packed and unpacked by
:mod:`parsph.parallel.halo_rows`. The compiled step sends them through :mod:`parsph.parallel.native_mpi`
(:func:`forward`, :func:`refresh`), and so does Python where that loads; elsewhere
:class:`~parsph.parallel.slab_ring.SlabRing` sends the same buffers through mpi4py between the same
pack and unpack.
"""
from typing import NamedTuple

import numpy as np
from numba import njit

from .halo_rows import pack_forward, pack_scalar, unpack_forward, unpack_scalar
from .native_mpi import exchange_rows

TAG_UP, TAG_DOWN = 11, 12  # the ghosts' messages (SlabRing's tags)


class HaloPlan(NamedTuple):
    """The ghosts' messages of one list build."""
    h: np.ndarray          # native_mpi.handles of the communicator
    left: int
    right: int
    send_up: np.ndarray    # owned places sent up (to the right) and down
    send_down: np.ndarray
    n_below: int           # ghost rows from the left and from the right
    n_above: int
    shift_below: float     # y shifts of the rows across y = 0 / y = Ly
    shift_above: float
    img_src: np.ndarray    # periodic images: source place, axis, shift
    img_axis: np.ndarray
    img_shift: np.ndarray
    f_up: np.ndarray       # forward rows (pos, vel, disp): send and receive buffers
    f_down: np.ndarray
    f_below: np.ndarray
    f_above: np.ndarray
    s_up: np.ndarray       # scalar rows (rho), shape (rows, 1)
    s_down: np.ndarray
    s_below: np.ndarray
    s_above: np.ndarray
    reqs: np.ndarray       # native_mpi.requests(4)
    stats: np.ndarray


@njit(cache=True)
def pack_forward_rows(plan, pos, vel, disp):
    """The forward round's rows to send: positions, velocities and displacements of the places sent."""
    pack_forward(pos, vel, disp, plan.send_up, plan.f_up, plan.send_down, plan.f_down)


@njit(cache=True)
def unpack_forward_rows(plan, pos, vel, disp, n_own):
    """The forward round's received rows into the ghosts (shifted across y = 0 / Ly), then the images."""
    unpack_forward(plan.f_below[:plan.n_below], plan.f_above[:plan.n_above], n_own, plan.shift_below,
                   plan.shift_above, pos, vel, disp, plan.img_src, plan.img_axis, plan.img_shift,
                   n_own + plan.n_below + plan.n_above)


@njit(cache=True)
def pack_scalar_rows(plan, arr):
    """The scalar round's rows to send: ``arr`` of the places sent."""
    pack_scalar(arr, plan.send_up, plan.s_up[:, 0], plan.send_down, plan.s_down[:, 0])


@njit(cache=True)
def unpack_scalar_rows(plan, arr, n_own):
    """The scalar round's received rows into the ghosts' ``arr``, then the images'."""
    unpack_scalar(plan.s_below[:plan.n_below, 0], plan.s_above[:plan.n_above, 0], n_own, arr, plan.img_src,
                  n_own + plan.n_below + plan.n_above)


@njit(cache=True)
def forward(plan, pos, vel, disp, n_own):
    """The ghosts' positions, velocities and displacements from their owners, then the images (one round);
    returns MPI's error code."""
    pack_forward_rows(plan, pos, vel, disp)
    err = exchange_rows(plan.h, plan.left, plan.right, TAG_UP, TAG_DOWN, plan.f_up, plan.send_up.shape[0],
                        plan.f_down, plan.send_down.shape[0], plan.f_below, plan.n_below, plan.f_above,
                        plan.n_above, plan.reqs, plan.stats)
    unpack_forward_rows(plan, pos, vel, disp, n_own)
    return err


@njit(cache=True)
def refresh(plan, arr, n_own):
    """One scalar per ghost (rho) from its owner, then the images (one round); returns MPI's error code."""
    pack_scalar_rows(plan, arr)
    err = exchange_rows(plan.h, plan.left, plan.right, TAG_UP, TAG_DOWN, plan.s_up, plan.send_up.shape[0],
                        plan.s_down, plan.send_down.shape[0], plan.s_below, plan.n_below, plan.s_above,
                        plan.n_above, plan.reqs, plan.stats)
    unpack_scalar_rows(plan, arr, n_own)
    return err
