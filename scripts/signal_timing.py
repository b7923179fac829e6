"""How long parsph takes from a signal to the end of every process, on 1 rank and under mpirun -n 2.

    PYTHONPATH=tests .venv/bin/python scripts/signal_timing.py [--grace S]

Starts the short paper box (tests/reliability_helpers: 560 particles, t_end =
0.5 s, no output before the end), waits for its first progress line, sends
the signal and prints, per case, the exit code, the seconds from the signal to
the end and parsph's stop line. tests/test_interrupt.py checks what happens;
this measures how fast (a time is no test on a loaded machine). ``--grace``
sets mpirun's delay from a signal to SIGTERM to the ranks, and on to SIGKILL
(Open MPI's odls_base_sigkill_timeout; 1 s by default).
"""
import argparse
import os
import sys
import tempfile
import time

try:  # the test suite's helpers, on the path as pytest puts them (PYTHONPATH=tests)
    from reliability_helpers import common as C
except ImportError:
    sys.exit("signal_timing.py: run it with PYTHONPATH=tests (it drives the suite's tests/reliability_helpers)")

LONG = (*C.SHORT, "output.t_end=0.5", "output.times=[0.5]", "output.progress_interval=0.05")


def to_ranks(which, sig):
    def send(live):
        pids = C.rank_pids(live.p.pid)
        for rank in (pids if which == "all" else [which]):
            os.kill(pids[rank], sig)
    return send


def measure(ranks, send, guard=300, **env):
    """(exit code, seconds from the signal to the end, parsph's lines) of one interrupted run."""
    with tempfile.TemporaryDirectory() as out:
        live = C.Live(C.run_cmd(ranks, "--out", out, *C.sets(*LONG)), **env)
        try:
            if not live.wait_for(lambda: any(ln.startswith("  step") for ln in live.out), guard):
                return None, None, ["no progress line"]
            t0 = time.monotonic()
            send(live)
            res, timed_out = live.finish(guard)
            took = time.monotonic() - t0
        finally:
            live.kill()
    return res.returncode, None if timed_out else took, C.parsph_lines(res.stderr)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grace", type=int, default=None, help="mpirun's odls_base_sigkill_timeout [s]")
    args = ap.parse_args(argv)
    env = {} if args.grace is None else {"OMPI_MCA_odls_base_sigkill_timeout": args.grace}
    cases = [("1 rank, SIGINT to parsph", 0, lambda live: live.p.send_signal(C.signal.SIGINT)),
             ("1 rank, SIGTERM to parsph", 0, lambda live: live.p.send_signal(C.signal.SIGTERM)),
             ("2 ranks, SIGINT to mpirun", 2, lambda live: live.p.send_signal(C.signal.SIGINT)),
             ("2 ranks, SIGTERM to mpirun", 2, lambda live: live.p.send_signal(C.signal.SIGTERM)),
             ("2 ranks, SIGTERM to each rank", 2, to_ranks("all", C.signal.SIGTERM)),
             ("2 ranks, SIGINT to rank 1 only", 2, to_ranks(1, C.signal.SIGINT))]
    for name, ranks, send in cases:
        rc, took, lines = measure(ranks, send, **env)
        when = "still running (killed)" if took is None else f"{took:.2f} s"
        print(f"{name}: exit {rc}, {when}: {' | '.join(lines)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
