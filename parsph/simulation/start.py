"""What a run starts from on one slab: its particles (from the scene, a snapshot or arrays), the walls'
density, the body force and the run's numbers and terms as the passes take them."""
import numpy as np

from parsph.output import read_particles
from parsph.physics.kernels import kernel_w_f
from parsph.physics.lattice_sums import lattice_sum
from parsph.sph import pass_data
from parsph.sph.particles import GRAIN, Particles


def slab_particles(cfg, ring, comm, state):
    """This slab's particles and whether the first build restores the list (``ref`` from a snapshot):
    from the scene, a snapshot (``state["path"]``) or arrays (id, kind, mass, position, velocity)."""
    if state is None:
        gid, kind, mass, pos, vel = cfg.scene.particles(cfg, ring.lo, ring.hi)
        perturb(cfg, kind, pos)
        return Particles.from_arrays(gid, kind, mass, pos, vel), False
    if "path" in state:  # a snapshot: only this slab's particles, read collectively (O(N/P) memory)
        p = read_particles(state["path"], comm, ring.lo, ring.hi)
        exact = "ref" in p  # the solver's state as it held it: continue from the same neighbour list
        ps = Particles.from_arrays(p["id"], p["kind"].astype(np.int64), p["mass"],
                                   p["position_raw"] if exact else p["position"], p["velocity"])
        if exact:
            ps.add_field("ref")
            ps.ref[:ps.n_own] = p["ref"]
        return ps, exact
    y = state["position"][:, 1]
    mine = (y >= ring.lo) & (y < ring.hi)
    return Particles.from_arrays(state["id"][mine], state["kind"][mine].astype(np.int64), state["mass"][mine],
                                 state["position"][mine], state["velocity"][mine]), False


def perturb(cfg, kind, pos):
    """[perturbation]: the fluid particles displaced along x by amplitude sin(2 pi x / wavelength) (a voidage
    wave's seed; along gravity in the beds and layers), times cos(2 pi y / wavelength_y) where that is given
    (a seed that varies across the bed: its columns alternately lifted and lowered), in place."""
    A = cfg.get("perturbation.amplitude")
    if A:
        fluid = kind == GRAIN
        dx = A * np.sin(2.0 * np.pi * pos[fluid, 0] / cfg.get("perturbation.wavelength"))
        lam_y = cfg.get("perturbation.wavelength_y")
        if lam_y is not None:
            dx *= np.cos(2.0 * np.pi * pos[fluid, 1] / lam_y)
        pos[fluid, 0] += dx


def hold_wall_density(cfg, kernel, ps):
    """Walls hold the density that Eq. (3) gives inside the initial lattice, so that the undisturbed
    lattice is in equilibrium next to a wall; scaled by the scene's wall_theta(x) / theta_0 where it
    has one (a function of x, which walls keep: a restart finds the same values). Returns that density."""
    rho_wall = cfg.mass * lattice_sum(kernel, cfg.h, cfg.spacing)
    ps.rho[:ps.n] = rho_wall
    wall_theta = cfg.scene.wall_theta
    if wall_theta is not None:
        wall = ps.kind[:ps.n] != GRAIN
        ps.rho[:ps.n][wall] *= wall_theta(cfg, ps.pos[:ps.n][wall, 0]) / cfg.theta0
    return rho_wall


def body_force(cfg):
    """g as a 3-vector; in a gas, with buoyancy: g (1 - rho_g / rho_s) (docs/physics.md)."""
    g = np.zeros(3)
    g[:cfg.dim] = cfg.g
    if cfg.gas is not None:
        g *= 1.0 - cfg.gas.rho / cfg.rho_s
    return g


def the_one_mass(collect, ps):
    """The mass every particle of the run has, or 0.0 where they differ (over all ranks; a run neither
    creates nor changes particles, so it holds to the end)."""
    m = ps.mass[:ps.n_own]
    lo_hi = np.array([-m.min(), m.max()]) if m.size else np.array([-np.inf, -np.inf])
    neg_lo, hi = collect.max(lo_hi)
    return float(hi) if -neg_lo == hi else 0.0


def pass_groups(cfg, kernel, mass):
    """The run's numbers and terms as the passes take them (pass_data.Constants, pass_data.Switches); every
    scene honours body_force.g (:func:`body_force`)."""
    sw = pass_data.switch
    g = body_force(cfg)
    inv_h = 1.0 / cfg.h
    norm = kernel.norm(cfg.h, cfg.dim)
    w0 = kernel_w_f(kernel.kid, 0.0, inv_h, norm)[0]
    consts = pass_data.Constants(kernel.kid, inv_h, norm, w0, cfg.rho_s, cfg.G_a, cfg.G_b, cfg.k, cfg.L,
                                 cfg.beta_max, np.asarray(g, float), mass, gas_constants(cfg.gas),
                                 cfg.mass / (cfg.rho_s * cfg.theta0), *(cfg.packing or (0.0, 0.0)),
                                 cfg.Ly if cfg.sides else 0.0, cfg.Ly_ring)
    switches = pass_data.Switches(sw(cfg.pressure), sw(cfg.viscosity),
                                  sw(cfg.get("numerics.viscosity_form") == "symmetric"), sw(cfg.scene.walls),
                                  sw(cfg.get("numerics.pressure_form") == "consistent"), sw(cfg.dim == 3),
                                  sw(mass > 0.0), sw(cfg.gas is not None), sw(cfg.scene.free_surface),
                                  sw(bool(cfg.packing)))
    return consts, switches


def gas_constants(gas):
    """The gas as the loops take it (pass_data.GasConstants; zeros without a gas)."""
    if gas is None:
        return pass_data.GasConstants(0, 0.0, 0.0, 0.0, 0, 0, 0.0, 0.0, np.zeros(3))
    u = np.zeros(3)
    u[:len(gas.velocity)] = gas.velocity
    return pass_data.GasConstants(gas.model, gas.rho, gas.mu, gas.d, pass_data.FLOWS[gas.flow], max(gas.axis, 0),
                                  gas.sign, gas.U, u)
