"""The decomposition into slabs along y over MPI: slab arithmetic, the halo's message rows, the slab ring
(migration, ghosts, images), and the collective reductions.

May import: mpi4py, :mod:`parsph.sph`'s particle storage and cell grid; never the equations.
"""
