"""How every collective command runs and ends (``parsph run``, ``parsph converge``): on MPI_COMM_WORLD,
fetched here and nowhere else, with SIGINT/SIGTERM caught, and every way it can end turned into one
message from rank 0 and one exit code; anything unexpected on one rank calls ``MPI_Abort``, so that no
rank is left waiting.
"""
import signal
import sys

from parsph.errors import GuardError, Interrupted, SolveError, UsageError
from .exits import EXIT_BAD_INPUT, EXIT_ERROR, EXIT_GUARD, EXIT_SIGNAL


class Signals:
    """SIGINT/SIGTERM set a flag that the time loop polls; the step in hand finishes."""

    def __init__(self):
        self.received = None
        for sig in EXIT_SIGNAL:
            signal.signal(sig, self._handle)

    def _handle(self, signum, frame):
        self.received = signum

    def __call__(self):
        """The number of the signal received (0: none)."""
        return int(self.received or 0)

    def release(self):
        """Once the run is over, a signal ends the process at once again: mpirun's SIGTERM to a rank
        still in MPI_Finalize after another rank's non-zero exit must not be swallowed by the flag."""
        for sig in EXIT_SIGNAL:
            signal.signal(sig, signal.SIG_DFL)


def world_command(fn):
    """Run ``fn(comm, say, signals)`` on MPI_COMM_WORLD (the one place it is fetched) with the signals
    caught and rank 0 saying; its exit code, every way it can end (:func:`reporting`)."""
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    root = comm.rank == 0
    signals = Signals()

    def say(msg):
        if root:
            print(msg, flush=True)

    try:
        return reporting(comm, lambda: fn(comm, say, signals))
    finally:
        signals.release()


def reporting(comm, fn):
    """fn(), with every way it can end turned into one message and an exit code."""
    root = comm.rank == 0
    try:
        return fn()
    except UsageError as e:
        if root:
            print(f"parsph: error: {e}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    except (GuardError, SolveError) as e:  # raised on every rank alike
        if root:
            print(f"parsph: error: {e}; earlier outputs are intact", file=sys.stderr, flush=True)
        return EXIT_GUARD
    except Interrupted as e:  # raised on every rank alike, with the signal they agreed on
        if root:
            print(f"parsph: {signal.Signals(e.signum).name}: {e}", file=sys.stderr, flush=True)
        return EXIT_SIGNAL.get(e.signum, EXIT_ERROR)
    except Exception as e:  # noqa: BLE001 - any failure must end every rank
        print(f"parsph: error on rank {comm.rank}: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
        if comm.size > 1:
            comm.Abort(EXIT_ERROR)
        return EXIT_ERROR
