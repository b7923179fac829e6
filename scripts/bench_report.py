"""Summarise scripts/bench.py records (JSON lines) as the performance tables of docs/performance.md.

    .venv/bin/python scripts/bench_report.py results/bench.json

Each configuration keeps its best record (highest rate) over the rounds of
scripts/bench_suite.sh. Two-rank efficiency is reported both ways: against
ideal (rate_2 / (2 rate_1)) and against the machine's measured ceiling for
two busy processes ((rate_a + rate_b) / rate_alone of two independent one-rank
runs at once, in the same round; the best round is kept).
"""
import json
import sys
from collections import defaultdict


def main(path):
    recs = [json.loads(line) for line in open(path) if line.strip()]
    by = defaultdict(dict)
    for r in recs:
        old = by[r["tag"]].get(r["nx"])
        if old is None or r["particle_steps_per_s"] > old["particle_steps_per_s"]:
            by[r["tag"]][r["nx"]] = r
    rounds = sorted({t.split()[-1] for t in by if t.startswith("alone")})
    print("| N_x | particles | ranks x threads | ms/step (CPU ms per rank) | particle-steps/s | steps per list build "
          "| outside the phases | density ns/pair (ref.) | forces ns/pair (ref.) | peak RSS B/particle (added by the run) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for tag in ("1 rank", "1 rank, 2 threads", "2 ranks"):
        for nx, r in sorted(by.get(tag, {}).items()):
            added = r.get("rss_added_bytes_per_particle")
            added = f" ({added:.0f})" if added is not None else ""
            cpu = r["cpu_s_per_step"] * 1e3 / r["ranks"]
            print(f"| {nx} | {r['particles']} | {r['ranks']} x {r.get('threads', 1)} | {r['step_s'] * 1e3:.2f} ({cpu:.2f}) | "
                  f"{r['particle_steps_per_s']:.3g} | {r.get('steps_per_rebuild', float('nan')):.1f} | "
                  f"{100 * r['outside_phases_share']:.1f}% | "
                  f"{r['ns_per_pair_density']:.1f} ({r['ns_per_pair_reference_density']:.1f}) | "
                  f"{r['ns_per_pair_forces']:.1f} ({r['ns_per_pair_reference_forces']:.1f}) | "
                  f"{r['rss_bytes_per_particle']:.0f}{added} |")
    print()
    print("| N_x | phase breakdown, 1 rank [ms/step] | JIT + set-up [s] |")
    print("| --- | --- | --- |")
    for nx, r in sorted(by.get("1 rank", {}).items()):
        ph = ", ".join(f"{k} {v * 1e3:.2f}" for k, v in r["phases_s"].items() if k not in ("output", "checks"))
        print(f"| {nx} | {ph} | {r['jit_s']:.1f} |")
    ceilings = []
    for k in rounds:
        alone, a, b = by.get(f"alone {k}", {}), by.get(f"pair-a {k}", {}), by.get(f"pair-b {k}", {})
        for nx in sorted(set(alone) & set(a) & set(b)):
            ceilings.append((nx, (a[nx]["particle_steps_per_s"] + b[nx]["particle_steps_per_s"])
                             / alone[nx]["particle_steps_per_s"]))
    ceiling = max(c for _, c in ceilings) if ceilings else None
    if ceiling:
        print(f"\nTwo independent one-rank runs at once (N_x = {ceilings[0][0]}) reached "
              + ", ".join(f"{c:.2f}x" for _, c in ceilings) + " the throughput of one (per round).")
    print("\n| N_x | speed-up over 1 rank | efficiency vs ideal | efficiency vs measured ceiling |")
    print("| --- | --- | --- | --- |")
    for tag in ("2 ranks", "1 rank, 2 threads"):
        for nx, r2 in sorted(by.get(tag, {}).items()):
            r1 = by.get("1 rank", {}).get(nx)
            if r1:
                s = r2["particle_steps_per_s"] / r1["particle_steps_per_s"]
                vs = f"{100 * s / ceiling:.0f}%" if ceiling else "-"
                print(f"| {nx}, {tag} | {s:.2f} | {100 * s / 2:.0f}% | {vs} |")
    # the exchanges (sync: ghosts' positions, validity test, all-reduce; halo: ghosts' rho) and the
    # list builds (migration included): the slowest rank's time per step (waiting for the other rank
    # included) and, where recorded, the least over ranks (closer to the messages' own cost)
    print("\n| N_x | ranks x threads | step [ms] | sync [ms] | rho exchange [ms] | list builds [ms] | share of the step "
          "| least over ranks |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for tag in ("1 rank", "2 ranks"):
        for nx, r in sorted(by.get(tag, {}).items()):
            ph, lo = r["phases_s"], r.get("phases_min_s")
            comm = lambda q: q["sync"] + q["halo"] + q["rebuild"]  # noqa: E731
            least = f"{100 * comm(lo) / r['step_s']:.1f}%" if lo else "-"
            print(f"| {nx} | {r['ranks']} x {r.get('threads', 1)} | {r['step_s'] * 1e3:.2f} | {ph['sync'] * 1e3:.2f} | "
                  f"{ph['halo'] * 1e3:.2f} | {ph['rebuild'] * 1e3:.2f} | {100 * comm(ph) / r['step_s']:.1f}% | {least} |")
    print(f"\nMachine: {recs[0]['machine']}")


if __name__ == "__main__":
    main(sys.argv[1])
