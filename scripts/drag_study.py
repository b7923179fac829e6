"""The gas's drag measured on the periodic box (parsph.studies.drag): docs/stability.md's "Drag" and
docs/validation.md's hindered settling.

    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/drag_study.py cost [--rounds 3]
        CPU seconds a step with drag (Stokes, Wen & Yu, Gidaspow; implicit and explicit) against one
        without, alternated, on the same box (N_x = 50)
    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/drag_study.py stability
        dt/tau from 1e-3 to 1e3 for each integrator and drag update: the error against the exact relaxation,
        or the guard's message where the run failed
    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/drag_study.py trade
        one relaxation (tau = 10 ms) at dt = tau/100 .. 4 tau: error against CPU time, explicit and implicit
    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/drag_study.py auto
        the relaxation to t = 10 ms with dt = "auto", tau from 10 ms to 1 us: steps, CPU and error
    .venv/bin/python scripts/drag_study.py settling [--png docs/hindered_settling.png]
        the settling speed against theta0 (Stokes and Wen & Yu) over Richardson & Zaki's line
"""
import argparse
import json
from pathlib import Path

import numpy as np

from parsph.studies import drag

RUN = Path(__file__).resolve().parents[1] / "run"


def cost(args):
    """Each variant timed between two runs without drag, its ratio against their mean (the machine's drift
    between neighbouring runs cancels); the median ratio of each variant at the end."""
    variants = [("stokes", "implicit"), ("stokes", "explicit"), ("wen_yu", "implicit"), ("gidaspow", "implicit")]
    ratios = {v: [] for v in variants}
    for r in range(args.rounds):
        before = drag.step_cost(RUN, "none", steps=args.steps)
        for closure, update in variants:
            t = drag.step_cost(RUN, closure, update, steps=args.steps)
            after = drag.step_cost(RUN, "none", steps=args.steps)
            ratio = t / (0.5 * (before + after))
            ratios[(closure, update)].append(ratio)
            print(json.dumps({"round": r, "drag": closure, "update": update, "ms_per_step": round(1e3 * t, 4),
                              "none_ms_per_step": round(500 * (before + after), 4), "ratio": round(ratio, 3)}),
                  flush=True)
            before = after
    for (closure, update), rs in ratios.items():
        print(json.dumps({"drag": closure, "update": update, "median_ratio": round(float(np.median(rs)), 3),
                          "range": [round(min(rs), 3), round(max(rs), 3)]}), flush=True)


def stability(args):
    for integrator in ("paper", "midpoint"):
        for update in ("explicit", "implicit"):
            for z in (1e-3, 1e-2, 0.1, 0.5, 1.0, 1.9, 2.1, 4.0, 10.0, 1e2, 1e3):
                row = drag.relaxation_run(RUN, z, update, integrator)
                row["failed"] = row["failed"].split(":")[0] if row["failed"] else ""
                print(json.dumps(row), flush=True)


def trade(args):
    tau = 1e-2
    for update in ("explicit", "implicit"):
        for z in (0.01, 0.03, 0.1, 0.3, 1.0, 1.9, 4.0):
            row = drag.relaxation_run(RUN, z, update, dt=z * tau, periods=5.0, min_steps=1)
            row["failed"] = row["failed"].split(":")[0] if row["failed"] else ""
            print(json.dumps(row), flush=True)


def auto(args):
    for update in ("explicit", "implicit"):
        for tau in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
            print(json.dumps(drag.auto_run(RUN, tau, update)), flush=True)


def settling(args):
    rows = []
    for closure in ("stokes", "wen_yu"):
        for theta0 in (0.05, 0.1, 0.2, 0.3, 0.4, 0.5):
            row = drag.settling_run(RUN, theta0, closure)
            print(json.dumps(row), flush=True)
            rows.append(row)
    if args.png:
        drag.settling_plot(rows, args.png)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("what", choices=("cost", "stability", "trade", "auto", "settling"))
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--steps", type=int, default=2000, help="cost: timed steps a run")
    p.add_argument("--png", default=None)
    args = p.parse_args()
    {"cost": cost, "stability": stability, "trade": trade, "auto": auto, "settling": settling}[args.what](args)


if __name__ == "__main__":
    main()
