"""Time integrators.

"paper", Eqs. (6)-(7), for fluid particles:
    r^{n+1} = r^n + dt v^n + dt^2 R^n / 2,    v^{n+1} = v^n + dt R^n.
Wall particles move with their prescribed velocity (r += dt v). Positions are
wrapped into the periodic [0, Ly) afterwards (and [0, Lz) in 3-D).
"""
from numba import njit

from .particles import FLUID


@njit(cache=True)
def step_paper(pos, vel, acc, kind, n_own, dt, Ly):
    dim = pos.shape[1]
    half_dt2 = 0.5 * dt * dt
    for i in range(n_own):
        if kind[i] == FLUID:
            for d in range(dim):
                pos[i, d] += dt * vel[i, d] + half_dt2 * acc[i, d]
                vel[i, d] += dt * acc[i, d]
        else:
            for d in range(dim):
                pos[i, d] += dt * vel[i, d]
        y = pos[i, 1]
        if y >= Ly:
            y -= Ly
        elif y < 0.0:
            y += Ly
            if y >= Ly:
                y = 0.0
        pos[i, 1] = y
