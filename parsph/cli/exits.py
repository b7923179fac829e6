"""Exit codes, bad command-line input, and how every rank agrees on bad input before any collective call."""
import signal

EXIT_ERROR, EXIT_BAD_INPUT, EXIT_GUARD = 1, 2, 3
EXIT_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143}


class UsageError(Exception):
    """Bad command-line input (not the run file)."""


def agree(comm, fn):
    """Run fn on every rank; if it raises a bad-input error anywhere, raise it everywhere.

    Validation must end every rank alike, or the ranks that passed would wait
    forever in the first collective call.
    """
    from parsph.setup.config import ConfigError
    from parsph.parallel.slab_ring import DecompositionError
    err = None
    try:
        result = fn()
    except (ConfigError, DecompositionError, UsageError) as e:
        err, result = str(e), None
    errs = comm.allgather(err)
    first = next((e for e in errs if e is not None), None)
    if first is not None:
        raise UsageError(first)
    return result
