"""A run: the validated run file and every quantity derived from it, computed once (:class:`RunConfig`).

A run file (:class:`parsph.setup.runfile.RunFile`) has the sections of
:data:`parsph.setup.schema.SCHEMA`; ``parsph run --set section.key=value``
overrides any key. Every
problem raises :class:`ConfigError` naming the key. The full key list with
units is in docs/running.md ("Run-file keys"). :func:`build` derives the
lattice, checks the kernel's support against it, and chooses the time step
against the run's stability limits (:mod:`parsph.physics.limits`).
"""
from dataclasses import dataclass, field, replace
import math

from parsph.physics.kernels import get_kernel
from parsph.physics import drag as closures_drag
from parsph.physics import closures
from parsph.physics import limits as stability
from parsph.errors import ConfigError
from .gas_config import gas_of, solved_grid
from .runfile import RunFile
from .scenes import get_scene
from .schema import validate

MAX_NEIGHBOURS = 5000  # lattice neighbours within the support: memory and time per particle grow with it


@dataclass(frozen=True)
class RunConfig:
    """A validated run with every derived quantity (SI units)."""
    values: dict
    text: str  # the run file as given, overrides applied (TOML)
    dim: int
    L: float
    Ly: float
    Lz: float
    Nx: int
    Ny: int
    Nz: int
    dx: float
    dy: float
    dz: float
    h: float
    layers: int
    mass: float
    rho_s: float
    theta0: float
    k: float
    G_a: float
    G_b: float
    V_w: float
    beta_max: float
    kernel: str
    dt: float
    dt_auto: bool
    t_end: float
    nsteps: int
    output_times: tuple
    integrator: str
    g: tuple
    scene: object = None
    gas: object = None   # Gas, or None: no gas (gas.drag = "none")
    pressure: bool = True
    viscosity: bool = True
    limits: dict = field(default_factory=dict)
    packing: tuple = ()  # (theta_min, theta_max) of the frictional pressure (material.theta_max), () for none
    side_layers: int = 0  # rows of wall particles beyond y = Ly (walls.sides), 0: y periodic with period Ly

    @property
    def sides(self):
        """Side walls at y = 0 and y = Ly (``walls.sides``)."""
        return self.side_layers > 0

    @property
    def Ly_ring(self):
        """The period of the slabs' ring along y [m]: Ly, and with side walls the rows of wall particles beyond
        it, which stand for both walls (the one at y = Ly, and across the period the one at y = 0)."""
        return self.Ly + self.side_layers * self.dy

    @property
    def nu(self):
        """Kinematic viscosity k theta0 / rho_s (Eq. (5) in a uniform state)."""
        return self.k * self.theta0 / self.rho_s

    @property
    def n_particles(self):
        """Fluid and wall particles the scene builds: the lattice's, less its empty columns above a layer
        (a scene with a free surface fills the columns below ``scene.height`` only)."""
        fluid = self.Nx
        if self.scene.free_surface:
            from .scenes import layer
            fluid = min(self.Nx, layer.fluid_columns(self))
        across = fluid + (2 * self.layers if self.scene.walls else 0)
        return (across * self.Ny + (self.Nx + 2 * self.layers) * self.side_layers) * self.Nz

    @property
    def spacing(self):
        """Lattice step per dimension [m]."""
        return (self.dx, self.dy, self.dz)[:self.dim]

    @property
    def velocity_scale(self):
        """The run's velocity scale [m/s]: the scene's, or the gas's (:attr:`gas_speed`) where larger;
        errors are normalised by it."""
        return max(self.scene.velocity_scale(self), self.gas_speed)

    @property
    def gas_speed(self):
        """The speed the gas drives [m/s]: a stream's |u_g|, or a column's U and its hindered settling
        speed at theta_0 (Stokes's, u_t eps_0^4.65, which bounds the other closures'); 0 without a gas."""
        gas = self.gas
        if gas is None:
            return 0.0
        if not gas.fed:
            return math.sqrt(sum(u * u for u in gas.velocity))
        g = math.sqrt(sum(x * x for x in self.g))
        u_t = closures_drag.terminal_velocity(self.rho_s, gas.rho, g, gas.d, gas.mu)
        return max(gas.U, u_t * (1.0 - self.theta0) ** 4.65)

    def drag_coefficient(self, theta, slip):
        """The largest drag coefficient C [1/s] of a particle at (theta, |u_g - v| = slip): 1/tau with tau
        of docs/physics.md (along a column's axis: rho_s theta eps^2 / beta); 0 without a gas."""
        gas = self.gas
        if gas is None:
            return 0.0
        K = closures_drag.rate(gas.model, theta, slip * slip, self.rho_s, gas.rho, gas.mu, gas.d)
        return K / (1.0 - theta) if gas.fed else K

    def error_scale(self, t):
        """What errors of the scene's error field are relative to at time t [m/s or 1]: the amplitude left
        of a decaying flow (the scene's current_scale), else the fixed scale (the velocity scale, or
        theta_0 for theta); where that is 0 (no flow to measure against), 1: errors in m/s.
        The profile, the output files and ``parsph check`` all take it from here."""
        if self.scene.current_scale is not None:
            left = float(self.scene.current_scale(self, t))
            if left > 0:
                return left
        scale = self.velocity_scale if self.scene.error_field == "vy" else self.theta0
        return scale if scale > 0 else 1.0

    @property
    def reynolds(self):
        return self.velocity_scale * self.L / self.nu if self.nu > 0 else math.inf

    def get(self, dotted):
        section, key = dotted.split(".")
        return self.values[section][key]


def _finite(key, value, what):
    """A derived quantity must be a finite, positive float: else the key is out of range."""
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(key, f"out of range: {what} = {value!r}")
    return value


def _lattice(v):
    """dim, L, Ly, Lz, Nx, Ny, Nz, dx, dy, dz, h and the key that gave h, of the validated values ``v``."""
    dom, num = v["domain"], v["numerics"]
    dim = v["scene"]["dim"]
    L = dom["L"]
    Ly = dom["Ly"] if dom["Ly"] is not None else L
    Nx = num["Nx"]
    dx = _finite("domain.L", L / Nx, "dx = L / Nx")
    if (num["h"] is None) == (num["h_over_dx"] is None):
        raise ConfigError("numerics.h", "give exactly one of numerics.h and numerics.h_over_dx")
    h = num["h"] if num["h"] is not None else num["h_over_dx"] * dx
    hkey = "numerics.h" if num["h"] is not None else "numerics.h_over_dx"
    if not (math.isfinite(h) and 0 < h / dx <= 1e6):
        raise ConfigError(hkey, f"h / dx = {h / dx:.3g} is out of range")
    for key, length in (("domain.Ly", Ly), ("domain.Lz", dom["Lz"] or Ly)):
        if not length / dx <= 2 ** 40:
            raise ConfigError(key, f"{length:g} m holds more than 2^40 particle rows of dx = {dx:g} m")
    Ny = max(1, round(Ly / dx))
    dy = Ly / Ny
    Lz = (dom["Lz"] if dom["Lz"] is not None else Ly) if dim == 3 else dx
    Nz = max(1, round(Lz / dx)) if dim == 3 else 1
    dz = Lz / Nz
    return dict(dim=dim, L=L, Ly=Ly, Lz=Lz, Nx=Nx, Ny=Ny, Nz=Nz, dx=dx, dy=dy, dz=dz, h=h), hkey


def _wall_layers(v, lat, hkey, scene, kern):
    """The wall layers, after checking that the kernel's support fits the lattice and the box."""
    num, walls = v["numerics"], v["walls"]
    dim, L, Ly, Lz, dx, h = lat["dim"], lat["L"], lat["Ly"], lat["Lz"], lat["dx"], lat["h"]
    support = kern.support * h
    if support <= dx * (1 + 1e-9):
        raise ConfigError(hkey, f"h / dx = {h / dx:.3g} is too small: the kernel support {kern.support:g}h = "
                          f"{support:.3g} m does not reach the next particle (dx = {dx:g} m), so no particle "
                          f"has a neighbour; need h / dx > {1 / kern.support:g} (the usual: 1.2 to 2)")
    lengths = [L, Ly] + ([Lz] if dim == 3 else [])
    if support > max(lengths):
        # wider than the channel and than the box: h is the cause, not one length
        raise ConfigError(hkey, f"h = {h:g} m (h / dx = {h / dx:.3g}) is too large: the kernel support "
                          f"2h = {support:g} m is wider than the channel (L = {L:g} m) and the box "
                          f"(L_y = {Ly:g} m{f', L_z = {Lz:g} m' if dim == 3 else ''})")
    ball = math.pi * (support / dx) ** 2 if dim == 2 else 4.0 / 3.0 * math.pi * (support / dx) ** 3
    if ball > MAX_NEIGHBOURS:  # with h given, N_x made dx too small for it; else h_over_dx is too large
        raise ConfigError("numerics.Nx" if num["h"] is not None else hkey, f"h / dx = {h / dx:.3g} is too large: the kernel support {kern.support:g}h holds "
                          f"about {ball:.3g} lattice neighbours per particle, more than {MAX_NEIGHBOURS} "
                          f"(the usual h / dx: 1.2 to 2.5, some 20 to 80 neighbours)")
    need_layers = math.ceil(support / dx - 1e-9)
    layers = walls["layers"] or need_layers
    if scene.walls and layers * dx < support * (1 - 1e-9):
        raise ConfigError("walls.layers", f"{layers} layers of dx = {dx:g} m do not cover the kernel "
                          f"support {support:g} m; need at least {need_layers}")
    if Ly < support:
        raise ConfigError("domain.Ly", f"{Ly:g} m is shorter than the kernel support 2h = {support:g} m")
    if dim == 3 and Lz < support:
        raise ConfigError("domain.Lz", f"{Lz:g} m is shorter than the kernel support 2h = {support:g} m")
    if not scene.walls and L < support:
        raise ConfigError("domain.L", f"{L:g} m is shorter than the kernel support 2h = {support:g} m")
    return layers if scene.walls else 0


def _side_layers(v, scene, layers):
    """Rows of wall particles beyond y = Ly for ``walls.sides`` (the plates' layers: they cover the kernel
    support, so the solids on either side see a whole wall and nothing of each other); 0 without."""
    if not v["walls"]["sides"]:
        return 0
    if not scene.free_surface:
        raise ConfigError("walls.sides", f"side walls close a layer or bed on the floor (the sedimentation and "
                          f"fluidized_bed scenes); the {scene.name} scene is periodic along y")
    return layers


def _body_force(v, dim, scene):
    """g per dimension: every scene honours it; a scene driven by a body force needs one."""
    g = v["body_force"]["g"]
    if g is None:
        g = (0.0,) * dim
    if len(g) != dim:
        raise ConfigError("body_force.g", f"needs {dim} components, got {len(g)}")
    if scene.terms.body_force and not any(g):
        raise ConfigError("body_force.g", f"the {scene.name} scene is driven by a body force; give a non-zero g")
    return tuple(g)


def _pressure_term(v, scene):
    """Eq. (5)'s pressure term: as terms.pressure says, else as the scene declares; a perturbed scene has it
    (a compression wave without the solids pressure would grow at the G -> 0 rate)."""
    given = v["terms"]["pressure"]
    if _perturbation(v) is not None:
        if given is False:
            raise ConfigError("terms.pressure", "is off, but a perturbation compresses the solids: its waves need "
                              "the solids pressure (leave terms.pressure out, or set it true)")
        return True
    return scene.terms.pressure if given is None else given


def _perturbation(v):
    """(amplitude, wavelength) of [perturbation], or None where its amplitude is 0."""
    p = v["perturbation"]
    A, lam, lam_y = p["amplitude"], p["wavelength"], p["wavelength_y"]
    if A == 0.0:
        for key in ("wavelength", "wavelength_y"):
            if p[key] is not None:
                raise ConfigError(f"perturbation.{key}", "has no effect without perturbation.amplitude")
        return None
    if lam is None:
        raise ConfigError("perturbation.amplitude", "needs perturbation.wavelength [m]")
    if not 2.0 * math.pi * abs(A) < lam:
        raise ConfigError("perturbation.amplitude", f"{A:g} m is too large for the wavelength {lam:g} m: "
                          "2 pi |amplitude| / wavelength >= 1 lets particles overtake each other")
    scene = get_scene(v["scene"]["name"])
    L, Nx = v["domain"]["L"], v["numerics"]["Nx"]
    if scene.walls and not abs(A) < 0.5 * L / Nx:
        raise ConfigError("perturbation.amplitude", f"{A:g} m would move the particles next to a wall past it: "
                          f"keep it below dx/2 = {0.5 * L / Nx:g} m")
    if not scene.walls and abs(L / lam - round(L / lam)) > 1e-9 * L / lam:
        raise ConfigError("perturbation.wavelength", f"{lam:g} m does not divide the period domain.L = {L:g} m "
                          "(x is periodic): give L / n")
    if lam_y is not None:
        Ly = L if v["domain"]["Ly"] is None else v["domain"]["Ly"]
        if v["scene"]["dim"] == 1:
            raise ConfigError("perturbation.wavelength_y", "varies the seed across y; a 1-D scene has no y")
        if not v["walls"]["sides"] and (abs(Ly / lam_y - round(Ly / lam_y)) > 1e-9 * Ly / lam_y
                                        or round(Ly / lam_y) < 1):
            raise ConfigError("perturbation.wavelength_y", f"{lam_y:g} m does not divide the period domain.Ly = "
                              f"{Ly:g} m (y is periodic): give Ly / n")
    return A, lam


def _time_step(v, cfg):
    """dt, whether it is automatic, the step count, the output times and the run's limits at theta_0."""
    mat, num, out = v["material"], v["numerics"], v["output"]
    theta0, g = cfg.theta0, cfg.g
    # explicit drag at theta_0, its slip the run's velocity scale
    drag_max = cfg.drag_coefficient(theta0, cfg.velocity_scale) if cfg.gas else 0.0
    if cfg.gas and not (0.0 < drag_max < math.inf and math.isfinite(cfg.velocity_scale)):
        raise ConfigError("gas.drag", f"the drag coefficient 1/tau at theta_0 is {drag_max:g} 1/s at a slip of "
                          f"{cfg.velocity_scale:g} m/s: out of range (material.d, gas.mu, gas.rho, the gas's speed)")
    if cfg.gas and cfg.gas.implicit:
        drag_max = 0.0  # implicit drag has no limit
    try:
        # the run's limits at theta_0 (parsph.physics.limits): the refusal of a fixed dt and the first automatic dt
        limits = dict(stability.run_limits(cfg, theta0, cfg.velocity_scale, math.sqrt(sum(x * x for x in g)),
                                           drag_max))
    except ZeroDivisionError:  # (rho_s theta)^2 underflows to 0 in the limits' pressure term
        raise ConfigError("material.rho_s", f"{mat['rho_s']:g} kg/m^3 is too small: the stability limits divide "
                          "by rho_s^2, which is 0 in floating point") from None
    except OverflowError:
        key = "material.G_a" if abs(mat["G_a"] * theta0) >= abs(mat["G_b"]) else "material.G_b"
        raise ConfigError(key, f"G(theta0) = 10^({mat['G_a']:g} theta0 + {mat['G_b']:g}) overflows") from None
    dt_max = min(limits.values())
    if num["dt"] == "auto":
        dt, auto = num["dt_safety"] * dt_max, True
    else:
        dt, auto = num["dt"], False
        if not dt > 0:
            raise ConfigError("numerics.dt", f"must be positive or \"auto\", got {dt!r}")
        if dt > dt_max and not num["allow_unstable_dt"]:
            which = min(limits, key=limits.get)
            raise ConfigError("numerics.dt", f"{dt:g} s is above the stability limit {dt_max:.3g} s "
                              f"({which}); lower it, use \"auto\", or set numerics.allow_unstable_dt = true")
    t_end = out["t_end"]
    if not t_end / dt <= 1e12:
        raise ConfigError("numerics.dt", f"t_end / dt = {t_end / dt:.3g} steps is more than 1e12")
    nsteps = max(1, round(t_end / dt))
    times = tuple(sorted(set(out["times"])))
    for t in times:
        if not 0 <= t <= t_end * (1 + 1e-12):
            raise ConfigError("output.times", f"{t:g} s lies outside [0, t_end = {t_end:g} s]")
    settle = v["checks"]["settle"]
    if settle is not None and not settle < t_end:
        raise ConfigError("checks.settle", f"{settle:g} s is not before output.t_end = {t_end:g} s: nothing would "
                          "be averaged")
    return dict(dt=dt, dt_auto=auto, nsteps=nsteps, output_times=times, limits=limits)


def _packing(v):
    """(theta_min, theta_max) of ``material.theta_max``'s frictional pressure, () where it is not given."""
    mat = v["material"]
    lo, hi = mat["theta_min"], mat["theta_max"]
    if hi is None:
        if lo is not None:
            raise ConfigError("material.theta_min", "is where the packing limit's frictional pressure starts: "
                              "it needs material.theta_max")
        return ()
    lo = closures.THETA_MIN if lo is None else lo
    if not lo < hi < 1.0:
        raise ConfigError("material.theta_max", f"{hi:g} must lie between material.theta_min = {lo:g} and 1")
    if v["numerics"]["pressure_form"] != "consistent":
        raise ConfigError("material.theta_max", "the frictional pressure adds to p = G / (G_a ln 10): it needs "
                          "numerics.pressure_form = \"consistent\"")
    tc = closures.packing_limit(lo, hi)
    if not mat["theta0"] < tc:
        raise ConfigError("material.theta0", f"{mat['theta0']:g} is past the packing limit's theta_c = {tc:.4g} "
                          f"(material.theta_max = {hi:g}), where the frictional pressure is its tangent: start "
                          "below it")
    return (lo, hi)


def build(run_file):
    """Validate a :class:`RunFile` and derive the run's quantities."""
    text = run_file.dump()
    v = validate(run_file.tables())
    mat, walls, num, out, terms = v["material"], v["walls"], v["numerics"], v["output"], v["terms"]
    lat, hkey = _lattice(v)
    dim = lat["dim"]
    scene = get_scene(v["scene"]["name"])
    if v["scene"]["height"] is not None and not scene.free_surface:
        raise ConfigError("scene.height", f"is the height of a layer on the floor (the sedimentation and "
                          f"fluidized_bed scenes); the {scene.name} scene has none: leave it out")
    layers = _wall_layers(v, lat, hkey, scene, get_kernel(num["kernel"], dim))
    side_layers = _side_layers(v, scene, layers)
    g = _body_force(v, dim, scene)
    gas = gas_of(v, dim, g, mat["rho_s"])
    if gas is not None and gas.solved:
        gas = solved_grid(gas, lat, scene.walls)
    theta0 = mat["theta0"]
    packing = _packing(v)
    cfg = RunConfig(
        values=v, text=text, **lat, layers=layers,
        mass=mat["rho_s"] * theta0 * lat["dx"] * lat["dy"] * (lat["dz"] if dim == 3 else 1.0), rho_s=mat["rho_s"],
        theta0=theta0, k=mat["k"], G_a=mat["G_a"], G_b=mat["G_b"], V_w=walls["V_w"], beta_max=walls["beta_max"],
        kernel=num["kernel"], dt=0.0, dt_auto=False, t_end=out["t_end"], nsteps=0, output_times=(),
        integrator=num["integrator"], g=g, scene=scene, gas=gas,
        pressure=_pressure_term(v, scene),
        viscosity=scene.terms.viscosity if terms["viscosity"] is None else terms["viscosity"], packing=packing,
        side_layers=side_layers)
    if scene.check is not None:
        scene.check(cfg)
    return replace(cfg, **_time_step(v, cfg))


def load(path, overrides=()):
    """Read, override and validate a run file."""
    return build(RunFile.read(path).override(overrides))


def loads(text, overrides=()):
    """Validate a run file given as a TOML string."""
    return build(RunFile.parse(text).override(overrides))
