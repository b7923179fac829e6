"""Output and restart I/O: throughput against the raw disk, and peak memory of a restart.

    mpirun -n P .venv/bin/python scripts/io_bench.py throughput --n 1000000 --dir DIR [--repeat 3] [--json F]
    .venv/bin/python scripts/io_bench.py rss --n 4000000 --ranks 1 2 4 --dir DIR [--json F]
    .venv/bin/python scripts/io_bench.py report docs/bench/io_*.json      (markdown tables)

throughput (under mpirun, P ranks): each rank builds N/P particles of the
paper case's lattice in its slab (``parsph.setup.scenes.lattice``; 2-D: id, kind,
mass, position, velocity, theta; synthetic velocities and theta, no solver; shuffled in memory by default, the worst
case for the writer's y-bin sort) and the real writer (output.Output) writes
one snapshot, timed from the call to the renamed, fsynced file. Then the file's
pages are dropped from the page cache (posix_fadvise DONTNEED after the
fsync) and every rank reads its own slab with output.read_particles, as a
restart does. In the same run rank 0 measures the raw disk on the same number
of bytes: numpy ``tofile`` + fsync, and ``dd oflag=direct`` (bs 4 MiB); reads
with ``fromfile`` after the same eviction, and ``dd iflag=direct``. Rates are
bytes / s; the ratio divides by the numpy rate of the same bytes (the larger
of the two raw rates where dd is faster). The median of ``--repeat`` rounds.

What is measured and how: parsph.studies.io_rates.

rss: a fresh run of the paper case with L_y chosen for N particles, one step
with one output (a restart point), then a restart from it for one more step
and output, each on P ranks (oversubscribed past the cores); every rank
records its peak resident set size (getrusage ru_maxrss) at exit. ``--repo``
runs another checkout's parsph (e.g. the commit before the slab reads).
"""
import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAPER = os.path.join(ROOT, "run", "couette_paper.toml")


def rss_run(argv):
    """Inside one rank: run the parsph CLI (of the checkout on PYTHONPATH), then record this
    process's peak RSS."""
    out = argv[0]
    from mpi4py import MPI
    from parsph import cli
    rc = cli.main(argv[1:])
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    with open(os.path.join(out, f"rss_{MPI.COMM_WORLD.rank}.txt"), "w") as f:
        f.write(f"{peak} {rc}\n")
    return rc


def rss(args, io_rates):
    Ly, N = io_rates.ly_for(args.n)
    env = dict(os.environ, PYTHONPATH=os.path.abspath(args.repo), NUMBA_NUM_THREADS="1",
               OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    dt = 1e-5
    sets = ["--set", f"domain.Ly={Ly!r}", "--set", "output.progress_interval=0"]
    results = []
    for P in args.ranks:
        base = tempfile.mkdtemp(prefix=f"io_rss_{P}_", dir=args.dir)
        legs = {"fresh": (["--set", f"output.t_end={dt}", "--set", f"output.times=[{dt}]"], None),
                "restart": (["--set", f"output.t_end={2 * dt}", "--set", f"output.times=[{dt}, {2 * dt}]"],
                            os.path.join(base, "out"))}
        row = {"ranks": P, "n": N}
        for leg, (extra, restart) in legs.items():
            rec = os.path.join(base, leg)
            os.makedirs(rec)
            cmd = ["mpirun", "--oversubscribe", "-n", str(P), "-x", "PYTHONPATH", "-x", "NUMBA_NUM_THREADS",
                   sys.executable, os.path.abspath(__file__), "_rss_rank", rec, "run", PAPER, "--quiet",
                   "--out", os.path.join(base, "out"), *sets, *extra]
            if restart:
                cmd += ["--restart", restart]
            t0 = time.perf_counter()
            r = subprocess.run(cmd, env=env, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            if r.returncode:
                raise SystemExit(f"{leg} on {P} ranks failed:\n{r.stdout}\n{r.stderr}")
            peaks = []
            for k in range(P):
                with open(os.path.join(rec, f"rss_{k}.txt")) as f:
                    peaks.append(int(f.read().split()[0]))
            row[leg] = {"peak_rss_MB": [p / 1e6 for p in peaks], "wall_s": wall}
            print(f"P = {P} {leg}: peak RSS per rank {[round(p / 1e6) for p in peaks]} MB ({wall:.0f} s)", flush=True)
        row["ratio_max"] = max(row["restart"]["peak_rss_MB"]) / max(row["fresh"]["peak_rss_MB"])
        results.append(row)
        shutil.rmtree(base)
    commit = subprocess.run(["git", "-C", args.repo, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    res = {"mode": "rss", "n": N, "repo": os.path.abspath(args.repo), "commit": commit, "machine": io_rates.machine(),
           "rows": results}
    print(json.dumps(res, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "_rss_rank":  # a rank: parsph not yet imported, so --repo's is
        return rss_run(sys.argv[2:])
    from parsph.studies import io_rates
    if len(sys.argv) > 1 and sys.argv[1] == "report":
        return io_rates.report(sys.argv[2:])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=("throughput", "rss"))
    ap.add_argument("--n", type=int, default=1_000_000, help="particles (rounded up to whole lattice rows)")
    ap.add_argument("--dir", default=None, help="directory on the disk to measure (default: the temp dir)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--order", choices=("shuffled", "lattice"), default="shuffled",
                    help="particle order in memory: shuffled (worst case for the y-bin sort) or lattice rows")
    ap.add_argument("--repo", default=ROOT, help="rss: the parsph checkout the ranks import (default this one)")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    return io_rates.throughput(args) if args.mode == "throughput" else rss(args, io_rates)


if __name__ == "__main__":
    sys.exit(main())
