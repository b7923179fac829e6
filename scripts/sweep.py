"""Accuracy against cost for the Couette case: run a grid of numerical choices, find the frontier.

    nice -n 10 .venv/bin/python scripts/sweep.py            # default grid (docs/accuracy.md)
    nice -n 10 .venv/bin/python scripts/sweep.py --quick    # a few minutes
    .venv/bin/python scripts/sweep.py --report-only         # CSV, plots and summary from the runs so far
    options: --jobs N (runs at once; default 1), --out DIR, --rerun (ignore finished runs),
             --max-cost S (skip runs whose estimated CPU time exceeds S seconds), --list,
             --no-snapshot (see below)

Each run is one process (scripts/sweep_run.py) on one rank; what a run is and
records: parsph.studies.sweep, the analysis: parsph.studies.sweep_report.
Finished runs are appended to DIR/runs.jsonl and are not run again (a killed
sweep resumes). The first run copies parsph/ to DIR/code and every run imports
that copy, so that edits to the working tree during a sweep do not mix code
versions (--rerun takes a fresh copy; each record carries a hash of the code). Written to DIR (default results/sweep, or results/sweep_quick):

    sweep.csv                 one row per run (columns: see CSV_COLUMNS)
    accuracy_pareto.png       max error against CPU time at t = 0.05 and 0.5 s, Pareto frontier drawn
    accuracy_pareto_wall.png  the same against wall time (shared machine: other people's load included)
    accuracy_convergence.png  max error against dx per kernel / integrator / h/dx, fitted orders
    summary.md                orders, frontier, the cheapest 1 % setting, the best within 10x the paper case

Cost is the process CPU time of the time loop up to the output time: on this
shared machine wall time also counts other people's work (both are in the CSV).
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

from parsph.studies import sweep  # noqa: E402
from parsph.studies.sweep_report import write_report  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the quick grid (a few minutes)")
    ap.add_argument("--out", help="results directory (default results/sweep or results/sweep_quick)")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (default 1)")
    ap.add_argument("--rerun", action="store_true", help="run every run again")
    ap.add_argument("--report-only", action="store_true", help="no runs: CSV, plots, summary from runs.jsonl")
    ap.add_argument("--max-cost", type=float, default=0.0, help="skip runs estimated above this many CPU s")
    ap.add_argument("--list", action="store_true", help="print the grid with estimated costs and stop")
    ap.add_argument("--no-snapshot", action="store_true",
                    help="run the working tree's parsph, not the copy in DIR/code made at the first run")
    args = ap.parse_args(argv)
    out_dir = args.out or os.path.join(ROOT, "results", "sweep_quick" if args.quick else "sweep")
    grid = sweep.merge(sweep.quick_grid() if args.quick else sweep.default_grid())
    if args.list:
        for k, (run, g) in sorted(grid.items(), key=lambda kv: sweep.estimate_cpu(kv[1][0])):
            print(f"{sweep.estimate_cpu(run):8.1f} s  {k}  [{' '.join(sorted(g))}]")
        print(f"total {sum(sweep.estimate_cpu(r) for r, _ in grid.values()) / 60:.1f} CPU-minutes (estimate)")
        return 0
    if not args.report_only:
        sweep.execute(grid, out_dir, [sys.executable, os.path.join(HERE, "sweep_run.py")], args.jobs, args.rerun,
                      args.max_cost, not args.no_snapshot)
    text = write_report(grid, sweep.runs_file(out_dir).store.records, out_dir)
    print(text)
    print(f"wrote {os.path.join(out_dir, 'sweep.csv')}, accuracy_pareto.png, accuracy_pareto_wall.png, "
          f"accuracy_convergence.png, summary.md in {out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
