"""Reference 4 of docs/physics.md ("The solid phase in a gas"): batch sedimentation after Kynch (1952).
:func:`batch_sedimentation` (the interface line, the sediment front, their meeting, the final sediment),
:func:`kynch_flux`, :func:`final_sediment`; the phases are :class:`parsph.physics.gas_references.Phases`.
The whole transient between them is :mod:`parsph.physics.consolidation`'s.
"""
from typing import NamedTuple

import numpy as np

from . import limits
from .bed_expansion import Column, check_form, steady_column
from .closures import G_A, G_B
from .gas_references import check_fraction, hindered_settling_velocity


def kynch_flux(theta, ph):
    """Kynch's flux F(theta) = theta v(theta) [m/s] (v of :func:`hindered_settling_velocity`; F(0) = 0, < 0
    downward), for a number or an array."""
    th = np.asarray(theta, dtype=float)
    out = np.array([t * hindered_settling_velocity(t, ph) if t > 0 else 0.0 for t in th.ravel()])
    return out.reshape(th.shape) if th.ndim else float(out[0])


def final_sediment(mass, ph, G_a=G_A, G_b=G_B, form="paper"):
    """Ref. 4's end state: the hydrostatic sediment dp_s/dx = -(rho_s - rho_g) theta |g| with ``mass`` [kg/m^2]
    and a free top (:func:`steady_column` with U = 0)."""
    return steady_column(mass, 0.0, ph, G_a, G_b, form)


class Sedimentation(NamedTuple):
    """Ref. 4 (:func:`batch_sedimentation`). Velocities [m/s], times [s], heights [m] above the floor."""
    theta0: float
    H0: float
    settling_velocity: float   # v0 < 0: the interface's (and the suspension's) velocity
    theta_packed: float        # the sediment's fraction in Kynch's jump condition
    front_speed: float         # > 0: the sediment front's rise
    meeting_time: float
    meeting_height: float
    final: Column              # the hydrostatic end state

    def interface(self, t):
        """Kynch's interface line H(t) = H0 + v0 t (the theta = theta0/2 level) for 0 <= t <= meeting_time;
        nan after (the interface then sits on the consolidating sediment, which ends as ``final``)."""
        t = np.asarray(t, dtype=float)
        return np.where((t >= 0) & (t <= self.meeting_time), self.H0 + self.settling_velocity * t, np.nan)

    def sediment_front(self, t):
        """The sediment front's line h(t) = front_speed t, 0 <= t <= meeting_time (nan after)."""
        t = np.asarray(t, dtype=float)
        return np.where((t >= 0) & (t <= self.meeting_time), self.front_speed * t, np.nan)


def batch_sedimentation(theta0, H0, ph, G_a=G_A, G_b=G_B, form="paper", theta_packed=None):
    """Ref. 4: a uniform layer theta0 of height H0 [m] on the floor, clear gas above, U = 0 (Kynch 1952).

    Kynch's theory: theta_t + F(theta)_x = 0, F = theta v(theta) (:func:`kynch_flux`); a jump between states a
    and b moves at the chord's slope (F(b) - F(a)) / (b - a).

    - The top (clear gas, F(0) = 0, over theta0): speed F(theta0)/theta0 = v0, the hindered settling velocity;
      H(t) = H0 + v0 t (Stokes: H0 - u_t (1 - theta0)^4.65 t). It is a shock (Oleinik: F below its chord on
      (0, theta0)) exactly where |v| falls with theta on (0, theta0]; checked, ValueError otherwise.
    - The sediment front (theta0 above, the sediment below, held at rest by p_s: flux 0): speed
      -F(theta0) / (theta_packed - theta0) = theta0 |v0| / (theta_packed - theta0), up from the floor.
    - They meet at t_m = H0 (theta_packed - theta0) / (theta_packed |v0|), at h_m = theta0 H0 / theta_packed.

    Which theta_packed (default): p_s is continuous at the front (above it the suspension's p_s(theta0) carries no
    gradient), and a sediment at rest with no gas flow through it (U = 0) is hydrostatic; so the sediment is the
    hydrostatic profile whose top is at theta0. The mass balance of the layer, int_0^h (theta - theta0) dx =
    theta0 |v0| t, is then Kynch's jump condition with theta_packed(t) the sediment's mean fraction; at the
    meeting the sediment holds the whole layer, so theta_packed = theta0 H0 / h_m with h_m the height of the
    hydrostatic sediment of mass rho_s theta0 H0 below its theta0 level (the :func:`final_sediment` holding that
    plus the mass above theta0 in a free top, rho_s (p_s(theta0) - p_s(0)) / ((rho_s - rho_g) |g|)). This makes
    t_m exact where the sediment consolidates as fast as it is fed (the front is then not exactly a line between:
    theta_packed grows as the sediment deepens); a slower consolidation leaves a looser, taller sediment that
    meets the interface earlier, so t_m is the latest meeting. A float ``theta_packed`` overrides the choice (a
    close packing in a kinematic model)."""
    check_fraction(theta0)
    if not H0 > 0:
        raise ValueError("H0 must be > 0")
    check_form(form)
    v0 = hindered_settling_velocity(theta0, ph)
    below = np.linspace(0.0, theta0, 41)[1:-1]
    if np.any(np.abs(kynch_flux(below, ph)) / below < abs(v0)):
        raise ValueError("the settling speed does not fall with theta below theta0: the top is not one shock")
    mass = ph.rho_s * theta0 * H0
    final = final_sediment(mass, ph, G_a, G_b, form)
    if theta_packed is None:
        tail = ph.rho_s * (limits.pressure(theta0, G_a, G_b, form) - limits.pressure(0.0, G_a, G_b, form)) \
            / ph.buoyant                                         # mass above the theta0 level [kg/m^2]
        h_m = final_sediment(mass + tail, ph, G_a, G_b, form).height_of(theta0)
        theta_packed = theta0 * H0 / h_m
    else:
        h_m = theta0 * H0 / theta_packed
    if not theta_packed > theta0:
        raise ValueError(f"theta_packed = {theta_packed:g} must exceed theta0 = {theta0:g}")
    speed = theta0 * abs(v0) / (theta_packed - theta0)
    t_m = (H0 - h_m) / abs(v0)
    return Sedimentation(theta0, H0, v0, theta_packed, speed, t_m, h_m, final)
