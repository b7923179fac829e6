"""HDF5 output: one file per output time, written collectively through h5py's mpio driver.

Directory layout (docs/output.md has the table with units)::

    DIR/<name>_NNNN.h5     output k = NNNN: profile and particle snapshot at one time
    DIR/<name>.xdmf        ParaView sidecar: the snapshots as a time series of points
    DIR/<name>.cells.h5    the sidecar's connectivity 0 .. N-1 (one point cell per particle), written once

Each file is written as ``<name>_NNNN.h5.part`` and renamed when complete and
closed (rank 0 fsyncs the file before the rename and the directory after it),
so a run killed at any moment (even SIGKILL, or a crash of the machine) leaves
every earlier output whole and readable, and every output file with particles
is a restart point. In a file:

    /                      attrs: parsph_version, run_file (TOML), scene, dim, n_particles, ranks,
                                  time, step, index, dt, L, Ly, the scene's scales (a channel's or a
                                  box's V_w, nu; a layer's H0, U, U_mf, dp_bed), kinds, units, snapshot
    /profile/x             (Nx,)          bin centres [m]
    /profile/vy, theta     (Nx,)          mean v_y [m/s] and theta of the fluid particles per bin
    /profile/count         (Nx,)          fluid particles per bin
    /profile/vy_exact, theta_exact (Nx,)  the scene's reference (NaN where it has none)
    /profile/vx, vx_exact  (Nx,)          mean v_x [m/s] per bin (a layer's settling velocity), and its
                                          reference (NaN where the scene has none)
    /profile attrs         err_max, err_rms: |f - f_exact| / scale of the scene's error field
                           (root attrs error_field, error_scale: the scale at this time, for a
                           decaying flow the amplitude left), max and RMS over bins
    /particles/{id, kind, mass, position, velocity, theta}   (N,), (N,), (N,), (N, dim), (N, dim), (N,)
                           mass in kg/m in 2-D (per metre of z), kg in 3-D (MASS_UNITS)
    /particles/position_view (N, dim) f8   layers only: ParaView's points, (y, x[, z]): the height along its Y
    /particles/velocity_xyz (N, 3) f4      2-D, and layers: ParaView's glyphs' vector in its frame ((v_x, v_y, 0);
                           a layer, drawn upright: (v_y, v_x, v_z))
    /layout/offset         (P+1,)         rows offset[r] .. offset[r+1]-1 hold writer rank r's particles
    /layout/y_range        (P, 2)         min and max y of those particles (NaN: none)
    /layout/bin_start      (P, B+1)       first row of each of B equal y-bins of [y_min, y_max] per rank
    /layout/memory_index   (N,) i4        each row's place in the writer rank's memory (restored on restart)
    /restart/position      (N, dim)       the solver's positions as it holds them: wrapped into the box
                                          only at its last neighbour-list build, so they may lie up to
                                          that build's drift outside it [m]
    /restart/ref           (N, dim)       the positions at that build (in the box) [m]: a restart builds
                                          the same list from them and continues bit for bit

Writing: every rank writes its particles as one hyperslab at the offset given
by a scan of the particle counts, in one collective H5Dwrite per dataset; a
rank with no particles takes part with an empty selection. Within its rows a
rank's particles are ordered by y-bin (a stable sort, O(n)), so that a restart
on P' ranks reads only the rows of the bins that overlap its own slab
(``read_particles``): O(N/P') memory and I/O per rank, whatever P and P'.
When h5py lacks MPI, rank 0 gathers and writes instead (one warning line
saying whether h5py lacks MPI or ``PARSPH_SERIAL_HDF5`` forced it), and each
rank of a restart reads its rows with serial h5py.

The package: :mod:`.layout` (the datasets, their types and units),
:mod:`.hdf5` (collective row I/O through h5py's low-level API, the durable
rename), :mod:`.write` (:class:`Output`: one output file per call),
:mod:`.xdmf` (the ParaView sidecar), :mod:`.restart` (each rank reads the
particles of its slab) and :mod:`.files` (finding and reading a run's
outputs with serial h5py, no MPI needed).
"""
from .files import last_snapshot, output_files, read_profile, read_snapshot
from .hdf5 import SERIAL_ENV, collective_dxpl, parallel_hdf5_available, read_rows, write_rows, y_bins
from .layout import (BIN_ROWS, FILE_DTYPES, MASS_UNITS, MAX_BINS, PARTICLE_FIELDS, PROFILE_FIELDS,
                     PROFILE_OPTIONAL, PROFILE_UNITS, RESTART_FIELDS, UNITS)
from .restart import read_grid, read_particles, read_state
from .write import Frame, Output, output_name
from .xdmf import snapshot_entry, write_xdmf, xdmf_grid

__all__ = ["BIN_ROWS", "FILE_DTYPES", "Frame", "MASS_UNITS", "MAX_BINS", "Output", "PARTICLE_FIELDS",
           "PROFILE_FIELDS", "PROFILE_OPTIONAL", "PROFILE_UNITS", "RESTART_FIELDS", "SERIAL_ENV", "UNITS", "collective_dxpl", "last_snapshot",
           "output_files", "output_name", "parallel_hdf5_available", "read_grid", "read_particles", "read_profile",
           "read_rows", "read_snapshot", "read_state", "snapshot_entry", "write_rows", "write_xdmf", "xdmf_grid",
           "y_bins"]
