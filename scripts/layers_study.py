"""Layers under clear gas (docs/validation.md, "Layers under clear gas: sedimentation and fluidised beds"):
the runs of tests/test_layers_scenes.py, their numbers as a JSON file and two plots.

    .venv/bin/python scripts/layers_study.py [--out docs]

writes docs/layers_study.json, docs/sedimentation.png (interface height against time over Kynch's lines)
and docs/bed_expansion.png (eps against U over Richardson & Zaki's line). One rank; a few minutes.
"""
import argparse
import json
from pathlib import Path

from parsph.studies import layers

MIDPOINT = 'numerics.integrator="midpoint"'
SEDIMENTATION = [(0.1, 0.02), (0.15, 0.015), (0.2, 0.01)]      # (theta0, H0 [m])
BEDS = [(0.2, 0.3), (0.3, 0.45), (0.4, 0.45)]                  # (theta*, packed theta0)


def sedimentation_cases():
    out = []
    for theta0, H0 in SEDIMENTATION:
        L = round(H0 * 1.2 / 2e-4) * 2e-4
        out.append(layers.sedimentation(theta0, H0=H0, Ly=8e-4, settle=1.5,
                                        extra=[MIDPOINT, f"domain.L={L!r}", f"numerics.Nx={round(L / 2e-4)}",
                                               "checks.theta_change=6.0"]))
    return out


def bed_cases():
    return [layers.bed(theta_star=ts, H0=0.005, Ly=8e-4, t_end=1.5, n_times=3,
                       extra=[MIDPOINT, "domain.L=0.015", "numerics.Nx=75", f"material.theta0={t0}"])
            for ts, t0 in BEDS]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs", help="folder for the JSON and the plots")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    free = layers.free_surface(theta0=0.5, H0=0.005, t_end=0.3,
                               extra=[MIDPOINT, "domain.L=0.008", "numerics.Nx=40", "material.k=1.0"])
    print(f"free surface: top {[f'{t * 1e3:.3f}' for t in free['top']]} mm against {free['top_ref'] * 1e3:.3f}; "
          f"highest {max(free['highest']) * 1e3:.3f} mm, the end state's theta0/20 level "
          f"{free['low_ref'] * 1e3:.3f} mm; profile error {free['profile_error']:.2%}")
    seds = sedimentation_cases()
    for c in seds:
        print(f"theta0 = {c['theta0']}: H0 = {c['H0'] * 1e3:.0f} mm, t_m = {c['meeting_time']:.3f} s, "
              f"{c['steps']} steps; interface - Kynch: {[f'{e:+.2%}' for e in c['interface_errors']]} of H0; "
              f"end height {[f'{e:+.2%}' for e in c['end_height_errors']]} of H0; "
              f"interior profile {c['end_profile_error']:.2%}; floor theta {c['end_floor_theta']:.4f} "
              f"(ref {c['floor_theta_ref']:.4f})")
    beds = bed_cases()
    air = layers.bed(Ly=8e-4, t_end=0.3, n_times=3, path=layers.BED_AIR)
    for b in [*beds, air]:
        print(f"bed U = {b['U'] * 1e3:.2f} mm/s: theta* = {b['theta_star']:.4f}, interior mean "
              f"{b['means'][-1]:.4f}, max |theta/ODE - 1| {[f'{e:.2%}' for e in b['errors']]} at "
              f"{[round(t, 2) for t in b['times']]} s; top {b['tops'][-1] * 1e3:.3f} mm "
              f"(ODE {b['top_ref'] * 1e3:.3f}); l = {b['compression_length'] * 1e3:.3g} mm; {b['steps']} steps")
    ph = layers.layer.phases(layers.load(layers.BED, []))
    layers.plot_bed_expansion(beds, out / "bed_expansion.png", ph)
    layers.plot_sedimentation(seds, out / "sedimentation.png")
    drop = ("x", "theta")
    (out / "layers_study.json").write_text(json.dumps(
        {"free_surface": {k: v for k, v in free.items() if k not in drop},
         "sedimentation": seds, "beds": beds, "air": air}, indent=1, default=float))


if __name__ == "__main__":
    main()
