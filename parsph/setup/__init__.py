"""From a run file to a run: the schema of its keys, the run file as a value (:class:`.runfile.RunFile`:
TOML text, overrides), the built configuration (lattice, kernel support, time step against the limits),
and the scenes.

May import: :mod:`parsph.physics`, :mod:`parsph.sph` (particle kinds, integrator names),
:mod:`parsph.parallel`'s pure slab arithmetic; never MPI.
"""
