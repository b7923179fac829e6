"""numba's disk cache of parsph's loops, kept in step with the sources.

numba checks a cached function against its own source file only: a compiled
function that calls another (the compiled step calls the passes, the passes
the kernels) keeps the callee's old code after the callee's file changes, and
may then read arrays of a changed layout. So on import parsph hashes its
sources and, where the hash differs from the one the cache was built with,
removes its cached loops (they compile again, or ``scripts/setup.sh``
compiles them ahead). One process does it while the others of an mpirun wait.

Where ``NUMBA_CACHE_DIR`` is set, that directory is kept in step the same
way, except that one without a stamp (a fresh copy of a cache that was in
step) is taken as it is. Nothing here changes a result; a read-only cache
is left alone.

Several processes compiling at once (mpirun's ranks, the test suite's
workers, ``parsph.cli.warm``'s processes) save into one cache. numba saves a
compiled version by reading the function's index, taking the first data file
number the index does not use, writing the index and then the data file, each
file replaced atomically but nothing held between the steps
(numba.core.caching.IndexDataCacheFile.save): two processes saving different
versions of one function at once can both take data file N, leaving the index
mapping one version's signature to the other's code, which later processes
load as a hit. So parsph's processes hold one lock (``fcntl.flock`` on
``parsph-save.lock`` in the cache's folder) for each save, from the index's
read to the data file's write (:func:`serialise_saves`). Loading takes no lock:
an index entry whose data file is not written yet reads as a miss.
"""
import hashlib
import os
import time
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
STAMP = "parsph-sources.sha256"
SAVE_LOCK = "parsph-save.lock"


def sources_hash():
    """SHA-256 of every .py file of the package (paths and contents, in sorted order)."""
    h = hashlib.sha256()
    for p in sorted(PACKAGE.rglob("*.py")):
        h.update(str(p.relative_to(PACKAGE)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def _cache_dirs(root):
    """The __pycache__ folders of the package (numba's default place), or the user's cache dir."""
    if root is None:
        return list(PACKAGE.rglob("__pycache__"))
    return [Path(root)]


def keep_in_step():
    """Remove parsph's cached loops built from other sources than these, and serialise this process's saves
    into the cache (see the module doc)."""
    root = os.environ.get("NUMBA_CACHE_DIR") or None
    base = PACKAGE / "__pycache__" if root is None else Path(root)
    serialise_saves(base / SAVE_LOCK)
    _clean(root, base)


def serialise_saves(lock_path):
    """From now on this process saves numba's cache entries holding ``lock_path`` (module doc). Where the
    lock cannot be opened (a read-only cache) a save goes on without it, as numba's own."""
    import fcntl
    from numba.core import caching
    current = caching.IndexDataCacheFile.save
    save = getattr(current, "unlocked", current)
    lock_path = Path(lock_path)

    def locked_save(self, key, data):
        try:
            lock_path.parent.mkdir(parents=True, exist_ok=True)
            f = open(lock_path, "a")
        except OSError:
            return save(self, key, data)
        with f:  # closing the file releases the lock
            fcntl.flock(f, fcntl.LOCK_EX)
            return save(self, key, data)
    locked_save.unlocked = save
    caching.IndexDataCacheFile.save = locked_save


def _clean(root, base):
    stamp = base / STAMP
    want = sources_hash()
    try:
        have = stamp.read_text().strip()
    except OSError:
        have = None
    if have == want:
        return
    if have is None and root is not None:  # a fresh cache dir (empty, or seeded from one in step)
        _write(stamp, want)
        return
    lock = base / (STAMP + ".lock")
    try:
        if time.time() - lock.stat().st_mtime > 60:  # left by a process that died while cleaning
            lock.unlink(missing_ok=True)
    except OSError:
        pass
    try:
        base.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:  # another process of this run cleans: wait for its stamp (a few seconds at most)
        for _ in range(200):
            time.sleep(0.05)
            if not lock.exists():
                break
        return
    except OSError:  # a read-only installation: nothing to keep
        return
    try:
        for d in _cache_dirs(root):
            for f in list(d.rglob("*.nbi")) + list(d.rglob("*.nbc")):
                if root is None or f.name.split(".")[0] in _module_stems():
                    f.unlink(missing_ok=True)
        _write(stamp, want)
    finally:
        os.close(fd)
        lock.unlink(missing_ok=True)


def _module_stems():
    return {p.stem for p in PACKAGE.rglob("*.py")}


def _write(path, text):
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + f".{os.getpid()}")
        tmp.write_text(text + "\n")
        os.replace(tmp, path)
    except OSError:
        pass
