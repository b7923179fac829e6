"""Restart: ``parsph run CONFIG --restart OUTPUT`` continues from the last complete snapshot.

    .venv/bin/python -m pytest -q tests/test_restart.py
    mpirun -n 2 .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_restart.py

The serial tests launch ``parsph`` (and ``mpirun -n 2 parsph``) themselves and
are skipped inside an mpirun job; the one test marked ``mpi`` restarts in
process on COMM_WORLD (pytest-mpi, any rank count).

Case: the paper's run file on a short box (Ly = 0.0024 m, 672 particles).
Uninterrupted: t_end = 0.004 s, outputs at [0.002, 0.004]. First leg:
t_end = 0.002 s, output at [0.002]; then ``--restart`` with the uninterrupted
run's t_end and times. The restarted run must end bit for bit equal to the
uninterrupted one (positions, velocities, theta, masses, kinds, sorted by id),
on the same rank count and across 1 -> 2, 2 -> 1 and 2 -> 3 ranks (each rank
reads only the rows of its own slab: output.read_particles), for the paper's
integrator, the midpoint integrator and numerics.dt = "auto".
"""
import hashlib
import os
import shutil
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from reliability_helpers import common as C  # noqa: E402

launches = pytest.mark.skipif(C.under_mpirun(), reason="launches parsph/mpirun itself (nested mpirun fails)")

FULL = (*C.SHORT, "output.t_end=0.004", "output.times=[0.002, 0.004]")
HALF = (*C.SHORT, "output.t_end=0.002", "output.times=[0.002]")
VARIANTS = {
    "paper": (),
    "midpoint": ("numerics.integrator=midpoint",),
    "auto": ("numerics.dt=auto",),
}
TIMEOUT = 180


def name(k):
    return f"{C.STEM}_{k:04d}.h5"


def digest(d):
    """{file name: sha256} of the complete and unfinished output files in d."""
    out = {}
    for f in sorted(os.listdir(d)):
        if f.startswith(C.STEM + "_"):
            with open(os.path.join(d, f), "rb") as fh:
                out[f] = hashlib.sha256(fh.read()).hexdigest()
    return out


def run_leg(ranks, out, legs, variant, *extra, timeout=TIMEOUT):
    args = ["--quiet", *extra, *C.sets(*legs, *VARIANTS[variant])]
    if out is not None:
        args = ["--out", out, *args]
    return C.run(C.run_cmd(ranks, *args), timeout=timeout)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Lazily made reference runs: runs("full"|"half", variant, ranks) -> directory (do not modify)."""
    base = tmp_path_factory.mktemp("restart_refs")
    made = {}

    def get(kind, variant="paper", ranks=1):
        key = (kind, variant, ranks)
        if key not in made:
            d = base / f"{kind}_{variant}_{ranks}"
            r = run_leg(ranks if ranks > 1 else 0, d, FULL if kind == "full" else HALF, variant)
            assert r.returncode == 0, r
            made[key] = d
        return made[key]
    return get


# ---- (a) exactness -----------------------------------------------------------------------

@launches
@pytest.mark.parametrize("variant, ranks_before, ranks_after", [
    ("paper", 1, 1), ("paper", 1, 2), ("paper", 2, 2), ("paper", 2, 1), ("paper", 2, 3),
    ("midpoint", 1, 2), ("auto", 2, 1),
])
def test_restart_is_bit_for_bit(runs, tmp_path, variant, ranks_before, ranks_after):
    ref = runs("full", variant, 1)
    d = tmp_path / "run"
    shutil.copytree(runs("half", variant, ranks_before), d)
    before = digest(d)
    assert list(before) == [name(0)], before

    r = run_leg(ranks_after if ranks_after > 1 else 0, None, FULL, variant, "--restart", d)
    assert r.returncode == 0, r
    assert "from t = 0.002 s" in r.stdout, r

    # the earlier output is untouched; the new one is numbered after it; nothing unfinished is left
    after = digest(d)
    assert sorted(after) == [name(0), name(1)], after
    assert after[name(0)] == before[name(0)], "the restart rewrote the output it started from"
    got, want = C.read_final(d / name(1)), C.read_final(ref / name(1))
    assert got["attrs"]["index"] == 1
    assert got["attrs"]["ranks"] == ranks_after
    C.assert_same_particles(got, want, f"{variant}: restart {ranks_before} -> {ranks_after} ranks at t = 0.004 s")

    # the run's profile series reads as one run
    from parsph.output import read_profile
    p, q = read_profile(d), read_profile(ref)
    assert np.array_equal(p["time"], q["time"]) and np.array_equal(p["step"], q["step"])
    if ranks_before == ranks_after == 1:
        assert np.array_equal(p["vy"], q["vy"], equal_nan=True)
    else:  # per-bin sums are all-reduced over ranks: the summation order depends on the rank count
        assert np.allclose(p["vy"], q["vy"], rtol=1e-12, atol=1e-15, equal_nan=True)

    # the ParaView sidecar lists the snapshots before and after the restart
    grids = [g.get("Name") for g in ET.parse(d / f"{C.STEM}.xdmf").getroot().iter("Grid")
             if g.get("GridType") == "Uniform"]
    assert grids == [name(0), name(1)], grids


@launches
def test_restart_from_one_file_into_another_directory(runs, tmp_path):
    """--restart FILE --out DIR: continue from that file (mid-run here), outputs numbered after it in DIR."""
    ref = runs("full", "paper", 1)
    before = digest(ref)
    out = tmp_path / "elsewhere"
    r = run_leg(0, out, FULL, "paper", "--restart", ref / name(0))
    assert r.returncode == 0, r
    assert C.h5_files(out) == [name(1)], os.listdir(out)
    assert digest(ref) == before, "the restart wrote into the directory it restarted from"
    C.assert_same_particles(C.read_final(out / name(1)), C.read_final(ref / name(1)), "restart from a file")


@launches
def test_restart_may_change_output_and_checks(runs, tmp_path):
    """[output] and [checks] may change on restart: more output times, another check cadence."""
    ref = runs("full", "paper", 1)
    d = tmp_path / "run"
    shutil.copytree(runs("half", "paper", 1), d)
    legs = (*C.SHORT, "output.t_end=0.004", "output.times=[0.002, 0.003, 0.004]",
            "checks.every=7", "checks.theta_change=0.4", "output.progress_interval=0.5")
    r = run_leg(0, None, legs, "paper", "--restart", d)
    assert r.returncode == 0, r
    assert C.h5_files(d) == [name(0), name(1), name(2)], os.listdir(d)
    with h5py.File(d / name(1), "r") as f:
        assert (f.attrs["step"], f.attrs["time"], f.attrs["index"]) == (300, 0.003, 1)
    C.assert_same_particles(C.read_final(d / name(2)), C.read_final(ref / name(1)), "restart with more outputs")


@launches
def test_restart_in_place_ignores_an_unfinished_part_file(runs, tmp_path):
    """A run killed while writing output k leaves <stem>_k.h5.part; restarting in place must still work.

    The .part file is debris of an unfinished write (never an output): the
    restart should overwrite it without --force, since --restart DIR is the
    documented recovery after a kill.
    """
    ref = runs("full", "paper", 1)
    d = tmp_path / "run"
    shutil.copytree(runs("half", "paper", 1), d)
    with open(d / name(0), "rb") as f:
        head = f.read(4096)
    with open(d / (name(1) + ".part"), "wb") as f:  # what SIGKILL mid-write leaves
        f.write(head)
    r = run_leg(0, None, FULL, "paper", "--restart", d)
    assert r.returncode == 0, r
    assert C.h5_files(d) == [name(0), name(1)] and not C.h5_files(d, part=True), os.listdir(d)
    C.assert_same_particles(C.read_final(d / name(1)), C.read_final(ref / name(1)), "restart over a .part")


# ---- (b) a restart may not change the physics -------------------------------------------------

# one valid changed value per key outside [output] and [checks]
PHYSICS_CHANGES = {
    "scene.name": "periodic_box",
    "scene.dim": "3",
    "scene.amplitude": "0.02",
    "terms.pressure": "false",
    "terms.viscosity": "false",
    "domain.Lz": "0.004",
    "numerics.pressure_form": "consistent",
    "domain.L": "0.012",
    "domain.Ly": "0.004",
    "numerics.skin": "0.3",
    "material.rho_s": "2500.0",
    "material.theta0": "0.3",
    "material.k": "2.0",
    "material.G_a": "8.5",
    "material.G_b": "-1.0",
    "walls.V_w": "0.5",
    "walls.layers": "4",
    "walls.beta_max": "2.0",
    "numerics.Nx": "40",
    "numerics.h": "2.4e-4",
    "numerics.kernel": "wendland_c2",
    "numerics.dt": "5e-6",
    "numerics.dt_safety": "0.5",
    "numerics.integrator": "midpoint",
    "numerics.viscosity_form": "symmetric",
    "body_force.g": "[0.0, 1.0]",
    "gas.drag": "stokes",
    "material.d": "1e-4",
    "numerics.drag_update": "explicit",
}
# the gas's other keys are refused without gas.drag (each is a physics key like gas.drag, compared alike)
NEED_DRAG = {"gas.rho", "gas.mu", "gas.flow", "gas.velocity", "gas.U"}
# scene.height and walls.sides are refused outside the layer scenes (sedimentation, fluidized_bed), so not on the
# paper case; restart_state compares them like every key outside [output] and [checks]
NEED_LAYER = {"scene.height", "walls.sides"}
# the solved gas's grid keys are refused without gas.flow = "solved", and a perturbation's two keys each without
# the other; restart_state compares them like every key outside [output] and [checks]
NEED_SOLVED = {"gas.cell", "gas.K_max", "gas.solve_every", "gas.jet"}
NEED_PAIR = {"perturbation.amplitude", "perturbation.wavelength", "perturbation.wavelength_y"}
# the packing limit is refused with the paper's pressure form, and theta_min without theta_max; restart_state
# compares them like every key outside [output] and [checks]
NEED_CONSISTENT = {"material.theta_max", "material.theta_min"}
FREE_CHANGES = {
    "output.t_end": "0.01",
    "output.times": "[0.001, 0.003, 0.004]",
    "output.snapshots": "false",
    "output.progress_interval": "1.0",
    "checks.every": "3",
    "checks.theta_change": "0.1",
    "checks.energy": "false",
}


def test_every_physics_key_is_covered():
    from parsph.setup.schema import SCHEMA
    physics = {f"{s}.{k}" for s, keys in SCHEMA.items() if s not in ("output", "checks") for k in keys}
    # h_over_dx: the paper file gives h (both at once is an error); allow_unstable_dt changes no trajectory
    untested = (physics - set(PHYSICS_CHANGES) - {"numerics.h_over_dx", "numerics.allow_unstable_dt"} - NEED_DRAG
                - NEED_LAYER - NEED_SOLVED - NEED_PAIR - NEED_CONSISTENT)
    assert not untested, f"run-file keys without a restart test: {sorted(untested)}"


@launches
@pytest.mark.parametrize("key", sorted(PHYSICS_CHANGES))
def test_restart_refuses_a_physics_change(runs, key):
    """In process (run.restart_state): UsageError naming the key, for every physics key."""
    from parsph.cli import run
    from parsph.errors import UsageError
    from parsph.setup import config
    snap = runs("half", "paper", 1) / name(0)
    cfg = config.load(C.PAPER, [*FULL, f"{key}={PHYSICS_CHANGES[key]}"])
    with pytest.raises(UsageError) as e:
        run.restart_state(cfg, str(snap))
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"--restart: {key} = "), msg


@launches
@pytest.mark.parametrize("key", sorted(FREE_CHANGES))
def test_restart_accepts_output_and_checks_changes(runs, key):
    from parsph.cli import run
    from parsph.setup import config
    snap = runs("half", "paper", 1) / name(0)
    cfg = config.load(C.PAPER, [*FULL, f"{key}={FREE_CHANGES[key]}"])
    state = run.restart_state(cfg, str(snap))
    assert int(state["attrs"]["step"]) == 200


@launches
@pytest.mark.parametrize("ranks, key", [(0, "material.k"), (0, "numerics.Nx"), (0, "numerics.kernel"),
                                        (2, "walls.V_w")])
def test_restart_refusal_on_the_command_line(runs, tmp_path, ranks, key):
    d = tmp_path / "run"
    shutil.copytree(runs("half", "paper", 1), d)
    before = digest(d)
    r = C.run(C.run_cmd(ranks, "--restart", d, "--quiet", *C.sets(*FULL, f"{key}={PHYSICS_CHANGES[key]}")),
              timeout=120)
    assert r.returncode == 2, r
    assert "Traceback" not in r.stderr and "MPI_ABORT" not in r.stderr, r
    lines = C.parsph_lines(r.stderr)
    assert len(lines) == 1 and key in lines[0] and lines[0].startswith("parsph: error: --restart"), r
    if not ranks:  # under mpirun, Open MPI adds its own "process returned a non-zero exit code" banner
        assert C.stderr_lines(r.stderr) == lines, r
    assert r.stdout == "", r
    assert digest(d) == before, "a refused restart changed the output directory"


# ---- (c) nothing to restart from ---------------------------------------------------------

def _no_snapshot_dir(kind, src, tmp):
    """A restart OUTPUT that holds no usable snapshot."""
    if kind == "missing":
        return tmp / "does-not-exist"
    d = tmp / kind
    d.mkdir()
    if kind == "only_part":  # a first output that never completed
        with open(src / name(0), "rb") as f:
            (d / (name(0) + ".part")).write_bytes(f.read(4096))
    elif kind == "profile_only":  # output.snapshots = false
        shutil.copy(src / name(0), d / name(0))
        with h5py.File(d / name(0), "a") as f:
            del f["particles"]
    elif kind == "corrupt_file":
        d = d / name(0)
        d.write_bytes(b"not an HDF5 file\n" * 10)
    return d


@launches
@pytest.mark.parametrize("ranks, kind", [(0, "missing"), (0, "empty_dir"), (0, "only_part"),
                                         (0, "profile_only"), (0, "corrupt_file"), (2, "empty_dir")])
def test_restart_without_a_snapshot_is_bad_input(runs, tmp_path, ranks, kind):
    """Exit 2 and one line naming the restart path: a bad --restart is bad input, not a crash (exit 1)."""
    target = _no_snapshot_dir(kind, runs("half", "paper", 1), tmp_path)
    r = C.run(C.run_cmd(ranks, "--restart", target, "--quiet", *C.sets(*FULL)), timeout=120)
    assert "Traceback" not in r.stderr and "MPI_ABORT" not in r.stderr, r
    assert r.returncode == 2, r
    lines = C.parsph_lines(r.stderr)
    assert len(lines) == 1 and lines[0].startswith("parsph: error: ") and str(target) in lines[0], r
    if not ranks:
        assert C.stderr_lines(r.stderr) == lines, r


# ---- in process on COMM_WORLD (pytest-mpi) -----------------------------------------------------

@pytest.mark.mpi
def test_restart_in_process_on_comm_world(mpi_tmp_path):
    """Simulation + Output on COMM_WORLD: continuing from read_state (attributes and path; the
    ranks read their own particles) equals the uninterrupted run."""
    from parsph.output import Output, read_snapshot, read_state
    from parsph.simulation.solver import Simulation
    comm, cfg, (a, b) = C.comm_world_case(mpi_tmp_path, ("uninterrupted", "restarted"),
                                          "output.t_end=0.0006", "output.times=[0.0003, 0.0006]")
    sim = Simulation(cfg, comm)
    sim.run(output=Output(comm, str(a), C.STEM, cfg, sim.n_total))
    state = read_state(str(a / name(0)))
    assert int(state["attrs"]["step"]) == 30 and set(state) == {"attrs", "path"}
    sim2 = Simulation(cfg, comm, state=state)
    assert sim2.n_total == sim.n_total
    sim2.run(output=Output(comm, str(b), C.STEM, cfg, sim2.n_total, first_index=1))
    comm.Barrier()
    assert sorted(os.listdir(b)) == [f"{C.STEM}.cells.h5", f"{C.STEM}.xdmf", name(1)]
    got, want = read_snapshot(str(b / name(1))), read_snapshot(str(a / name(1)))
    C.assert_same_particles(got, want, f"in-process restart on {comm.size} rank(s)")
