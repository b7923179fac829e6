"""One run of the accuracy/speed sweep (scripts/sweep.py), in its own process.

    .venv/bin/python scripts/sweep_run.py '{"Nx": 50, "kernel": "cubic_spline", ...}' [--profiles DIR] [--code DIR]

Runs the choices given (parsph.studies.sweep: the Couette case of Table 1 with
the run's numerics, one rank, no files but the profiles) and prints its record
as one JSON line. ``--code DIR``: import parsph from DIR (the snapshot
scripts/sweep.py makes), ahead of the working tree's.
"""
import json
import os
import sys

if "--code" in sys.argv:  # a snapshot of parsph (scripts/sweep.py makes one), ahead of the working tree
    sys.path.insert(0, os.path.abspath(sys.argv[sys.argv.index("--code") + 1]))

from parsph.studies.sweep import run_choices  # noqa: E402


def main(argv):
    run = json.loads(argv[1])
    prof_dir = argv[argv.index("--profiles") + 1] if "--profiles" in argv else None
    print(json.dumps(run_choices(run, prof_dir)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
