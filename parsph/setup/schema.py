"""The run file's schema: every section and key with its type, default and bounds, and the validation of a
raw run-file dict against it (:func:`validate`). Every problem raises :class:`ConfigError` naming the key.

The key list with units is in docs/running.md ("Run-file keys").
"""
from dataclasses import dataclass
import math

from parsph.errors import ConfigError
from parsph.sph.integrators import INTEGRATORS
from parsph.physics.closures import G_A, G_B
from parsph.physics.kernels import KERNEL_NAMES
from parsph.physics.drag import MODELS
from .scenes import SCENE_NAMES

REQUIRED = object()
DRAG_CLOSURES = ("none",) + tuple(MODELS)
DRAG_UPDATES = ("explicit", "implicit")


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
        "height": Key("float", None, positive=True,
                      doc="sedimentation, fluidized_bed: the layer's initial height H0 on the floor [m] "
                          "(default L / 2)"),
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
        "G_a": Key("float", G_A, doc="G = 10^(G_a theta + G_b) [Pa]"),
        "G_b": Key("float", G_B, doc="G = 10^(G_a theta + G_b) [Pa]"),
        "d": Key("float", 3.0e-4, positive=True, doc="grain diameter [m] (the gas's drag; Table 1's d_s)"),
        "theta_max": Key("float", None, positive=True, hi=1.0,
                         doc="packing limit: a frictional pressure p_f = 0.05 Pa (theta - theta_min)^2 / "
                             "(theta_max - theta)^5 (Johnson & Jackson 1987) added to the consistent form's p; "
                             "none by default"),
        "theta_min": Key("float", None, positive=True, hi=1.0,
                         doc="with theta_max: where the frictional pressure starts (default 0.5)"),
    },
    "walls": {
        "V_w": Key("float", 1.0, doc="velocity of the plate at x = L along +y [m/s]"),
        "layers": Key("int", 0, nonnegative=True, hi=1000, doc="wall particle layers (0: the fewest covering 2h)"),
        "beta_max": Key("float", 1.5, lo=1.0, doc="cap of the ghost velocity factor (Morris 1997)"),
        "sides": Key("bool", False, doc="side walls at y = 0 and y = L_y instead of the periodic strip (the layer "
                                        "and bed scenes): walls.layers rows of wall particles beyond y = L_y"),
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
        "drag_update": Key("str", "implicit", choices=DRAG_UPDATES,
                           doc="the gas's drag in the step: explicit (Eq. (7) as it is; stable for dt < 2 tau) "
                               "or implicit in v with beta frozen over the step (any dt)"),
        "viscosity_form": Key("str", "paper", choices=("paper", "symmetric"),
                              doc="mu_i = k theta_i (paper) or the pair mean k (theta_i + theta_j)/2"),
    },
    "body_force": {
        "g": Key("floatlist", None, doc="body force per unit mass [m/s^2], one entry per dimension"),
    },
    "gas": {
        "drag": Key("str", "none", choices=DRAG_CLOSURES,
                    doc="the gas's drag on the solids: none (the paper's case), or its closure"),
        "rho": Key("float", None, nonnegative=True, doc="gas density [kg/m^3] (default 1.2, air)"),
        "mu": Key("float", None, positive=True, doc="gas viscosity [Pa s] (default 1.8e-5, air)"),
        "flow": Key("str", None, choices=("stream", "column", "solved"),
                    doc="the gas velocity: a given stream, a column fed at superficial velocity U against "
                        "gravity (one-dimensional in the mean), or solved: the gas pressure on a grid, fed at U "
                        "through the floor (default stream)"),
        "velocity": Key("floatlist", None, doc="stream: the gas velocity, one entry per dimension [m/s] "
                                               "(default at rest)"),
        "U": Key("float", None, nonnegative=True,
                 doc="column: superficial gas velocity along the axis opposite to gravity [m/s] (default 0)"),
        "cell": Key("float", None, positive=True,
                    doc="solved: the grid's cell size [m] (default 4 dx; adjusted to tile the box)"),
        "K_max": Key("float", None, positive=True,
                     doc="solved: the cap of the gas's permeability K = eps^2 / beta in the pressure solve "
                         "[m^2/(Pa s)] (default 1000 K(theta0): a void carries 2 kappa U / (1 + kappa), within "
                         "0.1% of 2 U)"),
        "jet": Key("floatlist", None,
                   doc="solved, with walls: [y0, y1, U_jet] or [y0, y1, U_jet, t_off]: the floor faces whose "
                       "centres lie in y0 <= y < y1 fed at U_jet [m/s] instead of gas.U (an orifice; a profile "
                       "U(y)), until t_off [s] where given (an injected bubble), then at gas.U"),
        "solve_every": Key("int", None, lo=1, hi=10 ** 6,
                           doc="solved: the pressure solved every n steps, its flux interpolated to the particles "
                               "every step (default 1)"),
    },
    "output": {
        "t_end": Key("float", REQUIRED, positive=True, doc="end time [s]"),
        "times": Key("floatlist", (), doc="times of profile and snapshot output [s]"),
        "snapshots": Key("bool", True, doc="write particle snapshots at the output times"),
        "progress_interval": Key("float", 5.0, nonnegative=True, doc="seconds between progress lines (0: none)"),
    },
    "perturbation": {
        "amplitude": Key("float", 0.0, doc="the fluid particles displaced along x (gravity's axis in a bed) by "
                                           "amplitude sin(2 pi x / wavelength) at the start [m] (0: none)"),
        "wavelength": Key("float", None, positive=True,
                          doc="the perturbation's wavelength [m] (with walls any; x periodic: L / wavelength whole)"),
        "wavelength_y": Key("float", None, positive=True,
                            doc="the displacement times cos(2 pi y / wavelength_y) across the periodic y (a 2-D "
                                "seed: bubbles in a bed) [m] (Ly / wavelength_y whole; none: uniform across)"),
    },
    "checks": {
        "every": Key("int", 20, lo=1, hi=2 ** 40, doc="steps between run-time checks"),
        "theta_change": Key("float", 0.5, positive=True,
                            doc="largest accepted |theta - theta0| / theta0 of a fluid particle"),
        "energy": Key("bool", True, doc="stop when the fluid's kinetic energy exceeds the scene's bound"),
        "bubble_theta": Key("float", 0.2, positive=True, hi=1.0,
                            doc="a bubbling bed's bubbles: the solved gas's cells with theta below this, connected"),
        "settle": Key("float", None, nonnegative=True,
                      doc="a bubbling bed's measures are averaged over the outputs from this time on [s] "
                          "(default: a third of output.t_end)"),
    },
}


def _float(key, value):
    try:
        return float(value)
    except OverflowError:
        raise ConfigError(key, "number too large") from None


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
