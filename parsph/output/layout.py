"""The output file's datasets: which fields, their types in the file, their units, and the restart layout's bins.

The layout of a file is in :mod:`parsph.output`'s docstring and docs/output.md.
"""
import numpy as np

PARTICLE_FIELDS = ("id", "kind", "mass", "position", "velocity", "theta")
RESTART_FIELDS = ("id", "kind", "mass", "position", "velocity")
FILE_DTYPES = {"id": np.int64, "kind": np.int8, "mass": np.float64, "position": np.float64,
               "velocity": np.float64, "theta": np.float64}
PROFILE_FIELDS = ("x", "vy", "theta", "count", "vy_exact", "theta_exact", "vx", "vx_exact")
PROFILE_UNITS = {"x": "m", "vy": "m/s", "theta": "1", "count": "1", "vy_exact": "m/s", "theta_exact": "1",
                 "vx": "m/s", "vx_exact": "m/s"}
# written where the profile has them (every run since they were added); read as NaN from older files
PROFILE_OPTIONAL = ("vx", "vx_exact")
# a particle's mass per unit of the dimensions the lattice leaves out (2-D: per metre of z)
MASS_UNITS = {1: "kg/m^2", 2: "kg/m", 3: "kg"}
UNITS = {"id": "1", "kind": "1", "position": "m", "velocity": "m/s", "theta": "1"}
BIN_ROWS = 256       # rows per y-bin of the restart layout, on the fullest rank
MAX_BINS = 65535     # bin keys fit uint16, where numpy's stable sort is a radix sort
