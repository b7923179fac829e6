"""Run several ``parsph`` command lines in one Python process: one start-up instead of one each.

    python tests/mpi_helpers/cli_batch.py < cases.json > results.json

stdin: {name: [argv ...]}; stdout: {name: [exit code, stdout, stderr]}, each case's
streams captured apart. A case ends as ``python -m parsph`` would: main's return
value, argparse's SystemExit code, or an uncaught exception's traceback on its
stderr and code 1. Used by test_config_errors.py (bad input: no run starts, so
the cases cannot disturb each other).
"""
import contextlib
import io
import json
import sys
import traceback

from parsph.cli import main


def run_case(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except BaseException:  # noqa: BLE001 - reported as the process would report it
            traceback.print_exc()
            code = 1
    return [code, out.getvalue(), err.getvalue()]


if __name__ == "__main__":
    cases = json.load(sys.stdin)
    results = {name: run_case(argv) for name, argv in cases.items()}
    sys.stdout.write(json.dumps(results))
