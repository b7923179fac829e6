"""The peer for speed ratios: PySPH 1.0b2's Couette example (TVFScheme, cubic spline, serial) at the
resolution of parsph's benchmark case, in fluid particle-steps per second.

    python3 -m venv V && V/bin/pip install pysph==1.0b2     # about 5 minutes, once
    V/bin/python scripts/pysph_peer.py --nx 50 100 [--steps 2000] [--json FILE]

PySPH's example (pysph/examples/couette.py) is taken as it is but for its resolution: the channel
(width 1) is resolved by N_x fluid columns (dx = 1 / N_x), the periodic length is the width, so
that the box holds N_x x N_x fluid particles, as parsph's ``scripts/bench.py --nx N_x`` case
(L_y = L), and h = 1.25 dx as there (the same neighbours per particle). Each size runs twice (the first compiles PySPH's generated code into its cache); the
second is timed around the solver's loop, ``--steps`` steps, no output. Compare with parsph's
fluid particle-steps per second from bench.py, the two runs alternated on the same machine (docs/performance.md).
"""
import argparse
import json
import sys
import tempfile
import time


HDX = 1.25  # h / dx of parsph's case (the example's own 1.0 gives each particle about half the neighbours)


def run(nx, steps):
    import pysph.examples.couette as ex
    from pysph.base.kernels import CubicSpline

    dx = 1.0 / nx
    ex.dx = dx
    ex.hdx = HDX
    ex.Ly = 1.0
    ex.d = 0.5
    ex.Lx = 1.0
    ex.ghost_extent = 5 * dx
    ex.h0 = ex.hdx * dx
    ex.dt = min(0.25 * ex.h0 / (ex.c0 + ex.Vmax), 0.125 * ex.h0 ** 2 / ex.nu)

    class Peer(ex.CouetteFlow):
        def create_scheme(self):
            s = super().create_scheme()
            s.configure_solver(tf=steps * ex.dt, dt=ex.dt, kernel=CubicSpline(dim=2))
            return s

    out = tempfile.mkdtemp(prefix="pysph_peer_")
    app = Peer(fname="couette_peer", output_dir=out)
    argv = ["--disable-output", "--max-steps", str(steps), "-q", "--kernel", "CubicSpline"]
    app.setup(argv=argv)
    t0 = time.perf_counter()
    app.solver.solve()
    wall = time.perf_counter() - t0
    fluid = app.particles[0].num_real_particles  # without the periodic ghosts
    done = app.solver.count
    return {"nx": nx, "fluid": int(fluid), "steps": int(done), "wall_s": wall,
            "fluid_particle_steps_per_s": fluid * done / wall, "dt": ex.dt, "output_dir": out,
            "note": "pysph 1.0b2 TVFScheme couette, cubic spline, serial"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nx", type=int, nargs="+", default=[50, 100])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--json", help="append one JSON record per size")
    a = ap.parse_args()
    for nx in a.nx:
        run(nx, 20)  # compile PySPH's generated code (cached) and warm up
        r = run(nx, a.steps)
        print(f"PySPH N_x={nx}: {r['fluid']} fluid particles, {r['steps']} steps in {r['wall_s']:.2f} s: "
              f"{r['fluid_particle_steps_per_s']:.3g} fluid particle-steps/s", flush=True)
        if a.json:
            with open(a.json, "a") as f:
                f.write(json.dumps(r) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
