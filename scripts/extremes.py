"""The solved gas at its extremes (docs/validation.md, "At the extremes"): each case on one rank, a table of
whether the state stayed finite, the grains between the plates, the largest theta, the smallest step, the
walls' backstop and the wall time.

    .venv/bin/python scripts/extremes.py [--only NAME ...]

The cases (:mod:`parsph.studies.extremes`):
- jet: run/single_bubble.toml with its orifice blowing 10 U_mf (2.128 m/s) without end, to 0.3 s;
- contrast: run/bubbling_bed.toml with K_max = 10^6 K(theta0) (1000 times its default), to 0.5 s: the
  bubbles' clear gas a million times more permeable than the bed, and the bubbles erupting at its top;
- jet+contrast: both at once, to 0.3 s.
"""
import argparse

from parsph.studies import extremes


def cases():
    cap = extremes.default_cap(extremes.BUBBLING)
    jet = f"gas.jet=[0.035, 0.045, {10 * extremes.minimum_fluidization(extremes.SINGLE_BUBBLE)!r}]"
    contrast = f"gas.K_max={1000 * cap!r}"
    return {
        "jet": (extremes.SINGLE_BUBBLE, [jet], 0.3),
        "contrast": (extremes.BUBBLING, [contrast, "checks.settle=0.0"], 0.5),
        "jet+contrast": (extremes.SINGLE_BUBBLE, [jet, contrast], 0.3),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="*", default=None, help="the cases to run (default: all)")
    a = ap.parse_args()
    print("| case | to t [s] | steps | finite | grains between the plates (lowest, highest / L) | theta max | "
          "dt min [s] | backstop | wall time [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, (path, sets, t_end) in cases().items():
        if a.only and name not in a.only:
            continue
        e = extremes.run(name, path, sets, t_end)
        print(f"| {name} | {e.t_end:g} | {e.steps} | {'yes' if e.finite else 'NO'} | "
              f"{'yes' if e.held else 'NO'} ({e.x_min / e.L:.4f}, {e.x_max / e.L:.4f}) | {e.theta_max:.3f} | "
              f"{e.dt_min:.3g} | {e.reflected} | {e.seconds:.0f} |", flush=True)


if __name__ == "__main__":
    main()
