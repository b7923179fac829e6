"""The gas of a run, from its validated run file (docs/physics.md, "The solid phase in a gas" and "The solved
gas"): :class:`Gas`, what every gas key means once checked against the others (:func:`gas_of`), and the solved
gas's grid against the box (:func:`solved_grid`). Every problem raises :class:`ConfigError` naming the key.
"""
from dataclasses import dataclass, replace

from parsph.errors import ConfigError
from parsph.physics import drag as closures_drag
from .scenes import get_scene

AIR_RHO, AIR_MU = 1.2, 1.8e-5  # the gas's defaults: air at 20 C [kg/m^3], [Pa s]


@dataclass(frozen=True)
class Gas:
    """The gas the solids are in (docs/physics.md, "The solid phase in a gas"): its closure and the gas velocity.

    A stream has the constant velocity ``velocity``; a column is fed at superficial velocity ``U`` along
    the axis ``axis`` opposite to gravity (``sign``: +1 where that is +axis), its gas velocity per
    particle ``(U - theta v.e) / eps`` along e."""
    closure: str       # "stokes", "wen_yu", "gidaspow"
    model: int         # parsph.physics.drag.MODELS[closure]
    rho: float         # [kg/m^3]
    mu: float          # [Pa s]
    d: float           # grain diameter [m]
    flow: str          # "stream", "column" or "solved"
    velocity: tuple    # stream: the gas velocity per dimension [m/s] (column: zeros)
    U: float           # column, solved: superficial velocity [m/s] (fed through the floor)
    axis: int          # column, solved: the axis of gravity (-1 for a stream)
    sign: float        # column, solved: e = sign * unit(axis)
    implicit: bool     # numerics.drag_update
    cell: float = 0.0         # solved: the grid's cell size [m]
    jet: tuple = ()           # solved: (y0, y1, U_jet) fed through the floor there instead of U
    jet_until: float = float("inf")  # solved: the time the jet stops [s] (then U everywhere)
    K_max: float = 0.0        # solved: the cap of K in the pressure solve [m^2/(Pa s)]
    solve_every: int = 1      # solved: steps between pressure solves

    @property
    def column(self):
        """The column's closure: the gas velocity per particle from U (1-D in the mean)."""
        return self.flow == "column"

    @property
    def solved(self):
        """The gas pressure solved on a grid (:mod:`parsph.gas`)."""
        return self.flow == "solved"

    @property
    def fed(self):
        """Fed at U along the axis opposite to gravity: a column, by its closure or solved."""
        return self.flow in ("column", "solved")


def gas_of(v, dim, g, rho_s):
    """The run's Gas, or None with gas.drag = "none" (then no other gas key may be given)."""
    gas = v["gas"]
    given = [key for key in ("rho", "mu", "flow", "velocity", "U", "cell", "K_max", "solve_every", "jet")
             if gas[key] is not None]
    if gas["drag"] == "none":
        if given:
            raise ConfigError(f"gas.{given[0]}", 'has no effect with gas.drag = "none": give gas.drag '
                              f'({", ".join(closures_drag.MODELS)})')
        return None
    d = v["material"]["d"]
    if not d * d > 0:
        raise ConfigError("material.d", f"{d:g} m is too small: the drag divides by d^2, which is 0 in floating point")
    rho = AIR_RHO if gas["rho"] is None else gas["rho"]
    mu = AIR_MU if gas["mu"] is None else gas["mu"]
    if not rho < rho_s:
        raise ConfigError("gas.rho", f"{rho:g} kg/m^3 is not below the solids' density material.rho_s = "
                          f"{rho_s:g} kg/m^3: the grains would not sink in it")
    flow = gas["flow"] or "stream"
    velocity, U, axis, sign = (0.0,) * dim, 0.0, -1, 0.0
    if flow == "stream":
        if gas["U"] is not None:
            raise ConfigError("gas.U", 'is the superficial velocity of a column: give gas.flow = "column", '
                              "or the stream's gas.velocity")
        if gas["velocity"] is not None:
            velocity = gas["velocity"]
            if len(velocity) != dim:
                raise ConfigError("gas.velocity", f"needs {dim} components (one per dimension), got {len(velocity)}")
    else:
        if gas["velocity"] is not None:
            raise ConfigError("gas.velocity", "is a stream's velocity: a column's gas velocity follows from "
                              "gas.U and the solids' flux")
        axes = [k for k in range(dim) if g[k] != 0.0]
        if not axes:
            raise ConfigError("body_force.g", "a gas column (gas.flow = \"column\") needs gravity: give a "
                              "non-zero body_force.g")
        if len(axes) > 1:
            raise ConfigError("body_force.g", f"a gas column needs gravity along one axis, got {list(g)}")
        axis = axes[0]
        sign = -1.0 if g[axis] > 0 else 1.0
        U = gas["U"] or 0.0
    solved = _solved_keys(v, dim, g, flow, gas)
    return Gas(gas["drag"], closures_drag.MODELS[gas["drag"]], float(rho), float(mu),
               float(d), flow, tuple(float(x) for x in velocity), float(U), axis, sign,
               v["numerics"]["drag_update"] == "implicit", **solved)


# the solved gas's default cell: 4 dx (1.6 times the cubic spline's support 2h at h = 1.25 dx). A grid finer
# than the solids pressure's kernel lets particle-scale voids channel the gas: in run/fluidized_bed.toml the
# rms of v_y reaches 2.5e-11 m/s by 2 s with cells of 2 dx, 4e-4 m/s with cells of dx; with 4 dx it stays at
# round-off (docs/validation.md, "The solved gas")
CELL_DX = 4.0
K_MAX_FACTOR = 1000.0  # the default cap of K: this times K(theta0) (docs/physics.md, reference 6)


def _solved_keys(v, dim, g, flow, gas):
    """The solved gas's grid keys (cell, K_max, solve_every); they belong to it alone. K_max's default is
    left 0 here and set from K(theta0) by :func:`solved_cap`."""
    if flow != "solved":
        for key in ("cell", "K_max", "solve_every", "jet"):
            if gas[key] is not None:
                raise ConfigError(f"gas.{key}", f'belongs to the solved gas: give gas.flow = "solved" (not "{flow}")')
        return {}
    scene = get_scene(v["scene"]["name"])
    if not (g[0] < 0.0 and all(c == 0.0 for c in g[1:])):
        where = "through the floor at x = 0" if scene.walls else "along the periodic x at the mean flux gas.U"
        raise ConfigError("body_force.g", f"the solved gas is fed {where}: give gravity along -x, got {list(g)}")
    jet, jet_until = (), float("inf")
    if gas["jet"] is not None:
        if not scene.walls:
            raise ConfigError("gas.jet", f"feeds the floor; the {scene.name} scene has none (x is periodic)")
        if len(gas["jet"]) not in (3, 4):
            raise ConfigError("gas.jet", f"is [y0, y1, U_jet] or [y0, y1, U_jet, t_off], got {len(gas['jet'])} "
                              "numbers")
        y0, y1, U_jet = (float(x) for x in gas["jet"][:3])
        if len(gas["jet"]) == 4:
            jet_until = float(gas["jet"][3])
            if not jet_until > 0.0:
                raise ConfigError("gas.jet", f"t_off = {jet_until:g} s: the jet blows from t = 0 to t_off > 0")
        Ly = v["domain"]["Ly"] if v["domain"]["Ly"] is not None else v["domain"]["L"]
        if not 0.0 <= y0 < y1 <= Ly:
            raise ConfigError("gas.jet", f"needs 0 <= y0 < y1 <= domain.Ly = {Ly:g} m, got y0 = {y0:g}, y1 = {y1:g}")
        if not U_jet >= 0.0:
            raise ConfigError("gas.jet", f"U_jet = {U_jet:g} m/s: the floor feeds gas, U_jet >= 0")
        jet = (y0, y1, U_jet)
    return dict(cell=float(gas["cell"] or 0.0), K_max=float(gas["K_max"] or 0.0),
                solve_every=int(gas["solve_every"] or 1), jet=jet, jet_until=jet_until)


def solved_grid(gas, lat, walls):
    """The solved gas's cell size (default :data:`CELL_DX` dx) against the box, and its default cap K_max =
    :data:`K_MAX_FACTOR` K(theta0) where none is given."""
    Lx, Ly, dx = lat["L"], lat["Ly"], lat["dx"]
    Lz = lat["Lz"] if lat["dim"] == 3 else Ly
    cell = gas.cell or CELL_DX * dx
    nx_min = 2 if walls else 3  # a periodic axis needs 3 cells (a cell's two neighbours distinct)
    if not (cell <= Lx / nx_min * (1.0 + 1e-12) and cell <= min(Ly, Lz) / 3.0 * (1.0 + 1e-12)):
        box = f"{Lx:g} m x {Ly:g} m" + (f" x {Lz:g} m" if lat["dim"] == 3 else "")
        raise ConfigError("gas.cell", f"{cell:g} m leaves fewer than {nx_min} cells along x or 3 along a periodic "
                          f"y or z (the box is {box}: domain.L x domain.Ly" + (" x domain.Lz)" if lat["dim"] == 3
                                                                                else ")"))
    if lat["dim"] == 3 and (Lx / cell) * (Ly / cell) * (Lz / cell) > 200_000:
        raise ConfigError("gas.cell", f"{cell:g} m makes more than 200,000 cells in 3-D (the solve is one rank's "
                          "sparse direct solve)")
    if not (Lx / cell <= 4096 and Ly / cell <= 4096):
        raise ConfigError("gas.cell", f"{cell:g} m makes more than 4096 cells along an axis (the solve is one "
                          "rank's sparse direct solve)")
    return replace(gas, cell=float(cell))

