"""The time per step against the rank count P: a model from measured per-rank costs (docs/scaling.md).

    .venv/bin/python scripts/scaling_model.py --inputs2d docs/scaling/round_*_inputs_2d.json \\
        --inputs3d docs/scaling/inputs_3d.json --migration docs/scaling/migration.json \\
        --threads docs/scaling/threads.json [--alpha 2e-6 --bandwidth 1.25e10 --alpha-allreduce 2.5e-6] \\
        [--check docs/scaling/round_*_paper.json] [--counts docs/scaling/counts_*.json]

The model, its inputs and how they are fitted: parsph.studies.scaling_model.
"""
import argparse
import json

import numpy as np

from parsph.studies.scaling_model import (Case, check, counts, fit, fit_migration, fitted, inputs_table, load,
                                          strong, thread_ratios, weak)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--inputs2d", nargs="+", required=True,
                    help="scaling.py records at P = 1, 2-D, two or more sizes (JSON lines)")
    ap.add_argument("--inputs3d", nargs="+", required=True, help="the same in 3-D")
    ap.add_argument("--thread-factor", type=float, help="instead of the measured median (--threads)")
    ap.add_argument("--migration", nargs="+", required=True,
                    help="scaling.py inputs records at P = 2 (the migration's cost per list build)")
    ap.add_argument("--threads", nargs="+", metavar="ONE TWO",
                    help="pairs of scaling.py records of one size at P = 1 with --threads 1 and 2: the median "
                         "ratio of their pair passes' CPU per pair")
    ap.add_argument("--alpha", type=float, default=2e-6, help="point-to-point latency per round [s]")
    ap.add_argument("--alpha-allreduce", type=float, default=2.5e-6, help="latency per all-reduce stage [s]")
    ap.add_argument("--bandwidth", type=float, default=1.25e10, help="bandwidth per rank [bytes/s]")
    ap.add_argument("--cores-per-node", type=int, default=64)
    ap.add_argument("--check", nargs="*", default=[], help="scaling.py records of the paper case (P = 1, 2)")
    ap.add_argument("--alpha-here", type=float, default=4e-6, help="latency per round on the checking machine")
    ap.add_argument("--paper-s", type=float, default=56.2, help="steps per list build, the paper case")
    ap.add_argument("--big-s", type=float, default=1000.0, help="steps per list build, the large cases")
    ap.add_argument("--counts", nargs="*", default=[], help="scaling.py records whose counts to tabulate")
    a = ap.parse_args()
    if a.counts:
        print(counts([r for path in a.counts for r in load(path)]) + "\n")
    k2 = fit([r for path in a.inputs2d for r in load(path)])
    k3 = fit([r for path in a.inputs3d for r in load(path)], fixed=k2)
    mig = fit_migration([r for path in a.migration for r in load(path)])
    k2.update(mig)
    k3.update(mig)
    k2["thread_factor"] = k3["thread_factor"] = 1.0
    if a.threads:
        ratios = thread_ratios(a.threads)
        print(f"thread_factor from {len(ratios)} pairs: " + ", ".join(f"{r:.2f}" for r in ratios))
        k2["thread_factor"] = k3["thread_factor"] = float(np.median(ratios))
    if a.thread_factor:
        k2["thread_factor"] = k3["thread_factor"] = a.thread_factor
    print(fitted(k2, k3, a.inputs2d, a.inputs3d))
    print("\n" + inputs_table(k2, k3))
    net = dict(alpha=a.alpha, bandwidth=a.bandwidth, alpha_ar=a.alpha_allreduce)
    paper = Case("paper", 2, 50, 50)
    for line in check(a.check, k2, a.alpha_here, a.bandwidth):
        print(line)
    big = Case("3-D Couette", 3, 200, 220, 220)
    for title, case, k, s in (("Strong: the paper case", paper, k2, a.paper_s),
                              ("Strong: 3-D Couette", big, k3, a.big_s)):
        text, limit = strong(case, k, s, net, a.cores_per_node)
        print(f"\n### {title}: N = {case.N:,}, p = {case.p:.2f}, X = {case.X:,.0f}, slab limit {limit} ranks, "
              f"s = {s:g}\n\n{text}")
    print(f"\n### Weak, 2-D: N_x = 1000, 994 rows per rank (1,000,000 particles per rank), s = {a.big_s:g}\n")
    print(weak(lambda P: Case("w2", 2, 1000, 994 * P), k2, a.big_s, net))
    print(f"\n### Weak, 3-D: N_x = 200, N_z = 220, 22 rows per rank (997,040 particles per rank), s = {a.big_s:g}\n")
    print(weak(lambda P: Case("w3", 3, 200, 22 * P, 220), k3, a.big_s, net))
    print(json.dumps({"k2": k2, "k3": k3}))


if __name__ == "__main__":
    main()
