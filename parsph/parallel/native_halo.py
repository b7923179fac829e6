"""The ghosts' refresh between list builds in compiled code: the same rows as :class:`SlabRing`'s
``forward`` and ``refresh``, packed and unpacked by :mod:`parsph.parallel.halo_rows`, sent through
:mod:`parsph.parallel.native_mpi`. :meth:`parsph.parallel.slab_ring.SlabRing.plan` makes the plan
at each build.
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
def forward(plan, pos, vel, disp, n_own):
    """The ghosts' positions, velocities and displacements from their owners, then the images (one round);
    returns MPI's error code."""
    nu = plan.send_up.shape[0]
    nd = plan.send_down.shape[0]
    pack_forward(pos, vel, disp, plan.send_up, plan.f_up, plan.send_down, plan.f_down)
    err = exchange_rows(plan.h, plan.left, plan.right, TAG_UP, TAG_DOWN, plan.f_up, nu, plan.f_down, nd,
                        plan.f_below, plan.n_below, plan.f_above, plan.n_above, plan.reqs, plan.stats)
    unpack_forward(plan.f_below[:plan.n_below], plan.f_above[:plan.n_above], n_own, plan.shift_below,
                   plan.shift_above, pos, vel, disp, plan.img_src, plan.img_axis, plan.img_shift,
                   n_own + plan.n_below + plan.n_above)
    return err


@njit(cache=True)
def refresh(plan, arr, n_own):
    """One scalar per ghost (rho) from its owner, then the images (one round); returns MPI's error code."""
    nu = plan.send_up.shape[0]
    nd = plan.send_down.shape[0]
    pack_scalar(arr, plan.send_up, plan.s_up[:, 0], plan.send_down, plan.s_down[:, 0])
    err = exchange_rows(plan.h, plan.left, plan.right, TAG_UP, TAG_DOWN, plan.s_up, nu, plan.s_down, nd,
                        plan.s_below, plan.n_below, plan.s_above, plan.n_above, plan.reqs, plan.stats)
    unpack_scalar(plan.s_below[:plan.n_below, 0], plan.s_above[:plan.n_above, 0], n_own, arr, plan.img_src,
                  n_own + plan.n_below + plan.n_above)
    return err
