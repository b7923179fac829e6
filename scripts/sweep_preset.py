"""Run a run file as ``parsph run`` does, on one rank, in this process, and report its errors and cost.

    nice -n 10 .venv/bin/python scripts/sweep_preset.py run/couette_fast.toml [--out DIR]

The numbers quoted in the comments of run/couette_*.toml come from here: the
error table of the run's output files, the process CPU time of the whole
command (imports, numba cache load, set-up, time loop, HDF5 output with
snapshots) and of the time loop alone (``run_case``'s result: the library call
under ``parsph run``), and wall time.
"""
import argparse
import contextlib
import io
import os
import sys
import time

T0_CPU, T0_WALL = time.process_time(), time.perf_counter()
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--out", help="output directory (default results/presets/<name>)")
    args = ap.parse_args()
    name = os.path.splitext(os.path.basename(args.config))[0]
    out = args.out or os.path.join(ROOT, "results", "presets", name)
    from mpi4py import MPI
    from parsph.cli.report import print_table
    from parsph.output import read_profile
    from parsph.setup import config
    from parsph.simulation.case import run_case
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        res = run_case(MPI.COMM_SELF, config.load(args.config), out, name, force=True, say=print)
        print_table(out)
    cpu, wall = time.process_time() - T0_CPU, time.perf_counter() - T0_WALL
    print(text.getvalue())
    prof = read_profile(out)
    print(f"{name}: {prof['attrs']['n_particles']} particles, {res.sim.step} steps; "
          f"process CPU {cpu:.1f} s (time loop {res.cpu_s:.1f} s), wall {wall:.1f} s")
    for t, e, r in zip(prof["time"], prof["err_max"], prof["err_rms"]):
        print(f"  t = {t:g} s: max {e:.2e}, rms {r:.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
