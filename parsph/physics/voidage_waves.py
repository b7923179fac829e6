"""Reference 7 (docs/physics.md, "The solved gas"): voidage waves in a uniform fluidised bed (Anderson &
Jackson 1968; Jackson 2000). A bed at rest at theta0, fed at its fluidising velocity U = U_f(theta0), x up
along e; with

    f(theta, v) = beta(theta, |U - v| / eps) (U - v) / eps^2 - theta (rho_s - rho_g) |g|    (per unit volume)

(the column's drag less the buoyant weight; f = 0 in the base state), f_theta and B = -f_v at (theta0, 0), and
a perturbation exp(i k x + s t), the linearised solids momentum and continuity give

    theta0 rho_s s^2 + (theta0 mu_s k^2 + B) s + i k theta0 f_theta + k^2 theta0 p_s'(theta0) = 0.

Re(s) is the growth rate, -Im(s)/k the wave speed (upward where positive). The viscous term is the SPH's:
Eq. (5)'s Morris sum is (mu_s / rho_s) lap v per unit mass, theta0 mu_s lap v per unit volume (docs/physics.md
writes mu_s k^2; the factor theta0 is the discrete model's). p_s' is dp/dtheta of the pressure form in use
(:func:`parsph.physics.limits.dpressure`). Long waves grow iff the kinematic speed c_k = theta0 f_theta / B
exceeds the elastic one c_d = sqrt(p_s' / rho_s) (Wallis); Stokes drag: c_k = 4.65 theta0 u_t eps0^3.65."""
from dataclasses import dataclass
import math

import numpy as np

from parsph.physics import drag


@dataclass(frozen=True)
class Bed:
    """A uniform bed at rest: the closure ``model`` (:data:`parsph.physics.drag.MODELS`), the grains and gas."""
    theta0: float
    rho_s: float
    rho_g: float
    mu_g: float
    d: float
    g: float          # |g| [m/s^2]
    mu_s: float       # the solids' viscosity k theta0 [Pa s]
    dp: float         # p_s'(theta0) [Pa]
    model: int = drag.STOKES

    def force(self, theta, v, U):
        """f(theta, v) [N/m^3] at the superficial velocity U."""
        eps = 1.0 - theta
        slip = abs(U - v) / eps
        return drag.beta(self.model, theta, slip, self.rho_g, self.mu_g, self.d) * (U - v) / eps ** 2 \
            - theta * (self.rho_s - self.rho_g) * self.g

    def fluidising_velocity(self):
        """U_f(theta0): the root of f(theta0, 0; U) = 0 (Stokes: u_t eps0^4.65)."""
        lo, hi = 0.0, 1.0
        while self.force(self.theta0, 0.0, hi) < 0:
            hi *= 2.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.force(self.theta0, 0.0, mid) < 0 else (lo, mid)
        return 0.5 * (lo + hi)

    def derivatives(self):
        """(f_theta, B) at the base state, by central differences of f (relative steps 1e-6)."""
        U, t0 = self.fluidising_velocity(), self.theta0
        ht, hv = 1e-6 * t0, 1e-6 * U
        f_theta = (self.force(t0 + ht, 0.0, U) - self.force(t0 - ht, 0.0, U)) / (2 * ht)
        B = -(self.force(t0, hv, U) - self.force(t0, -hv, U)) / (2 * hv)
        return f_theta, B

    def kinematic_speed(self):
        f_theta, B = self.derivatives()
        return self.theta0 * f_theta / B

    def elastic_speed(self):
        return math.sqrt(self.dp / self.rho_s)

    def rate(self, k):
        """s(k): the root of the quadratic with the larger real part (the other is the fast decay of the
        slip, about -B / (theta0 rho_s))."""
        f_theta, B = self.derivatives()
        a = self.theta0 * self.rho_s
        b = self.theta0 * self.mu_s * k * k + B
        c = 1j * k * self.theta0 * f_theta + k * k * self.theta0 * self.dp
        disc = np.sqrt(complex(b * b - 4 * a * c))
        roots = ((-b + disc) / (2 * a), (-b - disc) / (2 * a))
        return max(roots, key=lambda s: s.real)

    def growth_and_speed(self, wavelength):
        """(Re s [1/s], -Im s / k [m/s]) of the mode of the given wavelength [m]."""
        k = 2 * math.pi / wavelength
        s = self.rate(k)
        return s.real, -s.imag / k
