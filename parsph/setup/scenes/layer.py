"""What the layer scenes share (``sedimentation``, ``fluidized_bed``): a layer of solids on the floor x = 0
under clear gas, a lid at x = L, gravity along -x, y (and z) periodic.

The fluid fills the lattice up to ``scene.height`` = H0 (the columns with x < H0); above it there are no
particles up to the lid. The top is a free surface: Eq. (3) sums over the particles there are, so the top
rows' theta falls toward theta0 / 2 over 2h (the kernel's missing half), and Eq. (5) needs nothing more
there: the pressure term's G((theta_i + theta_j)/2) is the smallest where theta is, the 1/theta factors are
at most 1/theta of a particle alone (its own m W(0) / rho_s, 0.29 theta0 at h = 1.25 dx), and gravity holds
the layer down (tests/test_layers_scenes.py: a layer at rest keeps its mass below a height and its top
within a few h of the hydrostatic profile's).

The floor's and the lid's walls continue the solids' own state, per pair (:mod:`parsph.sph.walls`, after
Adami, Hu & Adams 2012; docs/physics.md, "Walls under a free surface"): massless particles, each a
lattice site's volume, that renormalise Eq. (3) near a plate and carry the pressure extrapolated from the
grain next to them plus the body force. They know nothing of the end state, so a layer dropped loose
comes to rest on the floor instead of going through it.

The references are docs/physics.md's 3 and 4 (:mod:`parsph.physics.gas_references`: the end state, Kynch's
solution) and the whole transient between them (:mod:`parsph.physics.consolidation`), built once per run's
values (cached).
"""
from dataclasses import dataclass
from functools import lru_cache
import math


from parsph.errors import ConfigError
from parsph.physics import bed_expansion, closures, consolidation, gas_references as refs, kynch, limits, voidage_waves
from parsph.sph.particles import GRAIN
from . import lattice


def height(cfg):
    """H0 [m]: ``scene.height``, default L / 2."""
    h = cfg.get("scene.height")
    return 0.5 * cfg.L if h is None else h


def fluid_columns(cfg):
    """Lattice columns the layer fills: round(H0 / dx), at least 1."""
    return max(1, int(round(height(cfg) / cfg.dx)))


def layer_height(cfg):
    """The layer's initial height on the lattice [m] (its mass is rho_s theta0 times it)."""
    return fluid_columns(cfg) * cfg.dx


def weight(cfg):
    """|g| with buoyancy (1 - rho_g / rho_s) |g| [m/s^2], along -x."""
    return abs(cfg.g[0]) * (1.0 - (cfg.gas.rho / cfg.rho_s if cfg.gas is not None else 0.0))


def phases(cfg):
    """The run's solids and gas as the references take them (no gas: rho_g = 0, the drag unused)."""
    gas = cfg.gas
    if gas is None:
        return refs.Phases(cfg.rho_s, 0.0, 1.8e-5, cfg.get("material.d"), abs(cfg.g[0]), "stokes")
    return refs.Phases(cfg.rho_s, gas.rho, gas.mu, gas.d, abs(cfg.g[0]), gas.closure)


def form(cfg):
    return "paper" if cfg.get("numerics.pressure_form") == "paper" else "consistent"


@lru_cache(maxsize=16)
def _column(ph, mass, U, G_a, G_b, form, packing):
    return bed_expansion.steady_column(mass, U, ph, G_a, G_b, form, packing=packing)


@lru_cache(maxsize=16)
def _sedimentation(ph, theta0, H0, G_a, G_b, form):
    return kynch.batch_sedimentation(theta0, H0, ph, G_a, G_b, form)


def mass(cfg):
    """The layer's mass per unit floor area [kg/m^2]."""
    return cfg.rho_s * cfg.theta0 * layer_height(cfg)


def end_state(cfg):
    """The layer's steady state (bed_expansion.Column): the hydrostatic sediment (U = 0, or no gas), else the steady
    column at U with the layer's mass."""
    U = cfg.gas.U if cfg.gas is not None else 0.0
    return _column(phases(cfg), mass(cfg), U, cfg.G_a, cfg.G_b, form(cfg), cfg.packing)


def sedimentation(cfg):
    """Kynch's solution for the layer (kynch.Sedimentation)."""
    return _sedimentation(phases(cfg), cfg.theta0, layer_height(cfg), cfg.G_a, cfg.G_b, form(cfg))


@lru_cache(maxsize=8)
def _transient(ph, theta0, H0, L, U, G_a, G_b, form, times):
    return consolidation.solve(theta0, H0, ph, times, L, U, G_a, G_b, form)


def transient(cfg, times):
    """The layer's whole transient in the column closure with inertia dropped (consolidation.Transient: the
    sedimentation-consolidation equation from the layer at rest, theta0 up to H0, to the lid) at ``times``
    [s] (> 0); None without a gas (the layer then falls under gravity alone: no such reference). It applies to
    ``gas.flow = "solved"`` too, the grid's gas reducing to the column closure in a layer uniform across.
    None too with a packing limit (``material.theta_max``: that solver has G's p_s only)."""
    if cfg.gas is None or cfg.packing:
        return None
    return _transient(phases(cfg), cfg.theta0, layer_height(cfg), cfg.L, cfg.gas.U, cfg.G_a, cfg.G_b, form(cfg),
                      tuple(sorted(set(float(t) for t in times))))


def particles(cfg, y_lo, y_hi):
    gid, kind, m, pos, vel = lattice(cfg, y_lo, y_hi, fluid_columns=fluid_columns(cfg))
    m[kind != GRAIN] = 0.0  # the walls continue the solids' state (parsph.sph.walls): no mass of their own
    return gid, kind, m, pos, vel


def check(cfg, scene):
    """Gravity along -x only; H0 inside the box, below the lid by the kernel's reach; the end state exists."""
    g = cfg.g
    if not (g[0] < 0.0 and not any(g[1:])):
        raise ConfigError("body_force.g", f"the {scene} scene needs gravity along -x only (toward the floor), "
                          f"got {list(g)}")
    H0 = height(cfg)
    if not H0 + 2.0 * cfg.h <= cfg.L:
        raise ConfigError("scene.height", f"{H0:g} m leaves less than 2h = {2 * cfg.h:g} m below the lid at "
                          f"domain.L = {cfg.L:g} m")
    if H0 < 0.5 * cfg.dx:
        raise ConfigError("scene.height", f"{H0:g} m is less than half a lattice step dx = {cfg.dx:g} m")
    try:
        end = end_state(cfg)
    except (ValueError, RuntimeError) as e:
        raise ConfigError("scene.height", f"the layer has no steady state: {e}") from None
    if not math.isfinite(end.theta_floor):
        raise ConfigError("scene.height", "the layer's steady state is not finite")
    return end


def max_kinetic_energy(cfg, fluid_mass):
    """At most all the potential energy: every particle falling from the lid to the floor."""
    return fluid_mass * abs(cfg.g[0]) * cfg.L


# ---- what a layer says about itself: the banner of `parsph run` and the output files' root attributes ----
RANDOM_CLOSE_PACKING = 0.64  # theta of randomly packed equal spheres: no bed of them is denser


@dataclass(frozen=True)
class Numbers:
    """A layer's own scales (SI): theta0, H0 (the lattice's layer height), U, the buoyant weight's pressure
    drop theta0 (rho_s - rho_g) |g| H0 across the layer, and with a gas: Stokes's terminal velocity u_t, the
    drag time tau at theta0 (along the column, at the slip that carries the weight:
    refs.settling_relaxation_time), Ergun's minimum fluidisation velocity U_mf at theta0
    (bed_expansion.minimum_fluidization_velocity), and Wallis's two wave speeds (:class:`voidage_waves.Bed`) at
    ``theta_wallis`` (a fed bed's uniform interior theta*, else theta0): the elastic c_d = sqrt(p_s'/rho_s)
    and the kinematic c_k of the run's closure. Without a gas those are NaN."""
    theta0: float
    H0: float
    U: float
    dp_bed: float
    u_t: float = math.nan
    tau: float = math.nan
    U_mf: float = math.nan
    theta_wallis: float = math.nan
    c_d: float = math.nan
    c_k: float = math.nan

    @property
    def packed_past(self):
        """theta0 above random close packing: outside the physical range (the model runs it)."""
        return self.theta0 > RANDOM_CLOSE_PACKING

    @property
    def past_wallis(self):
        """The kinematic wave outruns the elastic one: a uniform layer does not stay uniform."""
        return self.c_k > self.c_d


def numbers(cfg):
    """The layer's :class:`Numbers` (a few root-finds: computed per call, not in the step)."""
    gas, H0 = cfg.gas, layer_height(cfg)
    if gas is None:
        return Numbers(cfg.theta0, H0, 0.0, cfg.theta0 * cfg.rho_s * abs(cfg.g[0]) * H0)
    ph = phases(cfg)
    theta = cfg.theta0
    if gas.U > 0:
        theta = end_state(cfg).theta_star
    bed = voidage_waves.Bed(theta, cfg.rho_s, gas.rho, gas.mu, gas.d, ph.g, cfg.k * theta,
                            limits.dpressure(theta, cfg.G_a, cfg.G_b, form(cfg), cfg.packing), gas.model)
    return Numbers(cfg.theta0, H0, gas.U, cfg.theta0 * ph.buoyant * H0, u_t=ph.u_t,
                   tau=refs.settling_relaxation_time(cfg.theta0, ph),
                   U_mf=bed_expansion.minimum_fluidization_velocity(cfg.theta0, ph), theta_wallis=theta,
                   c_d=bed.elastic_speed(), c_k=bed.kinematic_speed())


def file_attributes(cfg):
    """The layer's own root attributes of an output file: H0 [m], U, U_mf [m/s] (NaN without a gas) and
    dp_bed [Pa], the pressure drop across the layer at its buoyant weight theta0 (rho_s - rho_g) |g| H0."""
    gas, H0 = cfg.gas, layer_height(cfg)
    buoyant = phases(cfg).buoyant
    U_mf = bed_expansion.minimum_fluidization_velocity(cfg.theta0, phases(cfg)) if gas is not None else math.nan
    return {"H0": H0, "U": gas.U if gas is not None else 0.0, "U_mf": U_mf, "dp_bed": cfg.theta0 * buoyant * H0}


def describe(cfg):
    """The banner's lines about the layer (after its first line): its scales, and Wallis's margin."""
    n = numbers(cfg)
    packed = (f" (past random close packing, {RANDOM_CLOSE_PACKING:g}: outside the physical range)"
              if n.packed_past else "")
    across = (f"between side walls {cfg.Ly:g} m apart" if cfg.sides else f"periodic across L_y = {cfg.Ly:g} m")
    if cfg.dim == 3:
        across += f", periodic across L_z = {cfg.Lz:g} m"
    head = f"  layer: theta0 = {n.theta0:.4g}{packed}, H0 = {n.H0:.4g} m, {across}"
    if cfg.packing:
        lo, hi = cfg.packing
        p_f = closures.packing_pressure(cfg.theta0, lo, hi)[0]
        p_G = limits.pressure(cfg.theta0, cfg.G_a, cfg.G_b, "consistent")
        head += (f", packing limit theta_max = {hi:g} from theta_min = {lo:g} (at theta0 the frictional "
                 f"p_f = {p_f:.4g} Pa, G's p = {p_G:.4g} Pa)")
    if cfg.gas is None:
        return [f"{head}; no gas: it falls under gravity alone"]
    ratio = f"{n.U / n.U_mf:.4g}" if n.U_mf > 0 else "inf"
    where = "theta*" if n.U > 0 else "theta0"
    verdict = "past Wallis's bound: a uniform layer is unstable to voidage waves" if n.past_wallis else "stable"
    return [f"{head}; u_t = {n.u_t:.4g} m/s (Stokes), tau = {n.tau:.4g} s (the drag time at theta0); "
            f"U = {n.U:.4g} m/s, U_mf = {n.U_mf:.4g} m/s (Ergun at theta0), U/U_mf = {ratio}",
            f"  Wallis at {where} = {n.theta_wallis:.4g}: elastic c_d = {n.c_d:.4g} m/s, kinematic "
            f"c_k = {n.c_k:.4g} m/s, c_d/c_k = {n.c_d / n.c_k:.4g} ({verdict})"]


def wallis_warnings(cfg):
    """One line for a bed (fed at U > 0) past Wallis's bound in the one-dimensional gas (gas.flow = "column"):
    it would bubble and slug, which that gas cannot describe; the solved gas can."""
    gas = cfg.gas
    if gas is None or not gas.column or not gas.U > 0:
        return []
    n = numbers(cfg)
    if not n.past_wallis:
        return []
    return [f"parsph: warning: the bed is past Wallis's bound at theta* = {n.theta_wallis:.4g}: the kinematic "
            f"wave speed c_k = {n.c_k:.4g} m/s exceeds the elastic c_d = {n.c_d:.4g} m/s, so it does not stay "
            f"uniform (voidage waves, slugs), which the one-dimensional gas (gas.flow = \"column\") cannot "
            f"describe: give gas.flow = \"solved\""]
