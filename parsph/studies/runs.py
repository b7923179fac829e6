"""The one resumable runner of the studies: a run whose record is kept is not run again.

A study (the stability map, the accuracy sweep, ``parsph converge``) is many
runs of hours in all; a machine that stops, or a study extended by a few more
runs, must not repeat those already done. :class:`Runs` looks a run up by its
key in a store and runs only the missing ones, recording each as it finishes,
so a stopped study resumes where it stopped. The stores differ only in the
files the studies already keep, which earlier results in docs/ were made from:

- :class:`CsvRows`: one CSV row per run (the stability map's CSVs), read
  back as strings; an existing file keeps its header;
- :class:`JsonLines`: one JSON record per line (the sweep's runs.jsonl);
- :class:`RunDirs`: one directory per run holding a JSON record
  (``parsph converge``'s level.json), reused only where the record's run file
  is the one asked for.

On a communicator (``Runs(store, comm)``) rank 0 reads and writes the store
and every rank gets the same answer, as every rank takes part in each run.
"""
import csv
import json
import os


class Runs:
    """Finished runs by key, in ``store`` (one of the stores below); ``comm``: rank 0 keeps the store."""

    def __init__(self, store, comm=None):
        self.store, self.comm = store, comm

    @property
    def _keeper(self):
        return self.comm is None or self.comm.rank == 0

    def done(self, key):
        """The record of the run ``key`` (the same on every rank), None where it has not run."""
        rec = self.store.find(key) if self._keeper else None
        return rec if self.comm is None else self.comm.bcast(rec, root=0)

    def add(self, key, record):
        """Keep a finished run's record; the record as the store gives it back (rank 0's)."""
        return self.store.add(key, record) if self._keeper else record

    def get(self, key, run, then=None):
        """The record of run ``key``: the kept one, else ``run()``'s, kept (``then(record)`` after a new run)."""
        rec = self.done(key)
        if rec is None:
            rec = self.add(key, run())
            if then is not None:
                then(rec)
        return rec


# ---- the stores ---------------------------------------------------------------------------------------
def append_row(path, fields, row):
    """Append one row to a CSV; a new file gets the header ``fields``, an existing one keeps its own
    (older CSVs lack later columns)."""
    header = fields
    if os.path.exists(path):
        with open(path, newline="") as f:
            header = next(csv.reader(f), None) or fields
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, header, extrasaction="ignore")
        if header is fields:
            w.writeheader()
        w.writerow(row)


def load_rows(path):
    """The rows of a CSV (as strings), none where it does not exist."""
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def write_rows(path, fields, rows):
    """A CSV of ``rows`` (dicts) with the header ``fields`` (keys beyond them left out)."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def append_json(path, record):
    """Append ``record`` to a JSON-lines file as one line."""
    with open(path, "a") as f:
        f.write(json.dumps(record) + "\n")


class CsvRows:
    """One CSV row per run, keyed by ``key_of(row)``; ``rows``: every run so far, in the file's order."""

    def __init__(self, path, fields, key_of):
        self.path, self.fields, self.key_of = path, fields, key_of
        self.rows = load_rows(path)
        self._by_key = {key_of(r): r for r in self.rows}

    def find(self, key):
        return self._by_key.get(key)

    def add(self, key, row):
        append_row(self.path, self.fields, row)
        row = {k: str(v) for k, v in row.items()}   # as the file gives it back
        self.rows.append(row)
        self._by_key[key] = row
        return row


class JsonLines:
    """One JSON record per line, keyed by its field ``id``; ``fresh``: the file so far is moved to
    ``path + ".old"`` and every run made again."""

    def __init__(self, path, fresh=False):
        self.path = path
        if fresh and os.path.exists(path):
            os.replace(path, path + ".old")
        self.records = {}
        if os.path.exists(path):
            with open(path) as f:
                for line in f:
                    if line.strip():
                        r = json.loads(line)
                        self.records[r["id"]] = r

    def find(self, key):
        return self.records.get(key)

    def add(self, key, record):
        record = dict(record, id=key)
        append_json(self.path, record)
        self.records[key] = record
        return record


class RunDirs:
    """One directory per run holding the JSON record ``name``; a key is (the directory, the run file as
    written), and a record is found only where its field ``run_file`` is that run file (the same run).
    The record found carries its directory as ``dir`` (the study may have been moved since)."""

    def __init__(self, name="level.json"):
        self.name = name

    def find(self, key):
        run_dir, run_file = key
        try:
            with open(os.path.join(run_dir, self.name)) as f:
                rec = json.load(f)
        except (OSError, ValueError):
            return None
        if not isinstance(rec, dict) or rec.get("run_file") != run_file:
            return None
        return dict(rec, dir=run_dir)

    def add(self, key, record):
        with open(os.path.join(key[0], self.name), "w") as f:
            json.dump(record, f, indent=1)
        return record
