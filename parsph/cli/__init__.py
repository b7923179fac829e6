"""The ``parsph`` command: the parser (:mod:`.command`) and one module per command (:mod:`.run`,
:mod:`.report` and :mod:`.particles_plot`; converge's in :mod:`parsph.studies.converge`), what a
run prints (:mod:`.progress`), compiling the loops ahead (:mod:`.warm`), the exit codes
(:mod:`.exits`).

The top layer: may import every other.
"""
from .command import main  # noqa: F401  (the console script parsph.cli:main)
