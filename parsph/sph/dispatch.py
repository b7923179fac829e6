"""Calling numba passes from Python at the cost of positional arguments: the version compiled for the
arguments' types, looked up once per kind of arguments.

The dispatcher types named-tuple arguments at every call (5.5-9.1 us a pass on an empty input,
against 0.6-2.7 us through the compiled version: docs/performance.md, "The step in compiled
code, and its fixed cost"); the compiled version takes them as they are.
"""
import numba
import numpy as np


def threaded():
    """Whether this process runs the threaded passes and integrators (numba's thread count above one), else
    the serial ones, so that a one-thread run compiles and runs no parallel region: the one place that
    choice is made, for the compiled block and the Python path alike."""
    return numba.get_num_threads() > 1


def compiled(dispatcher, *args):
    """The version of a numba function compiled for the types of ``args`` (compiled, or loaded from the
    cache, now).

    The dispatcher must have run once (it starts numba's threads, which the
    compiled version expects). Typing the arguments here costs some 100 us a
    named tuple, so :class:`Calls` does it once per kind of arguments
    (:func:`kinds`). Without the JIT (``NUMBA_DISABLE_JIT``) the function is
    returned as it is.
    """
    if not hasattr(dispatcher, "compile"):
        return dispatcher
    return dispatcher.compile(tuple(numba.typeof(a) for a in args))


def kinds(value):
    """What decides a value's numba type, read cheaply: an array's dtype, dimensions, contiguity and
    writeability, a tuple's class and elements, another value's Python type."""
    if isinstance(value, np.ndarray):
        return (value.dtype.char, value.ndim, value.flags.c_contiguous, value.flags.writeable)
    if isinstance(value, tuple):
        return (type(value),) + tuple(kinds(v) for v in value)
    return type(value)


class Calls:
    """Numba functions by name, each called through its compiled version, looked up once until
    :meth:`forget` (a list build makes new arrays) and kept per kind of arguments across builds."""

    def __init__(self, functions):
        self.functions = functions
        self._now = {}       # name -> the version for this build's argument types
        self._versions = {}  # (name, kinds(args)) -> compiled version

    def forget(self):
        self._now = {}

    def __call__(self, name, *args):
        """The first call with arguments of a new kind goes through numba's dispatcher (which compiles or
        loads the function and starts numba's threads)."""
        fn = self._now.get(name)
        if fn is not None:
            return fn(*args)
        key = (name, kinds(args))
        version = self._versions.get(key)
        if version is None:
            out = self.functions[name](*args)
            self._now[name] = self._versions[key] = compiled(self.functions[name], *args)
            return out
        self._now[name] = version
        return version(*args)
