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
# Open MPI's shared-memory transport (vader, 4.x) sends messages of up to 4 KB
# eagerly and larger ones by rendezvous, which completes only while both ranks
# are inside MPI: the ghosts' rows of a step (about 10 KB on 2 ranks of the
# paper case) then wait for the later rank's whole Waitall. Eager up to 64 KB:
# the paper case on 2 ranks up to 21% faster (docs/performance.md). Another MPI
# ignores these variables.
export OMPI_MCA_btl_vader_eager_limit=${OMPI_MCA_btl_vader_eager_limit:-65536}
export OMPI_MCA_btl_vader_max_send_size=${OMPI_MCA_btl_vader_max_send_size:-65536}
