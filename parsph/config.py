"""Run files: TOML, every key validated, derived quantities computed once.

A run file has the sections below; ``parsph run --set section.key=value``
overrides any key. Every problem raises :class:`ConfigError` naming the key.
The full key list with units is in docs/running.md ("Run-file keys").
"""
from dataclasses import dataclass, field, replace
import math
import tomllib

from .kernels import KERNEL_NAMES, get_kernel
from . import limits as stability
from .integrate import INTEGRATORS
from .scenes import SCENE_NAMES, get_scene

REQUIRED = object()
MAX_NEIGHBOURS = 5000  # lattice neighbours within the support: memory and time per particle grow with it


def bytes_per_particle(cfg):
    """An upper bound of the resident memory per particle [bytes], to refuse runs that cannot fit.

    Fields (about 300 + 100 dim bytes) plus the neighbour list, 12 bytes per
    entry for the neighbours within 2h (the disc or ball's lattice points,
    +25% for a compressed lattice) and a margin of 4, with 30% spare capacity.
    Measured (docs/performance.md): 550 B in 2-D, 1.7 KB in 3-D at
    h = 1.25 dx; this gives 950 B and 1.9 KB.
    """
    reach = 2.0 * cfg.h
    cells = [reach / s for s in cfg.spacing]
    ball = math.pi * cells[0] * cells[1] if cfg.dim == 2 else 4.0 / 3.0 * math.pi * math.prod(cells)
    return 300 + 100 * cfg.dim + 1.3 * 12 * (1.25 * ball + 4)


class ConfigError(Exception):
    """A bad run file: ``key`` names the offending key."""

    def __init__(self, key, reason):
        shown = repr(key) if len((key + ".").splitlines()) > 1 else key  # one line, always
        super().__init__(f"{shown}: {reason}")
        self.key = key
        self.reason = reason


@dataclass(frozen=True)
class Key:
    kind: str  # "float", "int", "str", "bool", "floatlist", "float_or_auto"
    default: object = REQUIRED
    positive: bool = False
    nonnegative: bool = False
    choices: tuple = ()
    lo: float = None  # inclusive lower bound
    hi: float = None  # exclusive upper bound
    doc: str = ""


SCHEMA = {
    "scene": {
        "name": Key("str", "couette", choices=SCENE_NAMES, doc="scene to run"),
        "dim": Key("int", 2, choices=(2, 3), doc="spatial dimension (3: z periodic too)"),
        "amplitude": Key("float", 0.01, doc="periodic_box: amplitude of the initial shear wave v_y [m/s]"),
    },
    "terms": {
        "pressure": Key("bool", None, doc="the pressure term of Eq. (5) (default: as the scene declares)"),
        "viscosity": Key("bool", None, doc="the viscous term of Eq. (5) (default: as the scene declares)"),
    },
    "domain": {
        "L": Key("float", REQUIRED, positive=True, doc="plate distance [m]"),
        "Ly": Key("float", None, positive=True, doc="periodic streamwise length [m] (default L)"),
        "Lz": Key("float", None, positive=True, doc="periodic spanwise length in 3-D [m] (default Ly)"),
    },
    "material": {
        "rho_s": Key("float", REQUIRED, positive=True, doc="solid material density [kg/m^3]"),
        "theta0": Key("float", REQUIRED, positive=True, hi=1.0, doc="initial volume fraction"),
        "k": Key("float", REQUIRED, nonnegative=True, doc="viscosity coefficient, mu_s = k theta [Pa s]"),
        "G_a": Key("float", 8.76, doc="G = 10^(G_a theta + G_b) [Pa]"),
        "G_b": Key("float", -1.183, doc="G = 10^(G_a theta + G_b) [Pa]"),
    },
    "walls": {
        "V_w": Key("float", 1.0, doc="velocity of the plate at x = L along +y [m/s]"),
        "layers": Key("int", 0, nonnegative=True, hi=1000, doc="wall particle layers (0: the fewest covering 2h)"),
        "beta_max": Key("float", 1.5, lo=1.0, doc="cap of the ghost velocity factor (Morris 1997)"),
    },
    "numerics": {
        "Nx": Key("int", REQUIRED, lo=2, hi=2 ** 40, doc="particles across the channel"),
        "h": Key("float", None, positive=True, doc="smoothing length [m] (or give h_over_dx)"),
        "h_over_dx": Key("float", None, positive=True, doc="smoothing length in units of dx"),
        "kernel": Key("str", "cubic_spline", choices=KERNEL_NAMES, doc="smoothing kernel"),
        "dt": Key("float_or_auto", REQUIRED, doc="time step [s] or \"auto\""),
        "dt_safety": Key("float", 1.0, positive=True, hi=1.0 + 1e-12,
                         doc="factor on the stability limits for dt = \"auto\""),
        "allow_unstable_dt": Key("bool", False, doc="run a dt above the stability limit (warns)"),
        "integrator": Key("str", "paper", choices=INTEGRATORS,
                          doc="time integrator: Eqs. (6)-(7), or explicit midpoint (second order)"),
        "pressure_form": Key("str", "paper", choices=("paper", "consistent"),
                             doc="Eq. (5) as printed (G at the pair mean; discretises grad(G theta)) or "
                                 "p = G/(G_a ln 10), whose gradient is G grad theta"),
        "skin": Key("float", 0.4, positive=True, hi=4.0,
                    doc="neighbour-list skin in units of h: the list holds pairs within 2h + skin and is "
                        "rebuilt when particles near each other moved more than the skin relative to each other"),
        "viscosity_form": Key("str", "paper", choices=("paper", "symmetric"),
                              doc="mu_i = k theta_i (paper) or the pair mean k (theta_i + theta_j)/2"),
    },
    "body_force": {
        "g": Key("floatlist", None, doc="body force per unit mass [m/s^2], one entry per dimension"),
    },
    "output": {
        "t_end": Key("float", REQUIRED, positive=True, doc="end time [s]"),
        "times": Key("floatlist", (), doc="times of profile and snapshot output [s]"),
        "snapshots": Key("bool", True, doc="write particle snapshots at the output times"),
        "progress_interval": Key("float", 5.0, nonnegative=True, doc="seconds between progress lines (0: none)"),
    },
    "checks": {
        "every": Key("int", 20, lo=1, hi=2 ** 40, doc="steps between run-time checks"),
        "theta_change": Key("float", 0.5, positive=True,
                            doc="largest accepted |theta - theta0| / theta0 of a fluid particle"),
        "energy": Key("bool", True, doc="stop when the fluid's kinetic energy exceeds the scene's bound"),
    },
}


def _float(key, value):
    try:
        return float(value)
    except OverflowError:
        raise ConfigError(key, "number too large") from None


def _finite(key, value, what):
    """A derived quantity must be a finite, positive float: else the key is out of range."""
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(key, f"out of range: {what} = {value!r}")
    return value


def _typed(key, spec, value):
    """Check one value against its spec and return it converted."""
    k = spec.kind
    if k == "float_or_auto":
        if value == "auto":
            return value
        k = "float"
    if k == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(key, f"expected a number, got {value!r}")
        value = _float(key, value)
        if not math.isfinite(value):
            raise ConfigError(key, f"must be finite, got {value!r}")
    elif k == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(key, f"expected an integer, got {value!r}")
    elif k == "str":
        if not isinstance(value, str):
            raise ConfigError(key, f"expected a string, got {value!r}")
    elif k == "bool":
        if not isinstance(value, bool):
            raise ConfigError(key, f"expected true or false, got {value!r}")
    elif k == "floatlist":
        if not isinstance(value, (list, tuple)):
            raise ConfigError(key, f"expected a list of numbers, got {value!r}")
        out = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(_float(key, v)):
                raise ConfigError(key, f"expected a list of finite numbers, got {value!r}")
            out.append(float(v))
        return tuple(out)
    if spec.choices and value not in spec.choices:
        raise ConfigError(key, f"must be one of {', '.join(map(str, spec.choices))}, got {value!r}")
    if spec.positive and not value > 0:
        raise ConfigError(key, f"must be positive, got {value!r}")
    if spec.nonnegative and not value >= 0:
        raise ConfigError(key, f"must not be negative, got {value!r}")
    if spec.lo is not None and not value >= spec.lo:
        raise ConfigError(key, f"must be at least {spec.lo:g}, got {value!r}")
    if spec.hi is not None and not value < spec.hi:
        raise ConfigError(key, f"must be below {spec.hi:g}, got {value!r}")
    return value


def parse_value(text):
    """A --set value: TOML syntax (numbers, true/false, lists, quoted strings) or a bare string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(raw, overrides):
    """Apply ``section.key=value`` strings to a raw run-file dict (in place)."""
    for item in overrides:
        if "=" not in item:
            raise ConfigError(item, "an override must look like section.key=value")
        name, text = item.split("=", 1)
        parts = name.strip().split(".")
        if len(parts) != 2 or not all(parts):
            raise ConfigError(name, "an override key must look like section.key")
        section, key = parts
        if not isinstance(raw.get(section, {}), dict):
            raise ConfigError(section, "expected a table")
        raw.setdefault(section, {})[key] = parse_value(text.strip())
    return raw


def validate(raw):
    """Return {section: {key: value}} with defaults filled in, or raise ConfigError."""
    if not isinstance(raw, dict):
        raise ConfigError("<file>", "not a TOML table")
    out = {}
    for section in raw:
        if section not in SCHEMA:
            raise ConfigError(section, f"unknown section (known: {', '.join(SCHEMA)})")
        if not isinstance(raw[section], dict):
            raise ConfigError(section, "expected a table [" + section + "]")
    for section, keys in SCHEMA.items():
        given = raw.get(section, {})
        for key in given:
            if key not in keys:
                raise ConfigError(f"{section}.{key}", f"unknown key (known in [{section}]: {', '.join(keys)})")
        out[section] = {}
        for key, spec in keys.items():
            name = f"{section}.{key}"
            if key in given:
                out[section][key] = _typed(name, spec, given[key])
            elif spec.default is REQUIRED:
                raise ConfigError(name, "missing (required)")
            else:
                out[section][key] = spec.default
    return out


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
    pressure: bool = True
    viscosity: bool = True
    limits: dict = field(default_factory=dict)

    @property
    def nu(self):
        """Kinematic viscosity k theta0 / rho_s (Eq. (5) in a uniform state)."""
        return self.k * self.theta0 / self.rho_s

    @property
    def n_particles(self):
        """Fluid and wall particles of the lattice."""
        return (self.Nx + (2 * self.layers if self.scene.walls else 0)) * self.Ny * self.Nz

    @property
    def spacing(self):
        """Lattice step per dimension [m]."""
        return (self.dx, self.dy, self.dz)[:self.dim]

    @property
    def velocity_scale(self):
        """The scene's velocity scale [m/s]: errors are normalised by it."""
        return self.scene.velocity_scale(self)

    @property
    def reynolds(self):
        return self.velocity_scale * self.L / self.nu if self.nu > 0 else math.inf

    def get(self, dotted):
        section, key = dotted.split(".")
        return self.values[section][key]


def build(raw, text):
    """Validate a raw run-file dict and derive the run's quantities."""
    v = validate(raw)
    dom, mat, walls, num, out = v["domain"], v["material"], v["walls"], v["numerics"], v["output"]
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
    scene = get_scene(v["scene"]["name"])
    terms = v["terms"]
    kern = get_kernel(num["kernel"], dim)
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
    g = v["body_force"]["g"]
    if g is None:
        g = (0.0,) * dim
    if len(g) != dim:
        raise ConfigError("body_force.g", f"needs {dim} components, got {len(g)}")
    if scene.terms.body_force and not any(g):
        raise ConfigError("body_force.g", f"the {scene.name} scene is driven by a body force; give a non-zero g")
    theta0 = mat["theta0"]
    cfg = RunConfig(
        values=v, text=text, dim=dim, L=L, Ly=Ly, Lz=Lz, Nx=Nx, Ny=Ny, Nz=Nz, dx=dx, dy=dy, dz=dz, h=h,
        layers=layers if scene.walls else 0,
        mass=mat["rho_s"] * theta0 * dx * dy * (dz if dim == 3 else 1.0), rho_s=mat["rho_s"], theta0=theta0,
        k=mat["k"], G_a=mat["G_a"], G_b=mat["G_b"], V_w=walls["V_w"], beta_max=walls["beta_max"],
        kernel=num["kernel"], dt=0.0, dt_auto=False, t_end=out["t_end"], nsteps=0, output_times=(),
        integrator=num["integrator"], g=tuple(g), scene=scene,
        pressure=scene.terms.pressure if terms["pressure"] is None else terms["pressure"],
        viscosity=scene.terms.viscosity if terms["viscosity"] is None else terms["viscosity"])
    try:
        # the run's limits at theta_0 (parsph.limits): the refusal of a fixed dt and the first automatic dt
        limits = dict(stability.run_limits(cfg, theta0, cfg.velocity_scale, math.sqrt(sum(x * x for x in g))))
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
    return replace(cfg, dt=dt, dt_auto=auto, nsteps=nsteps, output_times=times, limits=limits)


def load(path, overrides=()):
    """Read, override and validate a run file."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise ConfigError("<file>", f"cannot read {path}: {e.strerror}") from None
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ConfigError("<file>", f"{path} is not valid TOML: {e}") from None
    apply_overrides(raw, overrides)
    return build(raw, dumps(raw))


def loads(text, overrides=()):
    """Validate a run file given as a TOML string."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError("<file>", f"not valid TOML: {e}") from None
    apply_overrides(raw, overrides)
    return build(raw, dumps(raw))


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(type(v))


def dumps(raw):
    """Write a raw run-file dict back as TOML (tables of scalars and lists only)."""
    lines = []
    for section, keys in raw.items():
        if not isinstance(keys, dict):
            continue
        lines.append(f"[{section}]")
        for key, value in keys.items():
            try:
                lines.append(f"{key} = {_toml_value(value)}")
            except TypeError:
                raise ConfigError(f"{section}.{key}", f"unsupported value {value!r}") from None
        lines.append("")
    return "\n".join(lines)
