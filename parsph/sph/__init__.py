"""SPH on one rank: particle storage, the neighbour list, the passes of Eqs. (3) and (5) and their data,
the integrators of Eqs. (6)-(7), the profile binning.

May import: :mod:`parsph.physics`. Never MPI: ghosts and images are ordinary particles here.
"""
