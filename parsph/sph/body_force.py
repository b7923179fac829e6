"""The per-particle tail of the momentum balance, beside Eq. (5)'s pair sums: gravity with buoyancy
(``Constants.g``) and the gas's drag (docs/physics.md, "The solid phase in a gas"), for the stream, the
column and the solved gas. Knows nothing of pairs or of MPI.
"""
from numba import njit

from parsph.physics.drag import GIDASPOW, STOKES, WEN_YU, rate
from .particles import GRAIN
from .pass_data import COLUMN, SOLVED, TOWARD_FLUX  # the gas's flows (GasConstants.flow)


@njit(cache=True, error_model="numpy")
def finish_acc(acc, kind, g, three_d, n_own, drag_on, vel, theta, rho_s, gas, drag, drag_rate, flux):
    """Owned fluid particles: + g, + the gas's drag (:func:`drag_rates` first, then :func:`drag_plain` per
    particle, with ``drag_on``); owned walls: zero (one call: an inlined call per particle would count
    references to its arrays every time). numpy's error model: with Python's, the drag's divisions and powers
    test for zero and took 4x as long."""
    if len(drag_on):
        drag_rates(n_own, vel, theta, rho_s, gas.model, gas.rho, gas.mu, gas.d, gas.flow, gas.axis, gas.sign,
                   gas.U, gas.u, flux, drag_rate, three_d)
    for k in range(n_own):
        if kind[k] == GRAIN:
            acc[k, 0] += g[0]
            acc[k, 1] += g[1]
            if len(three_d):
                acc[k, 2] += g[2]
            if len(drag_on):
                drag_plain(k, vel, 1.0 - theta[k], gas.flow, gas.axis, gas.sign, gas.U, gas.u, flux, acc, drag,
                           drag_rate[k], three_d)
        else:
            acc[k, 0] = 0.0
            acc[k, 1] = 0.0
            if len(three_d):
                acc[k, 2] = 0.0


@njit(cache=True, inline="always")
def stream_slip2(k, vf, u0, u1, u2, three_d):
    """|u_g - v_k|^2 in a stream u_g = (u0, u1, u2): the sum of (u_d - v_k,d)^2 over the components d.
    ``vf``: the velocities flat (:func:`flat`), read at the constant stride dim; u_g as numbers (loads from its
    array in the loop, or strides read from the 2-D array's shape, keep the loop off vector registers)."""
    dim = 3 if len(three_d) else 2
    s0 = u0 - vf[dim * k]
    s1 = u1 - vf[dim * k + 1]
    slip2 = s0 * s0 + s1 * s1
    if len(three_d):
        s2 = u2 - vf[dim * k + 2]
        slip2 += s2 * s2
    return slip2


@njit(cache=True, inline="always")
def column_slip2(k, vf, theta, axis, sign, U, three_d):
    """|u_g,k - v_k|^2 in a column (docs/physics.md): u_g.e = (U - theta v.e) / eps along e = sign * unit(axis), so
    the slip there is (sign U - v_k,axis) / eps, and -v_k,d across. Branch-free: each component a select;
    ``vf`` as in :func:`stream_slip2`."""
    dim = 3 if len(three_d) else 2
    se = (sign * U - vf[dim * k + axis]) / (1.0 - theta[k])
    s0 = se if axis == 0 else vf[dim * k]
    s1 = se if axis == 1 else vf[dim * k + 1]
    slip2 = s0 * s0 + s1 * s1
    if len(three_d):
        s2 = se if axis == 2 else vf[dim * k + 2]
        slip2 += s2 * s2
    return slip2


@njit(cache=True, inline="always")
def flat(a):
    """A C-contiguous (n, dim) array as a flat view (no copy)."""
    return a.reshape(a.shape[0] * a.shape[1])


@njit(cache=True, inline="always")
def solved_slip2(k, vf, theta, flux, three_d):
    """|u_g,k - v_k|^2 in the solved gas: eps (u_g - v) = j - v with j the mixture's flux at the particle
    (``flux[k]``, from the grid: :mod:`parsph.gas`), so the slip is (j - v_k) / eps_k."""
    dim = 3 if len(three_d) else 2
    s0 = flux[k, 0] - vf[dim * k]
    s1 = flux[k, 1] - vf[dim * k + 1]
    slip2 = s0 * s0 + s1 * s1
    if len(three_d):
        s2 = flux[k, 2] - vf[dim * k + 2]
        slip2 += s2 * s2
    e = 1.0 - theta[k]
    return slip2 / (e * e)


@njit(cache=True, error_model="numpy")
def drag_rates(n_own, vel, theta, rho_s, model, rho_g, mu_g, d_grain, flow, axis, sign, U, u, flux, K, three_d):
    """K[k] = :func:`parsph.physics.drag.rate` at (theta_k, |u_g,k - v_k|^2) for k < n_own, walls included
    (unused there): one loop per closure and kind of gas flow, each branch-free (the model a constant) so that
    it runs on vector registers, fastmath's log, exp and atan included. Plain arguments, as drag_plain's;
    :func:`parsph.sph.momentum._momentum_threaded` calls it on chunks of the arrays in parallel (a parallel
    loop of these bodies took about 20 s to compile per version). ``flux``: the solved gas's j per particle (else unread).
    ``flow`` SOLVED: K is the solved gas's stage's (the rates it deposited on the grid, so that the drag the
    grains feel is the grid's -grad p' exactly) and left as it is; TOWARD_FLUX: at the slip toward ``flux``
    (what that stage computes)."""
    if flow == SOLVED:
        return
    u0, u1, u2 = u[0], u[1], u[2]
    vf = flat(vel)
    if model == STOKES:
        for k in range(n_own):
            K[k] = rate(STOKES, theta[k], 0.0, rho_s, rho_g, mu_g, d_grain)
    elif flow == COLUMN:
        if model == WEN_YU:
            for k in range(n_own):
                K[k] = rate(WEN_YU, theta[k], column_slip2(k, vf, theta, axis, sign, U, three_d), rho_s, rho_g,
                            mu_g, d_grain)
        else:
            for k in range(n_own):
                K[k] = rate(GIDASPOW, theta[k], column_slip2(k, vf, theta, axis, sign, U, three_d), rho_s, rho_g,
                            mu_g, d_grain)
    elif flow == TOWARD_FLUX:
        for k in range(n_own):
            K[k] = rate(model, theta[k], solved_slip2(k, vf, theta, flux, three_d), rho_s, rho_g, mu_g, d_grain)
    elif model == WEN_YU:
        for k in range(n_own):
            K[k] = rate(WEN_YU, theta[k], stream_slip2(k, vf, u0, u1, u2, three_d), rho_s, rho_g, mu_g, d_grain)
    else:
        for k in range(n_own):
            K[k] = rate(GIDASPOW, theta[k], stream_slip2(k, vf, u0, u1, u2, three_d), rho_s, rho_g, mu_g, d_grain)


@njit(cache=True, inline="always")
def drag_plain(k, vel, eps, flow, axis, sign, U, u, flux, acc, drag, Kk, three_d):
    """The drag on fluid particle k, beside Eq. (5)'s sums and gravity with buoyancy (Constants.g):

        dv_k/dt += beta_k (u_g,k - v_k) / (rho_s theta_k eps_k),   eps = 1 - theta,

    theta_k from Eq. (3), beta_k the closure's at |u_g,k - v_k|, Kk = beta_k / (rho_s theta_k eps_k) from
    :func:`drag_rates`, eps = eps_k. Written per component as C (w - v_k): a stream has C = K and
    w = u_g; a column (gas fed at U along e, opposite to gravity) has u_g.e = (U - theta v.e) / eps, so
    along e C = K / eps and w = U e, across it C = K and w = 0; the solved gas has eps (u_g - v) = j - v
    with j the mixture's flux from the grid (``flux[k]``), so C = K / eps and w = j along every axis (a
    column's along e, exactly, where j = U e). ``drag[k]`` keeps C per component,
    what the implicit update divides by (:mod:`parsph.sph.integrators`) and the auto rule reads.
    Plain arguments: the threaded pass calls it inside a parallel loop, which misreads named tuples' arrays.
    The components written out (``three_d`` a switch; u has 3): a loop over vel.shape[1] took longer; every
    array read unconditionally (``flux`` only in the solved gas, the one flow that has it), else numba counts
    its references per particle."""
    c0, c1, c2, w0, w1, w2 = drag_terms(k, eps, flow, axis, sign, U, u, flux, Kk, three_d)
    acc[k, 0] += c0 * (w0 - vel[k, 0])
    acc[k, 1] += c1 * (w1 - vel[k, 1])
    drag[k, 0] = c0
    drag[k, 1] = c1
    if len(three_d):
        acc[k, 2] += c2 * (w2 - vel[k, 2])
        drag[k, 2] = c2


@njit(cache=True, inline="always")
def drag_terms(k, eps, flow, axis, sign, U, u, flux, Kk, three_d):
    """(C_x, C_y, C_z, w_x, w_y, w_z) of particle k's drag C (w - v) per component (:func:`drag_plain` says
    what they are in each flow); walls.rest_drag takes C w, the drag at rest."""
    c0 = Kk
    c1 = Kk
    c2 = Kk
    w0 = u[0]
    w1 = u[1]
    w2 = u[2]
    if flow == COLUMN:
        ce = Kk / eps
        we = sign * U
        c0 = ce if axis == 0 else Kk
        c1 = ce if axis == 1 else Kk
        c2 = ce if axis == 2 else Kk
        w0 = we if axis == 0 else 0.0
        w1 = we if axis == 1 else 0.0
        w2 = we if axis == 2 else 0.0
    elif flow == SOLVED:
        c0 = Kk / eps
        c1 = c0
        c2 = c0
        w0 = flux[k, 0]
        w1 = flux[k, 1]
        if len(three_d):
            w2 = flux[k, 2]
    return c0, c1, c2, w0, w1, w2
