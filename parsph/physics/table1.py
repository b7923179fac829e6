"""Table 1 of the paper (docs/physics.md, "Table 1"): the transient plane Couette flow, in SI units.

The numbers the studies and the case builders (:mod:`parsph.studies.builders`)
read, so that none of them copies one; ``run/couette_paper.toml`` is the same
case as a run file (a test holds the two together). The closure's constants
G = 10^(G_A theta + G_B) are :data:`parsph.physics.closures.G_A` and ``G_B``.
"""
L = 0.01           # plate distance [m]
RHO_S = 2000.0     # solid material density [kg/m^3]
THETA0 = 0.35      # initial volume fraction
K = 1.0            # mu_s = k theta [Pa s]: Re = V_w L rho_s / (k theta_0) = 57.14
V_W = 1.0          # plate velocity [m/s]
NX = 50            # particles across the channel: dx = 2e-4 m
H_OVER_DX = 1.25   # h = 2.5e-4 m
DT = 1.0e-5        # time step [s]
T_END = 0.5        # the paper's last profile [s]
TIMES = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)  # the profiles it shows [s]
