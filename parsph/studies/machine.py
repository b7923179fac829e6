"""The machine and the code a measurement ran on, for the records of the benchmarks and studies.

One home for what every benchmark writes beside its figures (the processor,
numba's threading layer, the memory in use, the commit), so that records made
by different scripts name the machine the same way.
"""
import os
import platform
import resource
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]   # the checkout parsph runs from (its scripts/, run/, docs/)


def cpu_model():
    """The 'model name' line of /proc/cpuinfo (where there is none: platform's processor or machine)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def threading_layer():
    """numba's threading layer ('none' before any parallel region has run)."""
    import numba
    try:
        return numba.threading_layer()
    except ValueError:
        return "none"


def current_rss():
    """Resident set size of this process now [bytes]."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def peak_rss():
    """Peak resident set size of this process so far [bytes] (getrusage's ru_maxrss)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def commit(repo=REPO, describe=False):
    """The short commit of ``repo`` ('git describe --always --dirty' with ``describe``); '' outside git."""
    args = ["describe", "--always", "--dirty"] if describe else ["rev-parse", "--short", "HEAD"]
    try:
        return subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""
