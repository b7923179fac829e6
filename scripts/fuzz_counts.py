"""Run the input fuzz tests and print how many cases each property tried.

    .venv/bin/python scripts/fuzz_counts.py [PYTEST ARGS]    # e.g. -k "not cli" for the in-process ones

tests/test_input_fuzz.py counts its cases in ``COUNTS`` (one key per property
or group of fixed cases); this runs the module with pytest in this process and
prints those counts, so that the number of cases a run tries can be quoted.
Exits with pytest's exit code.
"""
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(argv):
    rc = pytest.main(["-q", "-p", "no:cacheprovider", os.path.join(ROOT, "tests", "test_input_fuzz.py"), *argv])
    module = sys.modules.get("test_input_fuzz")
    counts = getattr(module, "COUNTS", {})
    for what, n in sorted(counts.items()):
        print(f"fuzz cases: {what}: {n}")
    print(f"fuzz cases: total: {sum(counts.values())}")
    return int(rc)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
