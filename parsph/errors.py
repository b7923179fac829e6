"""Every exception parsph raises on purpose, and how the ranks agree on bad input.

The bottom layer: imports nothing of parsph, so any module may raise or catch
these. Bad input (:class:`ConfigError`, :class:`DecompositionError`,
:class:`UsageError`) ends a command with exit code 2, a failed run-time check
(:class:`GuardError`) or a failed gas solve (:class:`SolveError`) with 3, a stop signal (:class:`Interrupted`) with 130 or
143 (:mod:`parsph.cli.exits`).
"""


class ConfigError(Exception):
    """A bad run file: ``key`` names the offending key."""

    def __init__(self, key, reason):
        shown = repr(key) if len((key + ".").splitlines()) > 1 else key  # one line, always
        super().__init__(f"{shown}: {reason}")
        self.key = key
        self.reason = reason


class DecompositionError(Exception):
    """A decomposition that cannot work (slabs too thin for the ghost rows)."""


class UsageError(Exception):
    """Bad command-line input (not the run file)."""


class GuardError(RuntimeError):
    """A run-time check failed on some rank; raised on every rank alike with the same ``result``
    (a :class:`parsph.simulation.guards.GuardResult`: the check's code, the particle, the value)."""

    def __init__(self, result):
        super().__init__(result.message)
        self.result = result


class SolveError(RuntimeError):
    """The solved gas's pressure solve failed (no finite answer); raised on every rank alike, naming the
    step and the time."""


class Interrupted(RuntimeError):
    """A stop was requested (signal); raised on every rank alike after the last output."""

    def __init__(self, message, signum):
        super().__init__(message)
        self.signum = signum


BAD_INPUT = (ConfigError, DecompositionError, UsageError)


def agree(comm, fn):
    """Run fn on every rank; if it raises a bad-input error anywhere, raise it (as UsageError) everywhere.

    Validation must end every rank alike, or the ranks that passed would wait
    forever in the first collective call.
    """
    err = None
    try:
        result = fn()
    except BAD_INPUT as e:
        err, result = str(e), None
    errs = comm.allgather(err)
    first = next((e for e in errs if e is not None), None)
    if first is not None:
        raise UsageError(first)
    return result
