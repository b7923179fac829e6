"""The ``parsph`` command: the parser (:mod:`.command`) and one module per command (:mod:`.run`,
:mod:`.converge`, :mod:`.report` and :mod:`.particles_plot`), what a run prints (:mod:`.progress`),
compiling the loops ahead (:mod:`.warm`), the exit codes (:mod:`.exits`).

The top layer: may import every other. Modules that start MPI (the solver, the
runs) are imported inside the commands that need them: ``parsph check`` and
``parsph plot`` must not start MPI.
"""
from .command import main

__all__ = ["main"]  # the console script parsph.cli:main
