#!/usr/bin/env python
"""Measured stability map of the Couette case against the predicted time-step limit (docs/stability.md).

    .venv/bin/python scripts/stability_map.py                      # the grid -> results/stability/
    .venv/bin/python scripts/stability_map.py --nx 50 --refine --long   # bisect the limits, confirm
    .venv/bin/python scripts/stability_map.py --integrator midpoint     # the dense corner, midpoint
    .venv/bin/python scripts/stability_map.py --plot-only          # redraw PNGs, summary, merged CSV
    .venv/bin/python scripts/stability_map.py --quick --out DIR    # a 12-run smoke test
    .venv/bin/python scripts/stability_map.py --scene settling [--refine]  # the granular column (gravity on)
    .venv/bin/python scripts/stability_map.py --damping --nx 200,400   # margin of the damping constant
    .venv/bin/python scripts/stability_map.py --pred all --nx 200 --bracket --tol 1.1   # bracket every column
                                                 # against parsph.physics.limits' prediction, + one dt = "auto" run each
    .venv/bin/python scripts/stability_map.py --pred all --nx 50 --auto-only   # auto only ("midpoint": its corner)
    .venv/bin/python scripts/stability_map.py --scene settling --pred all      # auto in the settling columns
    .venv/bin/python scripts/stability_map.py --scene settling --pred all --bracket --tol 1.1   # + fixed dt, bracketed
    .venv/bin/python scripts/stability_map.py --longer 50:0.7:2000:40:20000    # one run of any length
    .venv/bin/python scripts/stability_map.py --ratios CSV... [--auto AUTO_CSV]  # measured / predicted per column
    .venv/bin/python scripts/stability_map.py --figures CSV...    # every figure against the prediction now

What a run is, its criteria and the CSVs' columns: parsph.studies.stability_cases; the
modes: parsph.studies.stability_map; the figures and tables: parsph.studies.stability_report.
Outputs: stability_map.csv (paper integrator), stability_map_midpoint.csv, stability_long.csv,
stability_all.csv (all of them, with integrator and verdict: docs/stability_map.csv),
stability_settling.csv, summary*.txt and the PNGs. Rows already in a CSV are not run again
(delete it to start afresh).
"""
import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# one process, one core: numba's threads would only contend (a run of 260 particles
# took 31 ms a step with 2 threads on the loaded 2-core machine, 2.4 ms with 1)
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from parsph.studies import stability_map as sm  # noqa: E402
from parsph.studies.stability_cases import NXS  # noqa: E402
from parsph.studies.stability_report import ratios  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "results" / "stability"), help="results directory")
    ap.add_argument("--nx", default=",".join(map(str, NXS)), help="comma-separated N_x of the grid")
    ap.add_argument("--refine", action="store_true", help="bisect the measured limit of each N_x = 50 column")
    ap.add_argument("--long", action="store_true",
                    help="confirm the failures at a fixed physical time with a longer run at half the dt")
    ap.add_argument("--quick", action="store_true", help="12 runs only (smoke test)")
    ap.add_argument("--plot-only", action="store_true", help="redraw from the CSV")
    ap.add_argument("--integrator", default="paper", choices=("paper", "midpoint"),
                    help="time integrator (midpoint: its own CSV, the dense corner only)")
    ap.add_argument("--scene", default="couette", choices=("couette", "settling"),
                    help="couette (the map) or settling (the granular column, gravity on)")
    ap.add_argument("--damping", action="store_true",
                    help="theta_0 = 0.7, Re = 57 at the --nx given: fixed dt = DAMPING_FRACTIONS x nu/c^2, "
                         "and dt = \"auto\" (the margin of the damping limit)")
    ap.add_argument("--pred", default="",
                    help="columns 'theta:Re,...', 'all' (the grid) or 'midpoint' (its corner) at each --nx: fixed dt = "
                         "PRED_MULTS x the predicted limit (stability_pred_<integrator>.csv) and one dt = \"auto\" "
                         "run (stability_auto.csv); with --scene settling: auto in each column")
    ap.add_argument("--bracket", action="store_true",
                    help="with --pred: bracket each column's limit to --tol (1, 1.5, 2, doubling or halving, bisection); "
                         "with --scene settling too")
    ap.add_argument("--seed", nargs="*", default=[],
                    help="with --bracket: CSVs of earlier runs; a column whose bounds there lie beyond 1.5x (stable) or "
                         "3x (failing) the prediction starts its bracket from them")
    ap.add_argument("--tol", type=float, default=1.25, help="with --bracket: bisect until failing / stable <= TOL")
    ap.add_argument("--auto-only", action="store_true", help="with --pred: only the dt = \"auto\" runs")
    ap.add_argument("--longer", default="", help="'nx:theta:Re:multiple:steps,...': single runs of any length")
    ap.add_argument("--commits", nargs="*", default=[], help="with --ratios: only the runs made at these commits")
    ap.add_argument("--auto", default="", help="with --ratios: the dt = \"auto\" runs (stability_auto.csv)")
    ap.add_argument("--figures", nargs="*", default=None,
                    help="CSVs of runs (any prediction): redraw every figure against the prediction now")
    ap.add_argument("--ratios", nargs="*", default=None,
                    help="CSVs of runs (any prediction): measured stable dt / the predicted limit per column")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    nxs = [int(x) for x in a.nx.split(",") if x]
    if a.ratios is not None:
        print(f"wrote {ratios(a.ratios, a.out, a.auto, a.commits)}")
    elif a.figures is not None:
        for png in sm.figures(a.out, a.figures):
            print(f"wrote {png}")
    elif a.longer:
        specs = [s.split(":") for s in a.longer.split(",")]
        sm.longer(a.out, [(int(nx), float(t), float(Re), float(m), int(n)) for nx, t, Re, m, n in specs])
    elif a.pred and a.scene == "settling":
        sm.settling_auto(a.out, a.bracket, a.tol)
    elif a.pred:
        cols = a.pred if a.pred in ("all", "midpoint") else \
            [tuple(float(x) for x in c.split(":")) for c in a.pred.split(",") if c]
        sm.pred(a.out, cols, nxs, a.integrator, a.bracket, a.tol, a.seed, a.auto_only)
    elif a.damping:
        sm.damping(a.out, nxs)
    elif a.scene == "settling":
        sm.settling_map(a.out, a.plot_only, a.refine)
    elif a.integrator == "midpoint":
        sm.midpoint_map(a.out, a.plot_only)
    else:
        sm.couette_map(a.out, nxs, a.quick, a.plot_only, a.refine, a.long)
    return 0


if __name__ == "__main__":
    sys.exit(main())
