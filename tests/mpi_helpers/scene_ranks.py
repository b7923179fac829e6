"""The scenes of test_mpi_scenes.py in short boxes, and their comparison across rank and thread counts.

    mpirun -n 2 python tests/mpi_helpers/scene_ranks.py SCENE

As a script (NUMBA_NUM_THREADS >= 2 for the job): runs SCENE on COMM_WORLD with
2 numba threads per rank, then on rank 0 the same on COMM_SELF with 1 thread, and
prints one line ``verdict {json}`` on rank 0. As a module: the cases and the
helpers the tests use (only the solver's public API).
"""
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from parsph.setup import config
from parsph.sph.particles import GRAIN
from parsph.simulation.solver import Simulation

ROOT = Path(__file__).resolve().parents[2]
DX = 2e-4
ROWS = 12  # y rows: the smallest box whose 3 slabs hold their ghost rows (slabs.min_length(3) = 2.4 mm)

# scene -> (run file, overrides, random velocity of the fluid [m/s], steps). The body forces along y
# (settling: a column that settles while it is driven along y) move the fluid across slab edges.
CASES = {
    "couette_3d": ("couette_3d.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                       f"domain.Lz={6 * DX!r}"], 0.05, 60),
    "periodic_box": ("periodic_box.toml", ["domain.L=0.0032", "numerics.Nx=16", f"domain.Ly={ROWS * DX!r}",
                                           "scene.amplitude=0.5", "terms.pressure=true",
                                           "checks.energy=false"], 0.1, 80),
    "settling": ("settling.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                   "body_force.g=[-30.0, 50.0]", "numerics.dt=5e-5"], 0.05, 80),
    "poiseuille": ("poiseuille.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                       "body_force.g=[0.0, 500.0]"], 0.05, 100),
    # in a gas: a stream along y through a falling box (Gidaspow, implicit drag), and a stream of water along
    # y through the settling column, which it shears against the walls (Wen & Yu, explicit drag)
    "box_gas": ("periodic_box.toml", ["domain.L=0.0032", "numerics.Nx=16", f"domain.Ly={ROWS * DX!r}",
                                      "scene.amplitude=0.5", "terms.pressure=true", 'gas.drag="gidaspow"',
                                      "gas.velocity=[0.0, 0.3]", "gas.rho=1000.0", "gas.mu=1e-3",
                                      "body_force.g=[-9.81, 0.0]"], 0.1, 80),
    "settling_gas": ("settling.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                       'gas.drag="wen_yu"', "gas.velocity=[0.0, 0.5]", "gas.rho=1000.0",
                                       "gas.mu=1e-3", 'numerics.drag_update="explicit"', "numerics.dt=5e-5"],
                     0.05, 80),
    # the layer scenes: a layer on the floor under clear water up to a lid, its floor walls holding the end
    # state's theta and mass (no uniform mass), a free top with empty lattice above it
    "sedimentation": ("sedimentation.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                             "scene.height=0.002", "numerics.dt=5e-5"], 0.1, 80),
    "fluidized_bed": ("fluidized_bed.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                             "scene.height=0.0016", "numerics.dt=5e-5"], 0.1, 80),
    # the same in the solved gas: the deposits summed over the ranks, the pressure solved on every rank
    "sedimentation_solved": ("sedimentation.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                                    "scene.height=0.002", "numerics.dt=5e-5", 'gas.flow="solved"'],
                             0.1, 80),
    "fluidized_bed_solved": ("fluidized_bed.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                                    "scene.height=0.0016", "numerics.dt=5e-5", 'gas.flow="solved"'],
                             0.1, 80),
    # and between side walls (walls.sides): the wall rows beyond L_y span the ring's seam, the grid's y closed
    "fluidized_bed_sides": ("fluidized_bed.toml", ["domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                                   "scene.height=0.0016", "numerics.dt=5e-5", 'gas.flow="solved"',
                                                   "walls.sides=true"], 0.1, 80),
    # in 3-D: the grid's z periodic (3 cells of 2 dx), its faces across z, the deposit trilinear; a slip-dependent
    # closure (its rates at the 3-D slip toward the last solve's flux)
    "fluidized_bed_solved_3d": ("fluidized_bed.toml", ["scene.dim=3", "body_force.g=[-9.81, 0.0, 0.0]",
                                                       "domain.L=0.004", "numerics.Nx=20", f"domain.Ly={ROWS * DX!r}",
                                                       f"domain.Lz={6 * DX!r}", "scene.height=0.0016",
                                                       "numerics.dt=5e-5", 'gas.flow="solved"', "gas.cell=0.0004",
                                                       'gas.drag="gidaspow"'],
                                0.3, 80),
}
FIELDS = ("gid", "kind", "mass", "pos", "vel", "acc", "rho", "theta")


def load(scene, *extra):
    """The scene's short case for its number of steps (dt "auto": as many steps of the first dt)."""
    toml, over, _, steps = CASES[scene]
    first = config.load(ROOT / "run" / toml, [*over, "output.times=[]", "output.t_end=1.0"])
    return config.load(ROOT / "run" / toml, [*over, "output.times=[]", f"output.t_end={steps * first.dt!r}",
                                             *extra])


def perturb(sim, amplitude, seed=7):
    """Add a random velocity to the owned fluid particles: a function of the global id alone (one draw per
    lattice site, the empty sites above a layer's top included)."""
    ps, n, cfg = sim.ps, sim.ps.n_own, sim.cfg
    sites = (cfg.Nx + 2 * cfg.layers) * (cfg.Ny + cfg.side_layers) * cfg.Nz
    kick = np.random.default_rng(seed).normal(0.0, amplitude, (sites, cfg.dim))
    fluid = ps.kind[:n] == GRAIN
    ps.vel[:n][fluid] += kick[ps.gid[:n][fluid]]


class Moves:
    """An observer: list builds, and the particles that left this rank at the builds after the first."""

    def __init__(self):
        self.rebuilds, self.left, self.owned = 0, 0, None

    def __call__(self, sim):
        if sim.rebuilds != self.rebuilds:
            ids = np.sort(sim.particles()["id"])
            if self.owned is not None:
                self.left += int(np.setdiff1d(self.owned, ids, assume_unique=True).size)
            self.owned, self.rebuilds = ids, sim.rebuilds


def run_scene(cfg, comm, amplitude, state_in=None, output=None):
    """A run from the scene's start (perturbed) or from ``state_in`` (a restart); returns (sim, Moves)."""
    sim = Simulation(cfg, comm, state=state_in)
    if state_in is None:
        perturb(sim, amplitude)
    moves = Moves()
    sim.run(output=output, observe=moves)
    return sim, moves


def state(sim):
    """Every particle's state and rates on rank 0, sorted by global id (None elsewhere)."""
    ps, n = sim.ps, sim.ps.n_own
    parts = sim.comm.gather({k: getattr(ps, k)[:n].copy() for k in FIELDS}, root=0)
    if parts is None:
        return None
    out = {k: np.concatenate([p[k] for p in parts]) for k in FIELDS}
    order = np.argsort(out["gid"], kind="stable")
    return {k: v[order] for k, v in out.items()}


def differences(a, b):
    """{field: max |a - b|} of the fields that differ at all (inf: different shapes); {} when bit for bit."""
    out = {}
    for k in FIELDS:
        if a[k].shape != b[k].shape:
            out[k] = math.inf
        elif not np.array_equal(a[k], b[k]):
            out[k] = float(np.max(np.abs(a[k].astype(float) - b[k].astype(float))))
    return out


def idle_wait(comm):
    """Wait for rank 0 without busy-polling (the other ranks share the cores with its reference run)."""
    req = comm.Ibarrier()
    while not req.Test():
        time.sleep(0.005)


def main(argv):
    import numba
    from mpi4py import MPI
    scene = argv[0]
    comm = MPI.COMM_WORLD
    cfg = load(scene)
    amplitude = CASES[scene][2]
    numba.set_num_threads(2)
    threads = numba.get_num_threads()
    sim, moves = run_scene(cfg, comm, amplitude)
    par = state(sim)
    rebuilt = comm.allreduce(moves.rebuilds, op=MPI.MIN)
    migrated = comm.allreduce(moves.left)
    if comm.rank == 0:
        numba.set_num_threads(1)
        one, _ = run_scene(cfg, MPI.COMM_SELF, amplitude)
        ref = state(one)
        verdict = {"threads": [threads, numba.get_num_threads()], "diff": differences(par, ref),
                   "clock_equal": (one.step, one.t, one.dt) == (sim.step, sim.t, sim.dt),
                   "n": [len(par["gid"]), len(ref["gid"])], "rebuilt": rebuilt, "migrated": migrated}
        sys.stdout.write("verdict " + json.dumps(verdict) + "\n")
        sys.stdout.flush()
    idle_wait(comm)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
