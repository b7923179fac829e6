"""Walls whose state follows the solids next to them (docs/physics.md, "Walls"; Adami, Hu & Adams 2012, taken
per pair): the walls of the free-surface scenes (layers and beds), where a held wall state would have to know
the answer and a loose layer dropped on it goes through.

Such wall particles carry no mass: each stands for the volume ``V_w`` of one site of the lattice
(``Constants.wall_volume``), and a fluid particle i sees every wall particle w as the continuation of its own
state beyond the plate:

- Eq. (3), renormalised: ``theta_i = sum_fluid m_j W_ij / (rho_s (1 - phi_i))`` with
  ``phi_i = V_w sum_w W_iw``, the share of i's kernel that lies in the wall (the density pass sums the
  walls' zero masses; :func:`renormalise` divides);
- Eq. (5): w has the pressure ``p_w = p_i + rho_s theta_i max(0, a_i . (r_w - r_i))`` (Adami's
  extrapolation for a wall at rest, never below the particle's own), ``a_i`` the body force on i:
  gravity with buoyancy plus the drag i would feel at rest, ``C (w - 0)`` of the gas's flow
  (:func:`rest_drag`), so that a bed the gas carries presses on its floor only with what the gas leaves;
  ``theta_w = p^-1(p_w)`` in the run's pressure form (consistent: p = G / (G_a ln 10), plus the packing
  limit's p_f where the run has one; the paper's:
  p = G theta), mass ``rho_s theta_w V_w``; the pair's P, V, mu and the no-slip beta of
  :mod:`.pair_terms` (:func:`forces`, after Eq. (5)'s fluid pairs, in the order of the list).

Every wall-fluid pair has its fluid member owned (:mod:`.cells`), so both passes need nothing of a ghost
beyond its position: the result is the same on any rank and thread count, bit for bit.
"""
import math

import numpy as np
from numba import njit

from parsph.physics.closures import modulus_unchecked, packing_pressure
from parsph.physics.kernels import kernel_w_f
from .body_force import drag_terms
from .momentum import pressure_factor
from .pair_terms import pressure_term, viscosity_coefficient, viscous_term, wall_factor
from .particles import GRAIN
from .pass_data import INV_RHO, INV_THETA, PRESS, THETA, VX, VY, VZ

LN10 = math.log(10.0)
SHARE_MAX = 0.9  # phi_i above this (a particle beyond the plate, which the checks stop) is taken as this


@njit(cache=True)
def wall_pairs(pi, pj, npairs, kind):
    """The indices p of the pairs (pi[p], pj[p]) of a wall and a fluid particle, in list order."""
    count = 0
    for p in range(npairs):
        if (kind[pi[p]] == GRAIN) != (kind[pj[p]] == GRAIN):
            count += 1
    out = np.empty(count, np.int64)
    count = 0
    for p in range(npairs):
        if (kind[pi[p]] == GRAIN) != (kind[pj[p]] == GRAIN):
            out[count] = p
            count += 1
    return out


@njit(cache=True, inline="always")
def _members(p, pi, pj, kind):
    """(fluid, wall) of wall pair p."""
    a = pi[p]
    b = pj[p]
    if kind[a] == GRAIN:
        return a, b
    return b, a


@njit(cache=True, inline="always")
def _offset(pos, i, w, three_d):
    """r_i - r_w and |r_i - r_w|."""
    rx = pos[i, 0] - pos[w, 0]
    ry = pos[i, 1] - pos[w, 1]
    rz = pos[i, 2] - pos[w, 2] if len(three_d) else 0.0
    return rx, ry, rz, math.sqrt(rx * rx + ry * ry + rz * rz)


@njit(cache=True)
def renormalise(lst, parts, c, sw):
    """Eq. (3) next to a wall: ``rho_sum_i /= 1 - phi_i`` for the owned fluid (``lst.wall_share`` keeps phi)."""
    share, rho_sum, pos, kind = lst.wall_share, lst.rho_sum, parts.pos, parts.kind
    pairs = lst.wall_pairs
    for q in range(len(pairs)):
        i, w = _members(pairs[q], lst.pi, lst.pj, kind)
        share[i] = 0.0
    for q in range(len(pairs)):
        i, w = _members(pairs[q], lst.pi, lst.pj, kind)
        rx, ry, rz, r = _offset(pos, i, w, sw.three_d)
        share[i] += c.wall_volume * kernel_w_f(c.kid, r, c.inv_h, c.norm)[0]
    for q in range(len(pairs)):
        i, w = _members(pairs[q], lst.pi, lst.pj, kind)
        if share[i] >= 0.0:  # once per particle: the sign marks it done
            rho_sum[i] = rho_sum[i] / (1.0 - min(share[i], SHARE_MAX))
            share[i] = -1.0


@njit(cache=True, inline="always")
def rest_drag(i, flow, axis, sign, U, u, flux, K, eps, three_d):
    """The drag acceleration on particle i were it at rest, C w per component (body_force.drag_terms)."""
    c0, c1, c2, w0, w1, w2 = drag_terms(i, eps, flow, axis, sign, U, u, flux, K, three_d)
    return c0 * w0, c1 * w1, c2 * w2


@njit(cache=True, inline="always")
def mirror_theta(th_i, rise, G_a, G_b, rho_s, consistent, packing, theta_min, theta_max):
    """theta_w with p(theta_w) = p(theta_i) + rho_s theta_i rise (rise >= 0): exact for the consistent form's
    p = G / (G_a ln 10); for the paper's p = G theta, Newton on ln p, concave in theta, from below (monotone) to
    round-off; with the packing limit's p_f (``packing`` on), Newton on p (convex) from G's own root, which
    lies above (monotone) to round-off."""
    if rise <= 0.0:
        return th_i
    ga = G_a * LN10
    G = modulus_unchecked(th_i, G_a, G_b)
    if len(consistent):
        th = th_i + math.log1p(rho_s * th_i * rise * ga / G) / ga
        if len(packing):
            target = G / ga + packing_pressure(th_i, theta_min, theta_max)[0] + rho_s * th_i * rise
            for _ in range(60):
                Gt = modulus_unchecked(th, G_a, G_b)
                pf, dpf = packing_pressure(th, theta_min, theta_max)
                step = (Gt / ga + pf - target) / (Gt + dpf)
                th -= step
                if not abs(step) > 1e-15 * th:
                    break
        return th
    x = math.log1p(rho_s * rise / G)  # p_i = G theta_i
    th = th_i
    for _ in range(60):
        step = (ga * (th - th_i) + math.log(th / th_i) - x) / (ga + 1.0 / th)
        th -= step
        if not abs(step) > 1e-15 * th:
            break
    return th


@njit(cache=True, inline="always")
def no_slip(pos, i, w, ry, c):
    """The no-slip factor beta (pair_terms.wall_factor) of fluid particle i seen by wall particle w: toward the
    plate at x = 0 or L behind w, or with side walls (w between the plates: a side wall's row) toward the one
    on i's side (``ry`` = y_i - y_w > 0: y = 0, else y = Ly)."""
    xw = pos[w, 0]
    if not (c.side > 0.0 and xw >= 0.0 and xw <= c.L):
        return wall_factor(pos[i, 0], xw, c.L, c.beta_max)
    yy, depth = side_place(pos[i, 1], c.side, c.ring)
    if ry > 0.0:
        d_k = yy if yy <= c.side else yy - c.ring
    else:
        d_k = c.side - yy
    if d_k > 0.0:
        return min(c.beta_max, 1.0 + (abs(ry) - d_k) / d_k)
    return c.beta_max


@njit(cache=True, error_model="numpy")
def forces(lst, parts, c, sw):
    """The walls' part of Eq. (5) on the owned fluid, added to ``acc`` after the fluid pairs and the body force."""
    pos, kind, acc, fields = parts.pos, parts.kind, parts.acc, lst.fields
    pairs, pi, pj = lst.wall_pairs, lst.pi, lst.pj
    rho_s, G_a, G_b, gas = c.rho_s, c.G_a, c.G_b, c.gas
    c_press = -(10.0 ** G_b) / (rho_s * rho_s)
    three_d, consistent = sw.three_d, sw.consistent
    packing, theta_min, theta_max = sw.packing, c.theta_min, c.theta_max
    for q in range(len(pairs)):
        i, w = _members(pairs[q], pi, pj, kind)
        rx, ry, rz, r = _offset(pos, i, w, three_d)
        f = kernel_w_f(c.kid, r, c.inv_h, c.norm)[1]
        if not r < 2.0 / c.inv_h:
            continue
        th_i = fields[i, THETA]
        ax, ay, az = c.g[0], c.g[1], c.g[2]
        if len(sw.drag):
            dx_, dy_, dz_ = rest_drag(i, gas.flow, gas.axis, gas.sign, gas.U, gas.u, parts.flux,
                                      parts.drag_rate[i], 1.0 - th_i, three_d)
            ax += dx_
            ay += dy_
            az += dz_
        rise = max(0.0, -(ax * rx + ay * ry + az * rz))  # a . (r_w - r_i)
        un = ((fields[i, VX] - fields[w, VX]) * rx + (fields[i, VY] - fields[w, VY]) * ry) / r
        if len(three_d):
            un += (fields[i, VZ] - fields[w, VZ]) * rz / r
        un = -un  # the speed at which i approaches w
        if un > 0.0:
            stiff = modulus_unchecked(th_i, G_a, G_b)
            if len(packing):
                stiff += packing_pressure(th_i, theta_min, theta_max)[1]
            rise += un * (math.sqrt(stiff / rho_s) + un)
        th_w = mirror_theta(th_i, rise, G_a, G_b, rho_s, consistent, packing, theta_min, theta_max)
        rho_w = rho_s * th_w
        m_w = rho_w * c.wall_volume
        P = 0.0
        if len(sw.pressure):
            p_w = pressure_factor(th_w, rho_w, G_a, G_b, consistent, packing, theta_min, theta_max)
            P = pressure_term(fields[i, PRESS], p_w, fields[i, INV_THETA],
                              1.0 / th_w, f, c_press, consistent)
        s = 0.0
        if len(sw.viscosity):
            V = viscous_term(th_i, th_w, fields[i, INV_RHO], 1.0 / rho_w, f)
            mu = viscosity_coefficient(th_i, th_i, th_w, c.k_visc, sw.symmetric_mu)
            s = mu * no_slip(pos, i, w, ry, c) * V
        acc[i, 0] += m_w * (P * rx + s * (fields[i, VX] - fields[w, VX]))
        acc[i, 1] += m_w * (P * ry + s * (fields[i, VY] - fields[w, VY]))
        if len(three_d):
            acc[i, 2] += m_w * (P * rz + s * (fields[i, VZ] - fields[w, VZ]))


@njit(cache=True, inline="always")
def side_place(y, side, ring):
    """y in [0, ring) (positions wrap at rebuilds only), and the depth beyond the side walls (<= 0: between
    them at 0 and ``side``; the rows beyond ``side`` stand for both walls across the period)."""
    yy = y - ring * math.floor(y / ring)
    return yy, min(yy - side, ring - yy)


@njit(cache=True)
def reflect(pos, vel, kind, n_own, L, side, ring):
    """A grain that reached a plate (x < 0 or x > L; with side walls, ``side`` > 0, y outside [0, side] in
    the period ``ring``) after a step is put on it with its normal velocity removed (restitution 0, MP-PIC's
    wall for parcels: Snider 2001), the backstop for what the pressure cannot stop within a step (a loose
    layer falling as dust, Mach 30 at its grains' speed); the number."""
    count = 0
    for k in range(n_own):
        if kind[k] != GRAIN:
            continue
        x = pos[k, 0]
        if x < 0.0:
            pos[k, 0] = 0.0
            vel[k, 0] = max(vel[k, 0], 0.0)
            count += 1
        elif x > L:
            pos[k, 0] = L
            vel[k, 0] = min(vel[k, 0], 0.0)
            count += 1
        if side > 0.0:
            yy, depth = side_place(pos[k, 1], side, ring)
            if depth > 0.0:
                if yy - side < ring - yy:  # beyond y = side: onto it, in the particle's own frame
                    pos[k, 1] -= yy - side
                    vel[k, 1] = min(vel[k, 1], 0.0)
                else:  # beyond y = 0 (= ring)
                    pos[k, 1] += ring - yy
                    vel[k, 1] = max(vel[k, 1], 0.0)
                count += 1
    return count
