# Sourced by the scripts: settings for running Open MPI here.
# Root in a container needs Open MPI's explicit consent; more ranks than cores
# need --oversubscribe (the scripts pass $PARSPH_MPIRUN_FLAGS to mpirun).
if [ "$(id -u)" = 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
# numba: no busy-waiting worker threads competing with the MPI ranks
export NUMBA_NUM_THREADS=${NUMBA_NUM_THREADS:-1} OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
export PARSPH_MPIRUN_FLAGS=${PARSPH_MPIRUN_FLAGS:---oversubscribe}
