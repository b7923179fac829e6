#!/usr/bin/env bash
# Install whatever parsph needs and is missing; a second call with everything
# present returns in about a second.
#
#   system : Open MPI and parallel HDF5 (Debian: openmpi-bin libopenmpi-dev
#            libhdf5-openmpi-dev pkg-config), installed with apt-get as root
#   python : a virtual environment in .venv with scripts/requirements.txt,
#            h5py built against the MPI-enabled HDF5, and parsph (editable)
#   loops  : parsph's numba loops compiled into numba's cache (__pycache__
#            beside the sources) by tiny runs (parsph.cli.warm): the paper case
#            that scripts/main.sh runs (on 1 rank, then 2); with --suite (scripts/test.sh) also what
#            the test suite runs in launched processes and under mpirun, in one
#            process per core; again after a change of parsph/ or run/. Any
#            other case compiles at its first run, and says so.
#
#   bash scripts/setup.sh [--suite]
#
# Environment: PARSPH_VENV (default .venv), PARSPH_CACHE (default
# ~/.cache/parsph: the built h5py wheel, reused by later clones),
# HDF5_DIR (default: Debian's openmpi flavour), PYTHON (default python3).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${PARSPH_VENV:-$ROOT/.venv}
CACHE=${PARSPH_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/parsph}
HDF5_DIR=${HDF5_DIR:-/usr/lib/x86_64-linux-gnu/hdf5/openmpi}
PYTHON=${PYTHON:-python3}
APT_PACKAGES="openmpi-bin libopenmpi-dev libhdf5-openmpi-dev pkg-config"

say() { echo "setup: $*" >&2; }
die() { echo "setup: error: $*" >&2; exit 1; }

# Fingerprint of everything that decides the environment's content.
stamp_key=$(cat "$ROOT/scripts/requirements.txt" "$ROOT/pyproject.toml" "$ROOT/scripts/setup.sh" | sha256sum | cut -c1-16)
STAMP=$VENV/.parsph-setup-$stamp_key
# Fingerprint of what decides the compiled loops: parsph's sources and the run files warmed.
loops_key=$(cd "$ROOT" && find parsph run -name '*.py' -o -name '*.toml' | LC_ALL=C sort | xargs cat | sha256sum | cut -c1-16)
LOOPS=$VENV/.parsph-loops-$loops_key${NUMBA_CACHE_DIR:+-$(echo "$NUMBA_CACHE_DIR" | sha256sum | cut -c1-8)}
WARM=main  # the stamp $LOOPS-main: main.sh's case compiled; $LOOPS-suite: the test suite's too
WARM_ARGS=()
if [ "${1:-}" = "--suite" ]; then WARM=suite; WARM_ARGS=(--suite); fi
warm_loops() {
    [ -f "$LOOPS-$WARM" ] && return 0
    if [ "$WARM" = suite ]; then
        say "compiling the loops that main.sh and the test suite run into numba's cache (one process per core; once per change of parsph/ or run/)"
    else
        say "compiling the paper case's loops into numba's cache (about a minute, once per change of parsph/ or run/; other cases compile at their first run)"
    fi
    # (Open MPI's settings: the paper case also runs on 2 ranks, as main.sh runs it)
    (source "$ROOT/scripts/mpienv.sh" && "$VENV/bin/python" -m parsph.cli.warm "$ROOT/run" "${WARM_ARGS[@]}") \
        || die "compiling the loops failed"
    for f in "$VENV"/.parsph-loops-*; do  # the stamps of other sources
        case "$f" in "$LOOPS"-*) ;; *) rm -f "$f" ;; esac
    done
    touch "$LOOPS-main" "$LOOPS-$WARM"
}
if [ -f "$STAMP" ] && command -v mpirun >/dev/null && [ -x "$VENV/bin/parsph" ]; then
    warm_loops
    exit 0
fi

# --- system packages -------------------------------------------------------
have_system() {
    command -v mpirun >/dev/null && command -v mpicc >/dev/null && [ -f "$HDF5_DIR/include/H5pubconf.h" ] \
        && command -v pkg-config >/dev/null
}
if ! have_system; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        say "installing $APT_PACKAGES"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq --no-install-recommends $APT_PACKAGES >/dev/null
    else
        die "missing MPI or parallel HDF5; provide: Debian/Ubuntu packages '$APT_PACKAGES' (or, on a cluster, modules such as 'openmpi' and 'hdf5/parallel' with HDF5_DIR set to the parallel HDF5 prefix), then run this again"
    fi
    have_system || die "MPI or parallel HDF5 still missing after apt-get (HDF5_DIR=$HDF5_DIR)"
fi

# --- python environment ----------------------------------------------------
if [ ! -x "$VENV/bin/python" ]; then
    say "creating virtual environment $VENV"
    "$PYTHON" -m venv "$VENV" || die "'$PYTHON -m venv' failed (Debian: apt-get install python3-venv)"
fi
PY=$VENV/bin/python
say "installing Python packages"
"$PY" -m pip install -q --disable-pip-version-check -r "$ROOT/scripts/requirements.txt"

if ! "$PY" -c "import h5py, sys; sys.exit(0 if h5py.get_config().mpi else 1)" 2>/dev/null; then
    mkdir -p "$CACHE/wheels"
    hdf5_tag=$(dpkg-query -W -f='${Version}' libhdf5-openmpi-dev 2>/dev/null || echo custom)
    wheel_dir=$CACHE/wheels/hdf5-$hdf5_tag-$("$PY" -c 'import sys; print("py%d%d" % sys.version_info[:2])')
    if ! ls "$wheel_dir"/h5py-*.whl >/dev/null 2>&1; then
        say "building h5py against parallel HDF5 (about 4 minutes, once per machine)"
        mkdir -p "$wheel_dir"
        HDF5_MPI=ON HDF5_DIR=$HDF5_DIR CC=mpicc "$PY" -m pip wheel -q --disable-pip-version-check \
            --no-build-isolation --no-deps --no-binary=h5py -w "$wheel_dir" h5py
    fi
    "$PY" -m pip install -q --disable-pip-version-check --no-deps --force-reinstall "$wheel_dir"/h5py-*.whl
    "$PY" -c "import h5py, sys; sys.exit(0 if h5py.get_config().mpi else 1)" \
        || die "h5py was installed but is not MPI-enabled"
fi

"$PY" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$ROOT"
rm -f "$VENV"/.parsph-setup-*
touch "$STAMP"
warm_loops
say "ready: $VENV"
