"""Compile parsph's loops into numba's disk cache ahead of the first run (``scripts/setup.sh`` calls it).

    python -m parsph.cli.warm [RUN_DIR]

numba compiles a loop for each set of argument types the first time a
process needs it and keeps it in ``__pycache__`` beside the source (keyed by
the source's content, the CPU and numba's version), which later processes
load in well under a second. A run file's scene, dimension and terms decide
the types (the compile-time switches of :mod:`parsph.sph.pass_data`), so this
runs every run file of RUN_DIR (default: the repository's ``run/``) for a few
steps on a tiny box, in this one process on one rank: with one thread and with
two (the threaded passes), and the paper case also with the midpoint
integrator. What the cache holds already is loaded, not compiled again; no
result depends on any of it. Prints one line: what it ran and the seconds it
compiled.
"""
import contextlib
import io
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "2")  # the threaded passes compile even on one core

# (run file, overrides): tiny boxes that every scene accepts, a few steps, one output with particles
TINY = ["domain.Ly=0.003", "output.t_end=3e-5", "output.times=[3e-5]", "output.progress_interval=0"]
TINY_3D = ["domain.Lz=0.0006"]
EXTRA = {"couette_paper.toml": [["numerics.integrator=midpoint"]]}


def variants(run_dir):
    """(run file, overrides, threads) of every case to run."""
    out = []
    for path in sorted(Path(run_dir).glob("*.toml")):
        extra = TINY_3D if "dim = 3" in path.read_text() else []
        for more in [[]] + EXTRA.get(path.name, []):
            for threads in (1, 2):
                out.append((path, TINY + extra + more, threads))
    return out


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    run_dir = Path(argv[0]) if argv else Path(__file__).resolve().parents[2] / "run"
    from .command import main as parsph
    from .progress import CompileWatch
    t0 = time.perf_counter()
    failed = []
    cases = variants(run_dir)
    with CompileWatch() as watch, tempfile.TemporaryDirectory(prefix="parsph-warm-") as tmp:
        for k, (path, sets, threads) in enumerate(cases):
            args = ["run", str(path), "--out", os.path.join(tmp, str(k)), "--quiet", "--threads", str(threads)]
            for s in sets:
                args += ["--set", s]
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
                code = parsph(args)
            if code != 0:
                failed.append(f"{path.name} {' '.join(sets)} --threads {threads}: exit {code}: "
                              f"{err.getvalue().strip()[-300:]}")
    print(f"warm: {len(cases)} tiny runs of {run_dir}/*.toml in {time.perf_counter() - t0:.0f} s, "
          f"{watch.seconds():.0f} s of it compiling", file=sys.stderr)
    for f in failed:  # a case that cannot run here only leaves its loops to compile at its first run
        print(f"warm: skipped {f}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
