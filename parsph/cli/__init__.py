"""The ``parsph`` command: the parser (:mod:`.command`) and one module per command (:mod:`.run`,
:mod:`.report`; converge's in :mod:`parsph.studies.converge`), the exit codes (:mod:`.exits`).

The top layer: may import every other.
"""
from .command import main

__all__ = ["main"]  # the console script parsph.cli:main
