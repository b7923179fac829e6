"""A 2-D bed past Wallis's bound on a floor, in the solved gas: its pressure drop against its buoyant weight, its
voids, its heights and the walls' backstop (docs/validation.md, "A bed past Wallis's bound").

    .venv/bin/python scripts/floor_bed.py [--U 0.15] [--Ly 0.02] [--L 0.08] [--Nx 400] [--G_b -3.0] [--t 1.5]
                                          [--from 0.5] [--set KEY=VALUE ...]

run/fluidized_bed_air.toml (0.3 mm grains in air, theta0 = 0.6, H0 = 3 cm) with ``gas.flow = "solved"`` and
the values given (the defaults: 2.2 U_mf, 2 cm wide, 15,000 particles) and any further ``--set``, one rank, to --t
(:func:`parsph.studies.voidage.floor_bed`). Prints per 0.1 s the smallest theta of the grid's cells below the
bed's median height (a void reads near 0; the packed bed 0.6), the heights below which 5%, 50% and 95% of the
mass lies and the pressure drop over the weight; then the drop averaged from --from to the end, and how many
times a grain was put back on a plate.
"""
import argparse

import numpy as np

from parsph.studies.voidage import floor_bed


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--U", type=float, default=0.15)
    ap.add_argument("--Ly", type=float, default=0.02)
    ap.add_argument("--L", type=float, default=0.08)
    ap.add_argument("--Nx", type=int, default=400)
    ap.add_argument("--G_b", type=float, default=-3.0)
    ap.add_argument("--t", type=float, default=1.5)
    ap.add_argument("--from", dest="t0", type=float, default=0.5)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a further run-file value")
    a = ap.parse_args()
    b = floor_bed([f"material.G_b={a.G_b!r}", f"domain.Ly={a.Ly!r}", f"domain.L={a.L!r}", f"numerics.Nx={a.Nx}",
                   f"gas.U={a.U!r}", *a.set], t_end=a.t)
    print("| t [s] | theta_min below the median height | h5 / h50 / h95 [mm] | drop / weight |")
    print("| --- | --- | --- | --- |")
    for t0 in np.arange(0.0, a.t - 1e-9, 0.1):
        s = (b.t >= t0) & (b.t < t0 + 0.1)
        h = 1e3 * b.heights[s].mean(axis=0)
        print(f"| {t0:.1f}-{t0 + 0.1:.1f} | {b.theta_min[s].min():.3f} | {h[0]:.2f} / {h[2]:.2f} / {h[4]:.2f} | "
              f"{b.drop[s].mean() / b.weight:.4f} |")
    m = b.mean_drop(a.t0)
    print(f"pressure drop averaged over {a.t0}-{a.t} s: {m:.2f} Pa, the buoyant weight {b.weight:.2f} Pa: "
          f"{100 * (m / b.weight - 1):+.2f}%; a grain put back on a plate {b.reflected} times")


if __name__ == "__main__":
    main()
