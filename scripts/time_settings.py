"""Time Couette settings the way the sweep does, several times each: the cost comparison of
`parsph converge --target` (docs/accuracy.md, "Picking a setting for a target error").

    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/time_settings.py [--repeats 5] [--t 0.05] RUN_JSON ...

Each RUN_JSON is a scripts/sweep_run.py choice set ('{"Nx": 35, "kernel": "wendland_c2", ...}');
each is run REPEATS times in fresh processes (sweep_run.py: one rank, untimed warm-up,
no files), and the fewest process CPU seconds of the time loop to t = T and the max
error there against Eq. (8) are printed (the error is the same in every repeat).
"""
import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--t", type=float, default=0.05)
    args = ap.parse_args()
    for text in args.runs:
        run = json.loads(text)
        run.setdefault("t_end", args.t)
        cpus, err, steps = [], None, None
        for _ in range(args.repeats):
            p = subprocess.run([sys.executable, os.path.join(HERE, "sweep_run.py"), json.dumps(run)],
                               capture_output=True, text=True, cwd=os.path.dirname(HERE))
            rec = json.loads([ln for ln in p.stdout.splitlines() if ln.startswith("{")][-1])
            out = [o for o in rec["outputs"] if abs(o["t"] - args.t) < 1e-12][0]
            cpus.append(out["cpu_s"])
            err, steps = out["err_max"], out["step"]
        print(json.dumps({"run": run, "t": args.t, "err_max": err, "steps": steps, "particles": rec["n_particles"],
                          "cpu_min": min(cpus), "cpu_all": cpus, "code": rec["code"]}), flush=True)


if __name__ == "__main__":
    main()
