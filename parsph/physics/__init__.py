"""The physics of the paper without particles or MPI: kernels (Eq. 4), closures, Table 1, the analytic
references (Eq. 8 and the other scenes'), lattice sums of the kernels, and the time-step limits.

May import: numpy, numba, and nothing of parsph outside this package.
"""
