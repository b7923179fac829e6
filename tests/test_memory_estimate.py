"""The memory estimate that refuses runs too large for the nodes (``memory.bytes_per_particle``) against
the memory a real set-up takes.

A fresh process builds the paper case (2-D) and 3-D Couette at two sizes each,
takes three steps and one more evaluation (a list build, ghosts, both passes),
and reports the peak resident memory that each added: the kernel's high-water
mark (VmHWM, reset through /proc/self/clear_refs before each size) minus the
resident memory before it. glibc is told to map every block above 64 KiB
on its own (MALLOC_MMAP_THRESHOLD_), so that memory freed by the first size
goes back to the system instead of serving the second. Per particle: the peak
of the larger size over its particles, and the slope between the two sizes
(fixed costs cancel). The estimate must bound both and be at most 2.5x the
slope (measured, one thread: 2-D 742 B slope against 1266 B, 3-D 1.96 KB
against 3.10 KB; two threads: 1.03 KB against 2.02 KB, 3.39 KB against
5.34 KB). test_input_fuzz.py checks the refusal given the estimate; this checks
the estimate.
"""
import json
import os
import subprocess
import sys

import pytest

from conftest import ROOT, cli_env

CHILD = r"""
import gc, json, sys
from mpi4py import MPI
import numba
from parsph.setup import config, memory
from parsph.simulation.solver import Simulation


def status(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024


def run(path, over):
    cfg = config.load(path, [*over, "output.times=[]"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    for _ in range(3):
        sim.compute_rates()
        sim.integrate(sim.dt)
    sim.compute_rates()
    return cfg, sim


numba.set_num_threads(int(sys.argv[1]))
out = {}
for name, path, sizes in json.loads(sys.argv[2]):
    run(path, sizes[0])  # load the compiled passes of this scene
    out[name] = []
    for over in sizes[1:]:
        gc.collect()
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # VmHWM := VmRSS
        before = status("VmRSS")
        cfg, sim = run(path, over)
        out[name].append([cfg.n_particles, status("VmHWM") - before, memory.bytes_per_particle(cfg, numba.get_num_threads())])
        del sim
        gc.collect()
print(json.dumps(out))
"""

CASES = [  # name, run file, [warm-up, smaller, larger] overrides
    ("2-D", str(ROOT / "run" / "couette_paper.toml"), [["domain.Ly=0.002"], ["domain.Ly=0.04"], ["domain.Ly=0.12"]]),
    ("3-D", str(ROOT / "run" / "couette_3d.toml"),
     [[], ["domain.Ly=0.0032", "domain.Lz=0.0032"], ["domain.Ly=0.0048", "domain.Lz=0.0048"]]),
]


def measure(threads):
    """{case: (estimate, peak of the larger size per particle, slope per particle)} [bytes]."""
    env = cli_env()
    env.update(NUMBA_NUM_THREADS=str(max(threads, 1)), MALLOC_MMAP_THRESHOLD_="65536", OMP_NUM_THREADS="1")
    p = subprocess.run([sys.executable, "-c", CHILD, str(threads), json.dumps(CASES)], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    out = {}
    for name, ((n1, m1, est), (n2, m2, _)) in json.loads(p.stdout.splitlines()[-1]).items():
        assert n2 > 2 * n1
        out[name] = (est, m2 / n2, (m2 - m1) / (n2 - n1))
    return out


needs_proc = pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="needs Linux's /proc/self/clear_refs")


@needs_proc
@pytest.mark.parametrize("threads", [1, 2])
def test_estimate_bounds_the_measured_memory(threads):
    """The estimate (threads included: the threaded passes' per-pair arrays) bounds the measured peak and
    slope per particle, and is at most 2.5x the slope."""
    for name, (est, peak, slope) in measure(threads).items():
        assert peak <= est and slope <= est, f"{name}: estimate {est:.0f} B, measured {peak:.0f} B peak, " \
                                             f"{slope:.0f} B slope per particle"
        assert est <= 2.5 * slope, f"{name}: estimate {est:.0f} B is more than 2.5x the measured {slope:.0f} B"
