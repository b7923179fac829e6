"""Studies of the gas's drag on the periodic box (docs/stability.md, "Drag"; docs/validation.md): the settling
speed against theta0, the stability of each drag update across dt/tau, the error against CPU time, and the
cost of a step with drag against one without.

The box is uniform (Eq. (5)'s sums vanish but for round-off), so each run has an exact reference
(docs/physics.md's references 1 and 2, :mod:`parsph.physics.gas_references`) and measures the time
integration of the drag alone. Glass (2000 kg/m^3) in water; tau is set through the grain diameter.
"""
import math
import time

import numpy as np

from parsph.errors import GuardError
from parsph.physics import gas_references as refs
from parsph.setup import config
from parsph.sph.particles import GRAIN

RHO_S, RHO_G, MU, G = 2000.0, 1000.0, 1.0e-3, 9.81
STREAM = 0.01  # the stream's speed [m/s]


def box_config(run_dir, *sets, nx=8):
    """The periodic box of ``run_dir``/periodic_box.toml, nx columns of 0.2 mm, no wave, mu_s = 0.01 theta,
    glass in water, with ``sets`` (``section.key=value``) on top."""
    return config.load(run_dir / "periodic_box.toml",
                       [f"numerics.Nx={nx}", f"domain.L={nx * 2e-4!r}", "domain.Ly=0.0016", "output.times=[]",
                        "scene.amplitude=0.0", "material.k=0.01", f"material.rho_s={RHO_S}", f"gas.rho={RHO_G}",
                        f"gas.mu={MU}", *sets])


def diameter_for(tau, theta0):
    """The grain diameter [m] whose Stokes relaxation time in a stream is ``tau`` [s] at theta0."""
    return math.sqrt(18.0 * MU * tau / (RHO_S * (1.0 - theta0) ** 3.65))


def _fluid_mean(sim, field, axis):
    ps = sim.ps
    f = ps.kind[:ps.n_own] == GRAIN
    return float(getattr(ps, field)[:ps.n_own][f][:, axis].mean())


def relaxation_run(run_dir, dt_over_tau, update, integrator="paper", dt=1e-4, theta0=0.35, periods=5.0,
                   min_steps=200, comm=None):
    """Drag relaxation (Stokes, a stream along y) at dt/tau: {"error": |v - u (1 - exp(-t/tau))| / u at
    t_end = max(periods tau, min_steps dt), "steps", "cpu" [s], "failed": the guard's message or ""}.
    A fixed dt above the limit is allowed (``numerics.allow_unstable_dt``): the guards must catch it."""
    from mpi4py import MPI
    from parsph.simulation.solver import Simulation
    tau = dt / dt_over_tau
    t_end = max(periods * tau, min_steps * dt)
    cfg = box_config(run_dir, 'gas.drag="stokes"', f"gas.velocity=[0.0, {STREAM}]",
                     f"material.d={diameter_for(tau, theta0)!r}", f"material.theta0={theta0}",
                     f'numerics.drag_update="{update}"', f'numerics.integrator="{integrator}"',
                     f"numerics.dt={dt!r}", "numerics.allow_unstable_dt=true", f"output.t_end={t_end!r}")
    sim = Simulation(cfg, comm or MPI.COMM_SELF)
    t0 = time.process_time()
    failed = ""
    try:
        sim.take_steps(cfg.nsteps)
    except GuardError as e:
        failed = str(e)
    cpu = time.process_time() - t0
    exact = STREAM * -math.expm1(-sim.t / tau)
    err = abs(_fluid_mean(sim, "vel", 1) - exact) / STREAM if not failed else math.inf
    return {"dt_over_tau": dt_over_tau, "update": update, "integrator": integrator, "error": err,
            "steps": sim.step, "cpu": cpu, "failed": failed}


def auto_run(run_dir, tau, update, t_end=0.01, theta0=0.35, comm=None):
    """The relaxation of :func:`relaxation_run` with ``dt = "auto"`` to ``t_end`` at relaxation time ``tau``:
    {"tau", "update", "steps", "dt_last", "error", "cpu"}; the explicit drag's limit keeps dt <= tau."""
    from mpi4py import MPI
    from parsph.simulation.solver import Simulation
    cfg = box_config(run_dir, 'gas.drag="stokes"', f"gas.velocity=[0.0, {STREAM}]",
                     f"material.d={diameter_for(tau, theta0)!r}", f"material.theta0={theta0}",
                     f'numerics.drag_update="{update}"', 'numerics.dt="auto"', f"output.t_end={t_end!r}")
    sim = Simulation(cfg, comm or MPI.COMM_SELF)
    t0 = time.process_time()
    sim.run()
    cpu = time.process_time() - t0
    exact = STREAM * -math.expm1(-sim.t / tau)
    return {"tau": tau, "update": update, "steps": sim.step, "dt_last": sim.dt,
            "error": abs(_fluid_mean(sim, "vel", 1) - exact) / STREAM, "cpu": cpu}


def settling_run(run_dir, theta0, closure, update="implicit", comm=None):
    """Hindered settling of a uniform suspension (a closed column, U = 0) with grains of 0.3 mm: the mean
    v_x after 12 relaxation times against the closure's root, {"theta0", "v", "root", "u_t"} [m/s]."""
    from mpi4py import MPI
    from parsph.simulation.solver import Simulation
    ph = refs.Phases(RHO_S, RHO_G, MU, 3.0e-4, G, closure)
    tau = refs.settling_relaxation_time(theta0, ph)
    dt = min(2e-4, tau / 5)
    cfg = box_config(run_dir, f'gas.drag="{closure}"', 'gas.flow="column"', f"material.theta0={theta0}",
                     "body_force.g=[-9.81, 0.0]", f'numerics.drag_update="{update}"', f"numerics.dt={dt!r}",
                     f"output.t_end={12 * tau!r}")
    sim = Simulation(cfg, comm or MPI.COMM_SELF)
    sim.take_steps(cfg.nsteps)
    return {"theta0": theta0, "closure": closure, "v": _fluid_mean(sim, "vel", 0),
            "root": refs.hindered_settling_velocity(theta0, ph), "u_t": ph.u_t}


def step_cost(run_dir, drag, update="implicit", nx=50, steps=400, comm=None):
    """CPU seconds a step of the periodic box (nx x nx/5, the wave of 0.1 m/s, pressure on) with the gas's
    ``drag`` ("none" or a closure; a stream of 0.05 m/s across the wave) after a first block of steps."""
    from mpi4py import MPI
    from parsph.simulation.solver import Simulation
    sets = [f"numerics.Nx={nx}", f"domain.L={nx * 2e-4!r}", f"domain.Ly={nx * 2e-4 / 5!r}", "output.times=[]",
            "terms.pressure=true", "scene.amplitude=0.1", "numerics.dt=1e-5", "output.t_end=1.0"]
    if drag != "none":
        sets += [f'gas.drag="{drag}"', "gas.velocity=[0.05, 0.0]", f"gas.rho={RHO_G}", f"gas.mu={MU}",
                 f'numerics.drag_update="{update}"']
    sim = Simulation(config.load(run_dir / "periodic_box.toml", sets), comm or MPI.COMM_SELF)
    sim.take_steps(50)
    t0 = time.process_time()
    sim.take_steps(steps)
    return (time.process_time() - t0) / steps


def settling_plot(rows, path):
    """The settling speed against theta0 over Richardson & Zaki's line and the Wen & Yu root (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    th = np.linspace(0.0, 0.6, 121)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(th, (1 - th) ** 4.65, "k-", lw=1, label="Richardson & Zaki, $(1-\\theta_0)^{4.65}$ (Stokes)")
    wy = [r for r in rows if r["closure"] == "wen_yu"]
    if wy:
        ph = refs.Phases(RHO_S, RHO_G, MU, 3.0e-4, G, "wen_yu")
        tt = np.linspace(0.02, 0.6, 59)
        ax.plot(tt, [-refs.hindered_settling_velocity(t, ph) / ph.u_t for t in tt], "k--", lw=1,
                label="Wen & Yu root")
    for closure, mark in (("stokes", "o"), ("wen_yu", "s")):
        pts = [r for r in rows if r["closure"] == closure]
        if pts:
            ax.plot([r["theta0"] for r in pts], [-r["v"] / r["u_t"] for r in pts], mark, mfc="none",
                    label=f"parsph, {closure.replace('_', ' & ').title()}")
    ax.set_xlabel("$\\theta_0$")
    ax.set_ylabel("settling speed / $u_t$")
    ax.set_title("Hindered settling: glass (0.3 mm) in water, periodic box")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
