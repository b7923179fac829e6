# Sourced by the scripts: settings for running Open MPI here.
# Root in a container needs Open MPI's explicit consent; more ranks than cores
# need --oversubscribe (the scripts pass $PARSPH_MPIRUN_FLAGS to mpirun).
if [ "$(id -u)" = 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
# numba's OpenMP threads (parsph run --threads N) sleep instead of spinning
# while they wait: spinning threads ran many times slower on these VMs
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
export PARSPH_MPIRUN_FLAGS=${PARSPH_MPIRUN_FLAGS:---oversubscribe}
