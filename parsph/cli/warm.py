"""Compile parsph's loops into numba's disk cache ahead of the first run (``scripts/setup.sh`` calls it).

    python -m parsph.cli.warm [RUN_DIR] [--suite] [--jobs N]

numba compiles a loop for each set of argument types the first time a
process needs it and keeps it in ``__pycache__`` beside the source (keyed by
the source's content, the CPU and numba's version), which later processes
load in well under a second. A run file's scene, dimension and terms decide
the types (the compile-time switches of :mod:`parsph.sph.pass_data` and
:mod:`parsph.simulation.block`), so this runs cases for a few steps on a tiny
box, one rank each unless said:

- by default what ``scripts/main.sh`` runs: the paper case (RUN_DIR's
  couette_paper.toml, default the repository's ``run/``) on one thread, in
  this process, then on two ranks (``mpirun -n 2``, with the flags of
  ``PARSPH_MPIRUN_FLAGS``: what one rank never calls, the particles'
  migration between slabs);
- with ``--suite`` also what the test suite (``scripts/test.sh``) runs in
  launched processes and under mpirun, where each process or rank would
  compile it again: every run file of RUN_DIR on one thread and the variants
  of :data:`SUITE`.

Any other combination compiles at its first run, which says so and for how
long (:mod:`.progress`). What the cache holds already is loaded, not compiled
again; no result depends on any of it. Prints one line: what it ran, and the
seconds it compiled.

With several cases the first (the paper case, whose loops share most with every
other) runs alone, then the others go to ``--jobs`` processes (default: one per
core, at most 4) that take them one by one from a shared counter. They save
into the one cache, each save under parsph's lock
(:func:`parsph.numba_cache.serialise_saves`: numba's saves are not safe for
two processes writing versions of one function at once).
"""
import argparse
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "2")  # the threaded passes compile even on one core

# (run file, overrides): tiny boxes that every scene accepts, a few steps, one output with particles
TINY = ["domain.Ly=0.003", "output.t_end=3e-5", "output.times=[3e-5]", "output.progress_interval=0"]
TINY_3D = ["domain.Lz=0.0006"]
# run files whose solved gas needs a wider tiny box: 3 cells of 2 mm across y, with their seed's wavelength and
# the jet's orifice inside it
TINY_WIDER = {"bubbling_bed.toml": ["domain.Ly=0.006", "perturbation.wavelength_y=0.006", "checks.settle=0.0"],
              "single_bubble.toml": ["domain.Ly=0.006", "gas.jet=[0.002, 0.004, 1.0, 0.05]"],
              "bubbling_bed_3d.toml": ["domain.Ly=0.012", "domain.Lz=0.012", "perturbation.wavelength_y=0.012",
                                       "checks.settle=0.0"]}
RUN_DIR = Path(__file__).resolve().parents[2] / "run"
# scripts/main.sh: the paper case on 2 ranks, one thread each (a case's fourth field: its ranks, under mpirun;
# default 1, in process); on 2 ranks 50 steps, so that the neighbour list is rebuilt and particles migrate
MAIN = [("couette_paper.toml", [], 1), ("couette_paper.toml", ["output.t_end=5e-4", "output.times=[5e-4]"], 1, 2)]
# (run file, overrides, threads[, ranks]) that the suite runs in launched processes (tests/mpi_helpers/scene_ranks.py,
# parsph run / converge from the CLI tests) and under mpirun (the MPI phases: test_compiled_step's CASES,
# test_mpi_parallel, test_mpi_scenes) beyond the run files on one thread. A test that launches a variant not
# here compiles it in every process (each rank of each pytest worker) at once: add it here.
SUITE = [
    ("couette_paper.toml", ["numerics.integrator=midpoint"], 1),
    ("couette_paper.toml", ['numerics.dt="auto"'], 1),
    ("couette_paper.toml", ["numerics.integrator=midpoint", 'numerics.dt="auto"', "numerics.viscosity_form=symmetric"],
     1),
    ("couette_3d.toml", [], 2),
    ("settling.toml", ["numerics.dt=5e-5"], 1),
    ("periodic_box.toml", ["terms.pressure=true"], 1),
    ("periodic_box.toml", ["terms.pressure=true"], 2),
    # in a gas: scene_ranks' box_gas (implicit drag, 2 threads and 1) and settling_gas (explicit, fixed dt),
    # test_compiled_step's box_gas (explicit under the auto rule) and settling_gas (implicit, midpoint)
    ("periodic_box.toml", ["terms.pressure=true", 'gas.drag="gidaspow"', "gas.velocity=[0.0, 0.3]", "gas.rho=1000.0",
                           "gas.mu=1e-3", "body_force.g=[-9.81, 0.0]"], 1),
    ("periodic_box.toml", ["terms.pressure=true", 'gas.drag="gidaspow"', "gas.velocity=[0.0, 0.3]", "gas.rho=1000.0",
                           "gas.mu=1e-3", "body_force.g=[-9.81, 0.0]"], 2),
    ("settling.toml", ['gas.drag="wen_yu"', 'gas.flow="column"', "gas.U=0.02", 'numerics.drag_update="explicit"',
                       "numerics.dt=5e-5"], 1),
    ("periodic_box.toml", ['gas.drag="wen_yu"', 'gas.flow="column"', "body_force.g=[-9.81, 0.0]", "gas.rho=1000.0",
                           "gas.mu=1e-3", "material.d=1e-4", "scene.amplitude=2.0", 'numerics.drag_update="explicit"',
                           'numerics.dt="auto"'], 1),
    ("settling.toml", ['gas.drag="gidaspow"', 'gas.flow="column"', "gas.U=0.05", "numerics.integrator=midpoint"], 1),
    # the layer scenes (massless walls that follow the solids: the mirror switch): scene_ranks' cases
    # (fixed dt, 1 thread and 2), test_compiled_step's bed (midpoint); its sedimentation is the run file's
    ("sedimentation.toml", ["numerics.dt=5e-5"], 1),
    ("sedimentation.toml", ["numerics.dt=5e-5"], 2),
    ("fluidized_bed.toml", ["numerics.dt=5e-5"], 1),
    ("fluidized_bed.toml", ["numerics.dt=5e-5"], 2),
    ("fluidized_bed.toml", ["numerics.dt=1e-4", "numerics.integrator=midpoint"], 1),
    # the solved gas (its blocks, the grid's loops): scene_ranks' bed (1 thread and 2) and its 3-D
    # bed, the voidage waves of test_solved_gas_runs (a box periodic along gravity)
    ("fluidized_bed.toml", ["numerics.dt=5e-5", 'gas.flow="solved"'], 1),
    ("fluidized_bed.toml", ["numerics.dt=5e-5", 'gas.flow="solved"'], 2),
    ("fluidized_bed.toml", ["scene.dim=3", "body_force.g=[-9.81, 0.0, 0.0]", "domain.Lz=0.0012", "numerics.dt=5e-5",
                            'gas.flow="solved"', "gas.cell=0.0004", 'gas.drag="gidaspow"'], 1),
    ("voidage_waves.toml", ['gas.flow="solved"'], 1),
]
QUEUE = "PARSPH_WARM_QUEUE"  # a worker's shared folder: the lock, the next case, the results


def _ranks(case):
    return case[3] if len(case) > 3 else 1


def _tiny(path):
    return TINY + (TINY_3D if "dim = 3" in Path(path).read_text() else []) + TINY_WIDER.get(Path(path).name, [])


def variants(run_dir, suite=False):
    """(run file, overrides, threads, ranks) of every case to run: main.sh's, and with ``suite`` the suite's."""
    run_dir = Path(run_dir)
    picked = [(run_dir / c[0], *c[1:]) for c in MAIN]
    if suite:
        picked += [(path, [], 1) for path in sorted(run_dir.glob("*.toml"))]
        picked += [(run_dir / c[0], *c[1:]) for c in SUITE]
    out = []
    for c in picked:
        path, sets, threads = c[:3]
        case = (path, _tiny(path) + list(sets), threads, _ranks(c))
        if path.exists() and case not in out:
            out.append(case)
    return out


def describe(case):
    """A case as one line: the run file, the overrides beyond the tiny box's, the threads (and ranks)."""
    path, sets, threads, ranks = case
    more = [s for s in sets if s not in TINY + TINY_3D + TINY_WIDER.get(Path(path).name, [])]
    return " ".join(([f"mpirun -n {ranks}"] if ranks > 1 else []) + [Path(path).name] + more
                    + [f"--threads {threads}"])


def run_case(parsph, case, out):
    """Run one case with ``parsph`` (the command's main) into the directory ``out``, quietly: (exit code,
    what it wrote on stderr). A case on several ranks runs under ``mpirun`` (its ranks compile what this
    process has not saved into the cache, and save it)."""
    path, sets, threads, ranks = case
    args = ["run", str(path), "--out", str(out), "--quiet", "--threads", str(threads)]
    for s in sets:
        args += ["--set", s]
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), *os.environ.get("PARSPH_MPIRUN_FLAGS", "").split(), sys.executable,
               "-m", "parsph", *args]
        try:
            # os.environ as Python read it at start: the variables MPI_Init set in C (this process runs
            # on a singleton COMM_WORLD) would make the nested mpirun fail
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=1800, env=dict(os.environ))
        except (OSError, subprocess.TimeoutExpired) as e:
            return 1, str(e)
        return p.returncode, p.stderr + p.stdout
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
        code = parsph(args)
    return code, err.getvalue()


@contextlib.contextmanager
def _locked(folder):
    import fcntl
    with open(os.path.join(folder, "lock"), "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _next_case(folder):
    """The index of the next case nobody took (a counter in ``folder``, under its lock)."""
    with _locked(folder):
        counter = Path(folder) / "next"
        k = int(counter.read_text()) if counter.exists() else 0
        counter.write_text(str(k + 1))
    return k


def run_cases(cases, take=None):
    """Run the cases (those ``take()`` hands out, until it returns an index past the end): (compile
    seconds, [failures])."""
    from .command import main as parsph
    from .progress import CompileWatch
    failed = []
    with CompileWatch() as watch, tempfile.TemporaryDirectory(prefix="parsph-warm-") as tmp:
        for k in iter(take, None) if take else range(len(cases)):
            if k >= len(cases):
                break
            code, err = run_case(parsph, cases[k], os.path.join(tmp, str(k)))
            if code != 0:
                failed.append(f"{describe(cases[k])}: exit {code}: {err.strip()[-300:]}")
    return watch.seconds(), failed


def default_jobs():
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    return max(1, min(cores, 4))


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m parsph.cli.warm", description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", nargs="?", default=str(RUN_DIR))
    ap.add_argument("--suite", action="store_true", help="also what the test suite runs in launched processes")
    ap.add_argument("--jobs", type=int, default=int(os.environ.get("PARSPH_WARM_JOBS", 0)) or default_jobs())
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    cases = variants(a.run_dir, a.suite)
    if a.worker:  # one of main()'s processes: cases from the queue, the result into it
        folder = os.environ[QUEUE]
        seconds, failed = run_cases(cases, lambda: _next_case(folder))
        Path(folder, f"result.{os.getpid()}").write_text(json.dumps([seconds, failed]))
        return 0
    t0 = time.perf_counter()
    jobs = max(1, min(a.jobs, len(cases) - 1))  # the processes share the cases after the first
    if jobs == 1:
        seconds, failed = run_cases(cases)
    else:
        # the first case alone, then the others in ``jobs`` processes: it compiles what every case shares (the
        # build, the halo, the outputs, the checks), which processes starting together would each compile
        seconds, failed = run_cases(cases[:1])
        with tempfile.TemporaryDirectory(prefix="parsph-warm-queue-") as folder:
            Path(folder, "next").write_text("1")
            cmd = [sys.executable, "-m", "parsph.cli.warm", a.run_dir, "--worker"] + (["--suite"] if a.suite else [])
            procs = [subprocess.Popen(cmd, env={**os.environ, QUEUE: folder}) for _ in range(jobs)]
            codes = [proc.wait() for proc in procs]
            results = [json.loads(f.read_text()) for f in Path(folder).glob("result.*")]
        seconds += sum(r[0] for r in results)
        failed += [f for r in results for f in r[1]]
        failed += [f"a worker process: exit {c}" for c in codes if c != 0]
    what = "the cases of main.sh and the test suite" if a.suite else "the case of main.sh"
    runs = f"{len(cases)} tiny run{'s' if len(cases) > 1 else ''}"
    print(f"warm: {runs} ({what}) of {a.run_dir} in {time.perf_counter() - t0:.0f} s"
          f"{f' ({jobs} processes)' if jobs > 1 else ''}, {seconds:.0f} s of compiling", file=sys.stderr)
    for f in failed:  # a case that cannot run here only leaves its loops to compile at its first run
        print(f"warm: skipped {f}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
