"""The studies' one resumable runner (parsph/studies/runs.py): a kept run is not run again, in each store
the studies use (the stability map's CSVs, the sweep's runs.jsonl, converge's level.json), and on a
communicator rank 0 alone touches the store. No solver: the runs are stand-ins.
"""
import json

from parsph.studies.converge import LevelRun, _level_run
from parsph.studies.runs import CsvRows, JsonLines, RunDirs, Runs, append_row, load_rows


def counting(record):
    calls = []

    def run():
        calls.append(1)
        return dict(record)
    return run, calls


def test_csv_rows_run_once_and_resume(tmp_path):
    path = str(tmp_path / "runs.csv")
    key_of = lambda r: int(r["n"])  # noqa: E731
    runs = Runs(CsvRows(path, ["n", "x"], key_of))
    run, calls = counting({"n": 3, "x": 0.1})
    said = []
    assert runs.get(3, run, then=said.append) == {"n": "3", "x": "0.1"}   # as the file gives it back
    assert runs.get(3, run, then=said.append) == {"n": "3", "x": "0.1"}
    assert len(calls) == 1 and len(said) == 1
    again = Runs(CsvRows(path, ["n", "x"], key_of))   # a stopped study, started again
    assert again.get(3, run) == {"n": "3", "x": "0.1"} and len(calls) == 1
    assert again.store.rows == [{"n": "3", "x": "0.1"}]


def test_csv_rows_keep_an_older_header(tmp_path):
    """A CSV from before a column was added is appended to with its own header."""
    path = str(tmp_path / "old.csv")
    append_row(path, ["n"], {"n": 1})
    runs = Runs(CsvRows(path, ["n", "commit"], lambda r: int(r["n"])))
    runs.get(2, lambda: {"n": 2, "commit": "abc"})
    assert load_rows(path) == [{"n": "1"}, {"n": "2"}]


def test_json_lines_resume_and_fresh(tmp_path):
    path = str(tmp_path / "runs.jsonl")
    runs = Runs(JsonLines(path))
    assert runs.done("a") is None
    assert runs.add("a", {"err": 1.5}) == {"err": 1.5, "id": "a"}
    assert Runs(JsonLines(path)).done("a") == {"err": 1.5, "id": "a"}
    fresh = Runs(JsonLines(path, fresh=True))   # --rerun: the old records set aside, every run made again
    assert fresh.done("a") is None
    assert (tmp_path / "runs.jsonl.old").exists()


def test_run_dirs_reuse_only_the_same_run_file(tmp_path):
    """converge's levels: reused where level.json records the same run file, wherever the study now lies."""
    old, new = tmp_path / "old", tmp_path / "moved"
    old.mkdir()
    rec = LevelRun("given", 16, str(old), "RUN FILE", 100, [0.1], [10], [0.5], 1, 1, level=0)
    Runs(RunDirs()).add((str(old), "RUN FILE"), rec.record())
    old.rename(new)
    runs = Runs(RunDirs())
    assert runs.done((str(new), "OTHER RUN FILE")) is None
    found = _level_run(runs.done((str(new), "RUN FILE")))
    assert found.dir == str(new) and found.Nx == 16 and found.level == 0
    (new / "level.json").write_text(json.dumps({"run_file": "RUN FILE", "unknown": 1}))
    assert _level_run(runs.done((str(new), "RUN FILE"))) is None   # a record of another form: run again
    (new / "level.json").write_text("not json")
    assert runs.done((str(new), "RUN FILE")) is None


class Rank1:
    """A communicator seen from rank 1: bcast hands out rank 0's value."""
    rank = 1

    def __init__(self, value):
        self.value = value

    def bcast(self, obj, root=0):
        assert obj is None and root == 0
        return self.value


class NoStore:
    def find(self, key):
        raise AssertionError("only rank 0 reads the store")

    def add(self, key, record):
        raise AssertionError("only rank 0 writes the store")


def test_only_rank_0_keeps_the_store():
    assert Runs(NoStore(), Rank1({"x": 1})).done("k") == {"x": 1}
    run, calls = counting({"x": 2})
    assert Runs(NoStore(), Rank1(None)).get("k", run) == {"x": 2} and len(calls) == 1
