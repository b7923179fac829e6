"""Summarise scripts/bench.py records (JSON lines) as the README's performance tables.

    .venv/bin/python scripts/bench_report.py results/bench.json

Two-rank efficiency is reported both ways: against ideal (rate_2 / (2 rate_1))
and against the machine's measured ceiling for two busy processes
((rate_a + rate_b) / rate_alone of two independent one-rank runs at once).
"""
import json
import sys
from collections import defaultdict


def main(path):
    recs = [json.loads(line) for line in open(path) if line.strip()]
    by = defaultdict(dict)
    for r in recs:
        by[r["tag"]][r["nx"]] = r
    print("| N_x | particles | ranks | ms/step | particle-steps/s | outside numba | density ns/pair (ref.) "
          "| forces ns/pair (ref.) | RSS B/particle |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for tag in ("1 rank", "2 ranks"):
        for nx, r in sorted(by.get(tag, {}).items()):
            print(f"| {nx} | {r['particles']} | {r['ranks']} | {r['step_s'] * 1e3:.2f} | "
                  f"{r['particle_steps_per_s']:.3g} | {100 * r['outside_numba_share']:.1f}% | "
                  f"{r['ns_per_pair_density']:.1f} ({r['ns_per_pair_reference_density']:.1f}) | "
                  f"{r['ns_per_pair_forces']:.1f} ({r['ns_per_pair_reference_forces']:.1f}) | "
                  f"{r['rss_bytes_per_particle']:.0f} |")
    print()
    print("| N_x | phase breakdown, 1 rank [ms/step] | JIT + set-up [s] |")
    print("| --- | --- | --- |")
    for nx, r in sorted(by.get("1 rank", {}).items()):
        ph = ", ".join(f"{k} {v * 1e3:.2f}" for k, v in r["phases_s"].items() if k not in ("output", "checks"))
        print(f"| {nx} | {ph} | {r['jit_s']:.1f} |")
    ceiling = None
    if "alone" in by and "pair-a" in by and "pair-b" in by:
        nx = sorted(by["alone"])[0]
        ceiling = (by["pair-a"][nx]["particle_steps_per_s"] + by["pair-b"][nx]["particle_steps_per_s"]) \
            / by["alone"][nx]["particle_steps_per_s"]
        print(f"\nTwo independent one-rank runs at once (N_x = {nx}) reach {ceiling:.2f}x the throughput of one.")
    print("\n| N_x | 2-rank speed-up | efficiency vs ideal | efficiency vs measured ceiling |")
    print("| --- | --- | --- | --- |")
    for nx, r2 in sorted(by.get("2 ranks", {}).items()):
        r1 = by.get("1 rank", {}).get(nx)
        if r1:
            s = r2["particle_steps_per_s"] / r1["particle_steps_per_s"]
            vs = f"{100 * s / ceiling:.0f}%" if ceiling else "-"
            print(f"| {nx} | {s:.2f} | {100 * s / 2:.0f}% | {vs} |")
    print(f"\nMachine: {recs[0]['machine']}")


if __name__ == "__main__":
    main(sys.argv[1])
