"""Failures under mpirun end every rank, with one clear message.

Serial pytest launching ``mpirun`` itself (skipped inside an mpirun job):

    .venv/bin/python -m pytest -q tests/test_mpi_failures.py

Every launch has a hang guard: after HANG_GUARD seconds the whole process
group is killed and the test fails (a hang is the failure these tests exist to
catch). No test asserts how fast a job ends: a healthy one ends in seconds, and
the guard is set for a slow, loaded CI machine.
"""
import re

import h5py
import pytest

from mpi_helpers import launch  # noqa: E402

pytestmark = pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")


@pytest.fixture(scope="module", autouse=True)
def warm_numba_cache():
    """Compile once before the launches, so that the hang guard covers MPI behaviour, not the compiler."""
    launch.warm_cache()


HANG_GUARD = 300  # s: a job still running after this is taken for a hang, killed, and the test fails
SHORT = ["output.t_end=0.001", "domain.Ly=0.002", "output.times=[0.0005]"]


def sets(*extra):
    out = []
    for s in (*SHORT, *extra):
        out += ["--set", s]
    return out


def helper(name):
    return str(launch.HELPERS / name)


# ---- (a) an exception on one rank ------------------------------------------------------------
@pytest.mark.parametrize("rank, env", [
    (1, {}),                                    # parallel HDF5 (h5py built with MPI)
    (0, {}),                                    # the root rank fails
    (1, {"PARSPH_SERIAL_HDF5": "1"}),           # the gather-to-rank-0 output path
], ids=["rank1", "rank0", "rank1-serial-hdf5"])
def test_exception_on_one_rank_ends_the_job(tmp_path, rank, env):
    r = launch.run(launch.mpirun_cmd(2, launch.PYTHON, helper("inject_one_rank.py"), "raise", rank, 20, "--",
                                     launch.PAPER, *sets(), "--out", tmp_path / "out", "--force", "--quiet"),
                   timeout=HANG_GUARD, **env)
    assert r.returncode != 0, r
    assert launch.count_lines(r.output, "injected failure") == 1, r
    line = next(ln for ln in r.output.splitlines() if "injected failure" in ln)
    assert f"rank {rank}" in line and "RuntimeError" in line, r


# ---- (b) a NaN on one rank -----------------------------------------------------------------
@pytest.mark.parametrize("inject_at, check_every, native, caught_at", [
    (10, 5, "0", 10),     # Python path: the run-time checks of step 10 see it before the next step
    (10, 5, "1", 11),     # compiled blocks: put in after the block's checks; the next integration's flag
    (11, 5, "1", 12),     # between checks: the next integration's collective flag catches it
    (11, 1000, "1", 12),  # checks far apart: the per-step flag alone
], ids=["on-check-step-python", "after-check-step", "between-checks", "checks-rare"])
def test_nan_on_one_rank_stops_every_rank_with_exit_3(tmp_path, inject_at, check_every, native, caught_at):
    """A NaN velocity on rank 1: exit 3 and ONE message, from the checks (every checks.every steps)
    or, between them, from the per-step collective non-finite flag right after integration."""
    r = launch.run(launch.mpirun_cmd(2, launch.PYTHON, helper("inject_one_rank.py"), "nan", 1, inject_at, "--",
                                     launch.PAPER, *sets(f"checks.every={check_every}"),
                                     "--out", tmp_path / "out", "--force", "--quiet"),
                   timeout=HANG_GUARD, PARSPH_NATIVE_MPI=native)
    assert "nan_one_rank: NaN put into particle" in r.stderr, r   # the injection happened
    assert r.returncode == 3, r
    assert launch.count_lines(r.output, "check failed") == 1, r
    assert "error on rank" not in r.output, r                     # not the per-rank crash path
    assert "Traceback" not in r.output, r
    line = next(ln for ln in r.output.splitlines() if "check failed" in ln)
    assert line.startswith("parsph: error: check failed: non-finite position, velocity or acceleration"), r
    assert line.endswith("earlier outputs are intact"), r
    m = re.search(r"at step (\d+)", line)
    assert m, line
    assert int(m.group(1)) == caught_at, line


# ---- (c) a bad run file under mpirun -n 2 -----------------------------------------------------
BAD_TOML = """[scene]
name = "couette"
[domain]
L = 0.01
Ly = 0.002
[material]
rho_s = 2000.0
theta0 = 0.35
k = 1.0
viscosty = 2.0
[numerics]
Nx = 50
h = 2.5e-4
dt = 1.0e-5
[output]
t_end = 0.001
"""


@pytest.mark.parametrize("case", ["bad-value", "unknown-key", "missing-file", "not-toml", "unstable-dt",
                                  "layer-scene"])
def test_bad_run_file_exit_2_one_message(tmp_path, case):
    run_file, extra, expect = launch.PAPER, [], None
    if case == "bad-value":
        extra, expect = ["--set", "material.theta0=1.5"], "material.theta0"
    elif case == "unknown-key":
        run_file, expect = tmp_path / "bad.toml", "material.viscosty"
        run_file.write_text(BAD_TOML)
    elif case == "missing-file":
        run_file, expect = tmp_path / "nope.toml", "cannot read"
    elif case == "not-toml":
        run_file, expect = tmp_path / "bad.toml", "not valid TOML"
        run_file.write_text("[domain\nL = \n")
    elif case == "unstable-dt":
        extra, expect = ["--set", "numerics.dt=1e-3"], "numerics.dt"
    elif case == "layer-scene":  # a scene's check (Scene.check): the bed would expand past the lid
        run_file, extra, expect = launch.REPO / "run" / "fluidized_bed.toml", ["--set", "gas.U=0.03"], "domain.L"
    r = launch.run(launch.mpirun_cmd(2, *launch.parsph_cmd("run", run_file, *extra, "--out", tmp_path / "out")),
                   timeout=HANG_GUARD)
    assert r.returncode == 2, r
    assert launch.count_lines(r.output, "parsph: error") == 1, r
    line = next(ln for ln in r.output.splitlines() if "parsph: error" in ln)
    assert expect in line, r
    assert "Traceback" not in r.output, r
    out = tmp_path / "out"
    assert not out.exists() or not list(out.glob("couette_paper*")), list(out.iterdir())


# ---- (d) an existing output without --force ----------------------------------------------------
def test_existing_output_without_force_exit_2(tmp_path):
    """A complete output file of the run's is refused under mpirun -n 2 and left untouched."""
    name = "couette_paper_0000.h5"
    out = tmp_path / "out"
    out.mkdir()
    existing = out / name
    existing.write_bytes(b"an earlier run")
    r = launch.run(launch.mpirun_cmd(2, *launch.parsph_cmd("run", launch.PAPER, *sets(), "--out", out)),
                   timeout=HANG_GUARD)
    assert r.returncode == 2, r
    assert launch.count_lines(r.output, "parsph: error") == 1, r
    assert "--force" in r.output and "exists" in r.output and name in r.output, r
    assert existing.read_bytes() == b"an earlier run"          # untouched
    assert sorted(p.name for p in out.iterdir()) == [name]     # and nothing else written


def test_unfinished_part_file_is_debris(tmp_path):
    """A killed run's unfinished ``.part`` is not an output: under mpirun -n 2 the run goes on
    without --force, removes it and writes the complete file in its place."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "couette_paper_0000.h5.part").write_bytes(b"half an output")
    r = launch.run(launch.mpirun_cmd(2, *launch.parsph_cmd("run", launch.PAPER, *sets(), "--out", out,
                                                            "--quiet")), timeout=HANG_GUARD)
    assert r.returncode == 0, r
    assert sorted(p.name for p in out.iterdir()) == ["couette_paper.cells.h5", "couette_paper.xdmf",
                                                      "couette_paper_0000.h5"], r
    with h5py.File(out / "couette_paper_0000.h5", "r") as f:
        assert f.attrs["step"] == 50 and "particles" in f
