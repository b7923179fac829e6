"""One run of the accuracy/speed sweep (scripts/sweep.py), in its own process.

    [PYTHONPATH=DIR/code] .venv/bin/python scripts/sweep_run.py '{"Nx": 50, "kernel": "cubic_spline", ...}' [--profiles DIR]

Runs the choices given (parsph.studies.sweep: the Couette case of Table 1 with
the run's numerics, one rank, no files but the profiles) and prints its record
as one JSON line. scripts/sweep.py puts its snapshot of parsph (DIR/code) first
on PYTHONPATH, ahead of the installed working tree.
"""
import json
import sys

from parsph.studies.sweep import run_choices


def main(argv):
    run = json.loads(argv[1])
    prof_dir = argv[argv.index("--profiles") + 1] if "--profiles" in argv else None
    print(json.dumps(run_choices(run, prof_dir)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
