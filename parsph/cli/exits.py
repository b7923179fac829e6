"""Exit codes of the ``parsph`` command (the exceptions they answer are in :mod:`parsph.errors`)."""
import signal

EXIT_ERROR, EXIT_BAD_INPUT, EXIT_GUARD = 1, 2, 3
EXIT_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143}
