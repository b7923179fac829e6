"""Strong and weak scaling: time per step, ghosts, pairs and messages against the rank count.

    .venv/bin/python scripts/scaling.py strong --nx 50 --ranks 1 2 4 8 --set numerics.dt=1e-5 [--out results]
    .venv/bin/python scripts/scaling.py weak --nx 100 --ly-per-rank 0.0025 --max-ranks 16
    .venv/bin/python scripts/scaling.py inputs --nx 10 20 100 200 [--ranks 2]

strong: the same problem (the Couette case of ``scripts/bench.py``: N_x,
L_y = L, h = 1.25 dx, dt = "auto" unless ``--set``) on P = 1, 2, ... ranks;
efficiency T_1 / (P T_P). weak: L_y = P * ly-per-rank, the same particles
per rank; efficiency T_1 / T_P. inputs: several sizes in one process, their
timed blocks in turn, so that a drift of the machine's speed hits all alike
(the per-unit costs of scripts/scaling_model.py). Each P runs this script's
``worker`` under ``mpirun -n P`` (``--oversubscribe`` where ranks exceed
cores: then the counts are right and the times are not).

The worker takes ``--warmup`` steps, then ``--blocks`` blocks of
``--block`` steps, and records per rank what parsph.studies.scaling lists
(times per step, phases, messages, counts, a lone ghost round).
Writes OUTDIR/scaling_<mode>.json (one record per P and size, every rank's
figures), and for strong and weak a .csv (one row per P, the busiest rank)
and a .png, the machine named.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

from parsph.studies import scaling  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=("strong", "weak", "inputs", "worker"))
    ap.add_argument("--nx", type=int, nargs="+", default=[200],
                    help="lattice columns (inputs: several sizes, run in one process, blocks in turn)")
    ap.add_argument("--max-ranks", type=int, default=4)
    ap.add_argument("--ranks", type=int, nargs="*", help="explicit rank counts (default 1, 2, 4, ... max)")
    ap.add_argument("--ly-per-rank", type=float, default=0.0025, help="weak scaling: L_y per rank [m]")
    ap.add_argument("--set", action="append", default=[], help="run-file overrides (bench.py's case)")
    ap.add_argument("--warmup", type=int, default=200, help="steps before timing (past the impulsive start)")
    ap.add_argument("--blocks", type=int, default=10)
    ap.add_argument("--block", type=int, default=50, help="steps per timed block")
    ap.add_argument("--reps", type=int, default=200, help="repetitions of the lone ghost round")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", default="results")
    ap.add_argument("--json", help=argparse.SUPPRESS)
    ap.add_argument("--tag", default="", help=argparse.SUPPRESS)
    ap.add_argument("--mpirun", default="mpirun", help="launcher (e.g. 'srun' on a cluster)")
    a = ap.parse_args()
    if a.mode == "worker":
        lines = scaling.measure(a.nx, a.set, a.warmup, a.blocks, a.block, a.reps, a.threads, a.tag)
        if lines is not None:
            with open(a.json, "w") as f:
                f.write("\n".join(lines) + "\n")
        return 0
    if a.mode != "inputs" and len(a.nx) > 1:
        ap.error("strong and weak take one --nx")
    ranks = a.ranks or sorted({1, *[2 ** k for k in range(1, 13) if 2 ** k <= a.max_ranks], a.max_ranks})
    if a.mode == "inputs":
        ranks = a.ranks or [1]
    os.makedirs(a.out, exist_ok=True)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               NUMBA_NUM_THREADS=str(a.threads), OMP_WAIT_POLICY="passive")
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    records = []
    for p in ranks:  # the slab limit, before any launch
        sets = a.set + ([f"domain.Ly={a.ly_per_rank * p}"] if a.mode == "weak" else [])
        for nx in a.nx:
            why = scaling.slabs_refused(p, nx, sets)
            if why:
                print(f"scaling.py: {why}", file=sys.stderr)
                return 2
    for p in ranks:
        with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tmp:
            jpath = tmp.name
        cmd = [a.mpirun, "-n", str(p)]
        if a.mpirun == "mpirun":
            cmd += ["-x", "PYTHONPATH"] + (["--oversubscribe"] if p > (os.cpu_count() or 1) else [])
        sets = a.set + ([f"domain.Ly={a.ly_per_rank * p}"] if a.mode == "weak" else [])
        cmd += [sys.executable, os.path.abspath(__file__), "worker", "--nx", *map(str, a.nx), "--json", jpath,
                "--tag", a.mode, "--warmup", str(a.warmup), "--blocks", str(a.blocks), "--block", str(a.block),
                "--reps", str(a.reps), "--threads", str(a.threads)] + [f"--set={s}" for s in sets]
        print(" ".join(cmd), flush=True)
        rc = subprocess.run(cmd, env=env).returncode
        if rc:
            sys.exit(f"scaling.py: mpirun -n {p} failed (exit {rc}); its message is above")
        records += [json.loads(line) for line in open(jpath) if line.strip()]
        os.unlink(jpath)
    base = os.path.join(a.out, f"scaling_{a.mode}")
    with open(base + ".json", "w") as f:
        for r in records:
            f.write(json.dumps(r) + "\n")
    if a.mode == "inputs":
        for r in records:
            x = r["per_rank"][0]
            print(f"N_x={r['nx']:4d} P={r['ranks']} CPU {x['cpu_s_per_step'] * 1e3:8.3f} ms/step  "
                  f"pairs {x['pairs']:9d}  local {x['local']:8d}  phases (CPU ms) " +
                  " ".join(f"{k} {v * 1e3:.3f}" for k, v in x["phases_cpu_s"].items()) +
                  f"  {r['steps_per_rebuild']:.1f} steps/build")
        print(f"wrote {base}.json")
        return 0
    rows = scaling.write_table(records, a.mode, a.nx[0], a.set, base)
    for o in rows:
        print(f"P={o['ranks']:4d}  {o['step_best_block_s'] * 1e3:9.3f} ms/step (fastest block)  "
              f"CPU {o['cpu_s_per_step_max'] * 1e3:8.3f} ms  ghosts {o['ghosts_max']:7d}  "
              f"pairs {o['pairs_max']:9d}  {o['steps_per_rebuild']:.1f} steps/rebuild  "
              f"efficiency {o['efficiency']:.2f}")
    print(f"wrote {base}.csv, .json and .png ({scaling.machine()})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
