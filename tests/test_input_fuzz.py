"""Property-based tests of run-file validation (hypothesis), in process and on the command line.

    .venv/bin/python -m pytest -q tests/test_input_fuzz.py

Properties:

* In process (``parsph.setup.config``: what ``load`` / ``loads`` do after reading
  the file: ``build(RunFile(raw))``): whatever a run file holds (any TOML
  type in any key, missing and unknown keys and sections, NaN, +-inf, zero,
  negative, subnormal, huge and non-64-bit numbers, several bad keys at once,
  random text, random ``--set`` overrides), validation either returns a
  RunConfig with sane derived values whose run-file text parses back to the
  same values (a restart re-reads it), or raises ConfigError whose ``key``
  names the culprit, in a one-line ``"key: reason"`` message. Any other
  exception (OverflowError, ZeroDivisionError, TypeError, ...) is a bug.
  A wrong type, a non-finite or out-of-range value, a missing required key
  or an unknown key must name exactly that key.
* The memory check (``parsph.simulation.case.fits_in_memory``) with a stubbed memory figure:
  random large Nx, Ly, Lz and h / dx in 2-D and 3-D on 1 to 4 nodes is
  refused (ConfigError on ``numerics.Nx`` with the particle count and the
  estimate in GB) exactly when the estimate exceeds 80% of the memory.
* On the command line (``parsph run``, 1 rank and ``mpirun -n 2``), fixed
  cases and a hypothesis property drawing from the strategies above (wrong
  types, out-of-range numbers, missing and unknown keys, Nx too large for
  this machine's memory, output directories missing, read-only or under a
  read-only parent, run as root through ``setpriv`` without
  CAP_DAC_OVERRIDE): exit code 2, exactly one stderr line
  ``parsph: error: ...`` naming the key (or the directory), no traceback,
  no MPI_ABORT, no hang (HANG_GUARD), and a refused run file leaves the
  output directory untouched. A too large Nx is refused with a memory
  estimate before anything is allocated; a missing output directory is
  created; an existing output is replaced only with ``--force``.
  Subprocesses run under an 8 GB RLIMIT_AS.

Hypothesis runs derandomized (the same examples every time, no example
database written) and without a deadline per example: how long an example
takes depends on the machine's load, so it is no test of validation. A launched
command that runs into HANG_GUARD is killed and fails its test (a hang is a
bug; slowness is not). Cases per run, by design (``max_examples`` below; a
property that finds a bug stops early and shrinks, so a failing run tries
fewer): 3 150 examples of the 10 in-process properties (2 950 validation, 200
memory check), 20 of the command-line property (12 on 1 rank, 8 under
``mpirun -n 2``), 12 extreme-number regressions, 5 fixed documents, 19 fixed
command lines on 1 rank and 5 under ``mpirun -n 2``: 3 211 in all.
``scripts/fuzz_counts.py`` runs this module and prints the cases each
property tried (COUNTS).
"""
import copy
import datetime
import json
import math
import os
import resource
import shutil
import tempfile
import tomllib
from collections import Counter
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from reliability_helpers import common as C  # noqa: E402

from parsph.setup import config, memory  # noqa: E402
from parsph.setup.runfile import RunFile  # noqa: E402
from parsph.errors import ConfigError  # noqa: E402
from parsph.setup.schema import REQUIRED, SCHEMA  # noqa: E402

BASE_TEXT = C.PAPER.read_text()
BASE = tomllib.loads(BASE_TEXT)
ALL_KEYS = [(s, k) for s, keys in SCHEMA.items() for k in keys]
NUMERIC_KEYS = [(s, k) for s, k in ALL_KEYS if SCHEMA[s][k].kind in ("float", "int", "float_or_auto", "floatlist")]
COUNTS = Counter()


def fuzz_settings(n):
    """``n`` derandomized examples and no deadline: an example's time depends on the machine's load
    (and a deadline is checked after the example returns, so it would not catch a hang either)."""
    return settings(max_examples=n, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                           HealthCheck.data_too_large])


# ---- strategies ---------------------------------------------------------------------------

SPECIAL_NUMBERS = [0, 0.0, -0.0, -1, 1, 2, 3, 5e-324, 2.2250738585072014e-308, 1e-300, 1e-30, 1e-12,
                   1e30, 1e300, 1.7976931348623157e308, 10 ** 7, 10 ** 9, 2 ** 62, 2 ** 63 - 1, -(2 ** 63),
                   10 ** 19, 10 ** 400, -10 ** 400, math.nan, math.inf, -math.inf]
numbers = st.one_of(
    st.sampled_from(SPECIAL_NUMBERS),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-10.0, max_value=10.0),
    st.integers(min_value=-(2 ** 64), max_value=2 ** 64),
    st.integers(min_value=-5, max_value=200),
)
datetimes = st.one_of(st.datetimes(), st.dates(), st.times())
scalars = st.one_of(st.booleans(), numbers, st.text(max_size=12), datetimes,
                    st.sampled_from(["auto", "couette", "cubic_spline", "wendland_c2", "paper", "midpoint",
                                     "symmetric", "true", "1e-5", "", "nan"]))
values = st.recursive(scalars, lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(min_size=1, max_size=4),
                                                                                       c, max_size=2),
                      max_leaves=6)
# printable key names (a name with a line break is test_a_key_name_with_a_line_break_stays_on_one_line)
PRINTABLE = st.characters(blacklist_categories=("Cc", "Cs", "Zl", "Zp"))
key_names = st.text(PRINTABLE, min_size=1, max_size=12)


def _wrong(kind):
    """Values of the wrong type for a schema kind."""
    not_numbers = st.one_of(st.text(max_size=8).filter(lambda s: s != "auto"), st.booleans(), datetimes,
                            st.lists(numbers, max_size=2), st.dictionaries(st.text(min_size=1, max_size=3),
                                                                           numbers, max_size=2))
    if kind in ("float", "float_or_auto"):
        return not_numbers
    if kind == "int":
        return st.one_of(not_numbers, st.floats(allow_nan=True, allow_infinity=True))
    if kind == "str":
        return st.one_of(numbers, st.booleans(), datetimes, st.lists(st.text(max_size=3), max_size=2),
                         st.dictionaries(st.text(min_size=1, max_size=3), st.text(max_size=3), max_size=2))
    if kind == "bool":
        return st.one_of(numbers, st.text(max_size=6), datetimes, st.lists(st.booleans(), max_size=2))
    if kind == "floatlist":
        bad_item = st.one_of(st.text(max_size=4), st.booleans(), datetimes, st.just(math.nan), st.just(math.inf),
                             st.just(-math.inf), st.lists(numbers, max_size=2))
        return st.one_of(numbers, st.text(max_size=6), st.booleans(), datetimes,
                         st.tuples(st.lists(st.floats(0, 0.5), max_size=2), bad_item,
                                   st.lists(st.floats(0, 0.5), max_size=2)).map(lambda t: [*t[0], t[1], *t[2]]))
    raise AssertionError(kind)


# ---- the property -------------------------------------------------------------------------------

def base():
    return copy.deepcopy(BASE)


def validate_raw(raw):
    """config.loads after tomllib: the text is written before validation, as there."""
    return config.build(RunFile(raw))


def outcome(raw, what):
    """Validate ``raw``: a checked RunConfig, or a ConfigError with a one-line 'key: reason' message.

    Any other exception is a bug: it propagates (hypothesis shrinks and reports it).
    """
    COUNTS[what] += 1
    try:
        cfg = validate_raw(raw)
    except ConfigError as e:
        assert isinstance(e.key, str) and e.key, repr(e.key)
        msg = str(e)
        assert "\n" not in msg and msg.startswith(f"{e.key}: ") and e.reason, repr(msg)
        return e
    check_config(cfg)
    return cfg


def finite_positive(x):
    return isinstance(x, (int, float)) and math.isfinite(x) and x > 0


def check_config(cfg):
    """An accepted run has usable derived quantities, and its run-file text reads back the same."""
    for name in ("L", "Ly", "dx", "dy", "h", "t_end", "rho_s", "theta0"):
        assert finite_positive(getattr(cfg, name)), f"accepted run with {name} = {getattr(cfg, name)!r}"
    assert isinstance(cfg.Nx, int) and cfg.Nx >= 2 and isinstance(cfg.Ny, int) and cfg.Ny >= 1
    assert isinstance(cfg.Nz, int) and cfg.Nz >= 1 and finite_positive(cfg.dz)
    assert isinstance(cfg.layers, int) and (cfg.layers >= 1 if cfg.scene.walls else cfg.layers == 0)
    assert isinstance(cfg.n_particles, int) and cfg.n_particles >= 1
    assert isinstance(cfg.nsteps, int) and cfg.nsteps >= 1
    assert cfg.dt > 0 and not math.isnan(cfg.dt), cfg.dt
    if not cfg.dt_auto:
        assert math.isfinite(cfg.dt)
    assert not math.isnan(cfg.mass) and not math.isnan(cfg.k)
    assert all(0 <= t <= cfg.t_end * (1 + 1e-12) for t in cfg.output_times)
    again = config.loads(cfg.text)  # what a restart does with the run_file attribute
    assert again.values == cfg.values, "the run file text does not read back to the same values"


def name_of(section, key):
    return f"{section}.{key}"


# ---- in-process properties ---------------------------------------------------------------------

@fuzz_settings(600)
@given(st.lists(st.tuples(st.sampled_from(ALL_KEYS), st.one_of(values, numbers)), min_size=1, max_size=3))
def test_any_values_in_any_keys(changes):
    raw = base()
    for (s, k), v in changes:
        raw.setdefault(s, {})[k] = v
    outcome(raw, "any value in any key")


@fuzz_settings(600)
@given(st.lists(st.tuples(st.sampled_from(NUMERIC_KEYS), numbers), min_size=1, max_size=3))
def test_any_numbers_in_numeric_keys(changes):
    """Extreme numbers alone or together: a ConfigError or a usable run, never an arithmetic crash."""
    raw = base()
    for (s, k), v in changes:
        raw.setdefault(s, {})[k] = [v, v] if SCHEMA[s][k].kind == "floatlist" else v
    outcome(raw, "numbers in numeric keys")


@fuzz_settings(300)
@given(st.data())
def test_a_wrong_type_names_its_key(data):
    s, k = data.draw(st.sampled_from(ALL_KEYS))
    v = data.draw(_wrong(SCHEMA[s][k].kind))
    raw = base()
    raw.setdefault(s, {})[k] = v
    e = outcome(raw, "wrong type")
    assert isinstance(e, ConfigError), f"{name_of(s, k)} = {v!r} accepted"
    assert e.key == name_of(s, k), f"{name_of(s, k)} = {v!r}: the error names {e.key!r}: {e}"


def _violates(spec, v):
    """Whether a number breaks the key's own constraints (finite, sign, bounds, choices)."""
    if not math.isfinite(v):
        return True
    if spec.choices and v not in spec.choices:
        return True
    return ((spec.positive and not v > 0) or (spec.nonnegative and not v >= 0)
            or (spec.lo is not None and not v >= spec.lo) or (spec.hi is not None and not v < spec.hi))


@st.composite
def out_of_range_numbers(draw):
    """(section, key, value): NaN, +-inf, zero or negative where positive, below lo, at or above hi."""
    s, k = draw(st.sampled_from([sk for sk in NUMERIC_KEYS if SCHEMA[sk[0]][sk[1]].kind != "floatlist"]))
    spec = SCHEMA[s][k]
    if spec.kind == "int":
        v = draw(st.one_of(st.integers(-(2 ** 63), 2 ** 63 - 1), st.sampled_from([-1, 0, 1, 2, 3])))
    else:
        v = draw(st.one_of(st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0, -1e-300, -1.0, 1.0,
                                            1.0 + 1e-12, 0.999999]),
                           st.floats(allow_nan=True, allow_infinity=True)))
    hypothesis.assume(_violates(spec, v))
    return s, k, v


@fuzz_settings(300)
@given(out_of_range_numbers())
def test_an_out_of_range_number_names_its_key(skv):
    """Out-of-range numbers: ConfigError on that key."""
    s, k, v = skv
    raw = base()
    raw.setdefault(s, {})[k] = v
    e = outcome(raw, "out of range")
    assert isinstance(e, ConfigError), f"{name_of(s, k)} = {v!r} accepted"
    assert e.key == name_of(s, k), f"{name_of(s, k)} = {v!r}: the error names {e.key!r}: {e}"


@fuzz_settings(200)
@given(st.sets(st.sampled_from([(s, k) for s in BASE for k in BASE[s]] + [(s, None) for s in BASE]), min_size=1))
def test_missing_keys(removed):
    raw = base()
    for s, k in removed:
        if k is None:
            raw.pop(s, None)
        else:
            raw.get(s, {}).pop(k, None)
    gone = {(s, k) for s, keys in SCHEMA.items() for k in keys if k not in raw.get(s, {})}
    required = [(s, k) for s, k in ALL_KEYS if SCHEMA[s][k].default is REQUIRED and (s, k) in gone]
    res = outcome(raw, "missing keys")
    if required:
        assert isinstance(res, ConfigError), f"accepted without {required}"
        assert res.key == name_of(*required[0]), (required, res.key, str(res))
        assert "missing" in res.reason
    elif ("numerics", "h") in gone:
        assert isinstance(res, ConfigError) and res.key == "numerics.h", res
    else:
        assert not isinstance(res, ConfigError), f"removing {sorted(removed, key=str)} gave {res}"


@fuzz_settings(300)
@given(st.data())
def test_unknown_keys_and_sections(data):
    raw = base()
    case = data.draw(st.sampled_from(["key", "section", "not_a_table"]))
    if case == "key":
        s = data.draw(st.sampled_from(list(SCHEMA)))
        k = data.draw(key_names.filter(lambda x: x not in SCHEMA[s]))
        raw.setdefault(s, {})[k] = data.draw(st.one_of(numbers, st.text(max_size=5), st.booleans()))
        expect = name_of(s, k)
    elif case == "section":
        s = data.draw(key_names.filter(lambda x: x not in SCHEMA))
        raw[s] = data.draw(st.one_of(st.dictionaries(key_names, st.one_of(numbers, st.booleans()), max_size=2),
                                     numbers, st.text(max_size=5)))
        expect = s
    else:
        s = data.draw(st.sampled_from(list(SCHEMA)))
        raw[s] = data.draw(st.one_of(numbers, st.text(max_size=5), st.booleans(), st.lists(numbers, max_size=2)))
        expect = s
    e = outcome(raw, "unknown key or section")
    assert isinstance(e, ConfigError), f"{case} {s!r} accepted"
    assert e.key == expect, f"{case}: the error names {e.key!r}, not {expect!r}: {e}"


@fuzz_settings(300)
@given(st.one_of(st.text(max_size=200),
                 st.lists(st.sampled_from(BASE_TEXT.splitlines() + ["[numerics]", "Nx = 1e400", "dt = nan",
                                                                    "k = inf", "[[output]]", "x.y = 1",
                                                                    "material = 3", "t_end = 1979-05-27"]),
                          max_size=30).map("\n".join)))
def test_random_text(text):
    COUNTS["random text"] += 1
    try:
        cfg = config.loads(text)
    except ConfigError as e:
        assert "\n" not in str(e) and e.key, repr(str(e))
        return
    check_config(cfg)


@fuzz_settings(300)
@given(st.lists(st.one_of(
    st.text(PRINTABLE, max_size=30),
    st.tuples(st.sampled_from([*SCHEMA, "scene.name", "x", ""]), st.sampled_from([k for _, k in ALL_KEYS] + ["y", ""]),
              st.one_of(st.text(PRINTABLE, max_size=12), st.sampled_from(["nan", "inf", "-inf", "1e400", "10000000", "[]",
                                                               "[1, 2]", "[nan]", "true", "\"auto\"", "auto",
                                                               "{a = 1}", "1979-05-27", "0", "-1", "[0.1, \"a\"]"])))
    .map(lambda t: f"{t[0]}.{t[1]}={t[2]}")), min_size=1, max_size=3))
def test_random_overrides(overrides):
    COUNTS["--set overrides"] += 1
    try:
        cfg = config.loads(BASE_TEXT, overrides)
    except ConfigError as e:  # the key of a malformed override is the override as given (may be "")
        assert "\n" not in str(e) and str(e).startswith(f"{e.key}: "), repr(str(e))
        return
    check_config(cfg)


@fuzz_settings(50)
@given(st.binary(max_size=300))
def test_random_bytes_as_a_run_file(blob):
    COUNTS["random bytes file"] += 1
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "run.toml")
        with open(path, "wb") as f:
            f.write(blob)
        try:
            config.load(path)
        except ConfigError as e:
            assert "\n" not in str(e) and e.key, repr(str(e))


# Extreme numbers, with the exception each raises in build()'s arithmetic unless validation refuses
# it first; every one must be a ConfigError naming one of the keys listed.
EXTREME = {
    "t_end_int_beyond_float": ({"output": {"t_end": 10 ** 400}}, {"output.t_end"}),  # OverflowError in _typed
    "Nx_int_beyond_float": ({"numerics": {"Nx": 10 ** 400}}, {"numerics.Nx"}),  # OverflowError: L / Nx
    "layers_int_beyond_float": ({"walls": {"layers": 10 ** 400}}, {"walls.layers"}),  # OverflowError
    "L_subnormal": ({"domain": {"L": 5e-324}}, {"domain.L", "numerics.Nx"}),  # ZeroDivisionError: Ly / dx
    "Ly_huge": ({"domain": {"Ly": 1.7976931348623157e308}}, {"domain.Ly"}),  # OverflowError: round(inf)
    "Lz_huge_3d": ({"scene": {"dim": 3}, "domain": {"Lz": 1.7976931348623157e308}}, {"domain.Lz"}),
    "g_int_beyond_float": ({"body_force": {"g": [0, 10 ** 400]}}, {"body_force.g"}),  # isfinite(int)
    "h_huge": ({"numerics": {"h": 1.7976931348623157e308}}, {"numerics.h", "walls.layers", "domain.Ly"}),
    "G_a_huge": ({"material": {"G_a": 1e30}}, {"material.G_a", "material.G_b"}),  # OverflowError: 10.0 ** x
    "G_b_huge": ({"material": {"G_b": 1e7}}, {"material.G_a", "material.G_b"}),
    "dt_subnormal": ({"numerics": {"dt": 2.2e-311}}, {"numerics.dt", "output.t_end"}),  # round(t_end / dt = inf)
    "t_end_huge": ({"output": {"t_end": 1e308}}, {"output.t_end", "numerics.dt"}),
}


@pytest.mark.parametrize("case", sorted(EXTREME))
def test_extreme_numbers_are_config_errors(case):
    changes, keys = EXTREME[case]
    raw = base()
    for s, kv in changes.items():
        raw.setdefault(s, {}).update(kv)
    try:
        res = outcome(raw, "extreme numbers")
    except Exception as e:  # noqa: BLE001 - report the crash precisely
        pytest.fail(f"{changes}: {type(e).__name__}: {e} (expected ConfigError naming one of {sorted(keys)})")
    assert isinstance(res, ConfigError), f"{changes} accepted"
    assert res.key in keys, f"{changes}: the error names {res.key!r}: {res}"


def test_a_key_name_with_a_line_break_stays_on_one_line():
    """TOML allows any quoted key, line breaks included; the message must stay one line (repr the name)."""
    for raw in ({**base(), "a\nb": {}}, {**base(), "material": {**BASE["material"], "x\ny": 1}}):
        with pytest.raises(ConfigError) as e:
            validate_raw(raw)
        COUNTS["key with a line break"] += 1
        assert "\n" not in str(e.value), repr(str(e.value))
    # parsph run --set $'material.k\n=1': whitespace around a key is trimmed, as TOML does
    assert config.loads(BASE_TEXT, ["material.k\n=1"]).k == 1.0
    with pytest.raises(ConfigError) as e:  # parsph run --set $'mate\nrial.k=1'
        config.loads(BASE_TEXT, ["mate\nrial.k=1"])
    assert "\n" not in str(e.value), repr(str(e.value))


def test_nan_and_inf_in_the_toml_text_name_the_key():
    """The TOML spellings nan / inf reach the same checks as Python's floats."""
    for key, section, text in (("numerics.dt", "numerics", "dt = nan"), ("material.k", "material", "k = inf"),
                               ("output.times", "output", "times = [0.01, -inf]")):
        lines = [ln for ln in BASE_TEXT.splitlines() if not ln.startswith(text.split(" ")[0] + " ")]
        doc = "\n".join(lines).replace(f"[{section}]", f"[{section}]\n{text}")
        with pytest.raises(ConfigError) as e:
            config.loads(doc)
        assert e.value.key == key, str(e.value)
        COUNTS["spelled nan/inf"] += 1


# ---- on the command line --------------------------------------------------------------------

launches = pytest.mark.skipif(C.under_mpirun(), reason="launches parsph/mpirun itself (nested mpirun fails)")
RLIMIT_AS = 8 * 2 ** 30  # a run that allocates before refusing fails (exit 1) instead of swapping the machine
HANG_GUARD = 300  # s: a launched command still running after this is killed and fails its test
SMALL = ("output.t_end=0.0001", "output.times=[0.0001]", *C.SHORT)


def _limit():
    resource.setrlimit(resource.RLIMIT_AS, (RLIMIT_AS, RLIMIT_AS))


def run_limited(cmd, timeout=HANG_GUARD, prefix=()):
    import subprocess
    import time
    t0 = time.monotonic()
    p = subprocess.Popen([*prefix, *map(str, cmd)], cwd=C.REPO, env=C.env(), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, encoding="utf-8", errors="backslashreplace",
                         start_new_session=True, preexec_fn=_limit)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        C.kill_tree(p.pid)
        out, err = p.communicate()
        raise AssertionError(f"no answer within {timeout} s:\n{out}\n{err}") from None
    return C.Result(p.returncode, out, err, time.monotonic() - t0)


def _without(text, section, key):
    out, current = [], None
    for ln in text.splitlines():
        if ln.startswith("["):
            current = ln.strip("[] ")
        if current == section and ln.split("=")[0].strip() == key:
            continue
        out.append(ln)
    return "\n".join(out) + "\n"


def _with(text, section, line):
    return text.replace(f"[{section}]", f"[{section}]\n{line}", 1)


def _replace(text, section, key, value):
    return _with(_without(text, section, key), section, f"{key} = {value}")


# name: (run-file text, extra args, key the message must name, a word of the reason)
BAD_FILES = {
    "wrong_type": (_replace(BASE_TEXT, "material", "k", '"one"'), [], "material.k", "number"),
    "nan": (_replace(BASE_TEXT, "numerics", "dt", "nan"), [], "numerics.dt", "finite"),
    "zero_Nx": (_replace(BASE_TEXT, "numerics", "Nx", "0"), [], "numerics.Nx", "at least"),
    "unknown_key": (_with(BASE_TEXT, "numerics", "nx = 50"), [], "numerics.nx", "unknown"),
    "missing_key": (_without(BASE_TEXT, "material", "rho_s"), [], "material.rho_s", "missing"),
    "inf_t_end": (_replace(BASE_TEXT, "output", "t_end", "inf"), [], "output.t_end", "finite"),
    "huge_Nx": (_replace(BASE_TEXT, "numerics", "Nx", "10000000"), [], "numerics.Nx", "neighbours"),
    "overflow_G_a": (_replace(BASE_TEXT, "material", "G_a", "1e308"), [], "material.G_", ""),
    "beyond_64_bit_Nx": (_replace(BASE_TEXT, "numerics", "Nx", "1" + "0" * 400), [], "numerics.Nx", ""),
    "not_toml": ("[numerics\nNx = 50\n", [], "not valid TOML", ""),
    "bad_set": (BASE_TEXT, ["--set", "numerics.Nx"], "numerics.Nx", "section.key=value"),
    "bad_set_value": (BASE_TEXT, ["--set", "numerics.kernel=gauss"], "numerics.kernel", "one of"),
}


def check_bad(r, key, word, ranks):
    assert "Traceback" not in r.stderr and "MPI_ABORT" not in r.stderr, r
    assert r.returncode == 2, r
    lines = C.parsph_lines(r.stderr)
    assert len(lines) == 1 and lines[0].startswith("parsph: error: "), r
    assert key in lines[0] and word in lines[0], r
    if not ranks:  # under mpirun, Open MPI adds a banner about the non-zero exit
        assert C.stderr_lines(r.stderr) == lines, r


@launches
@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_cli_bad_run_file(tmp_path, case):
    text, extra, key, word = BAD_FILES[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "out"
    r = run_limited(C.parsph("run", path, "--out", out, *extra))
    COUNTS["cli 1 rank"] += 1
    check_bad(r, key, word, 0)
    assert not out.exists() or not os.listdir(out), "a refused run wrote output"


@launches
def test_cli_missing_run_file(tmp_path):
    path = tmp_path / "nope.toml"
    r = run_limited(C.parsph("run", path, "--out", tmp_path / "out"))
    COUNTS["cli 1 rank"] += 1
    check_bad(r, str(path), "cannot read", 0)


@launches
def test_cli_creates_a_missing_output_directory(tmp_path):
    out = tmp_path / "a" / "b" / "c"
    r = run_limited(C.run_cmd(0, "--out", out, "--quiet", *C.sets(*SMALL)))
    COUNTS["cli 1 rank"] += 1
    assert r.returncode == 0, r
    assert C.h5_files(out) == [f"{C.STEM}_0000.h5"], os.listdir(out)


@launches
def test_cli_output_path_is_a_file(tmp_path):
    out = tmp_path / "file"
    out.write_text("x")
    r = run_limited(C.run_cmd(0, "--out", out, *C.sets(*SMALL)))
    COUNTS["cli 1 rank"] += 1
    check_bad(r, str(out), "cannot create output directory", 0)


@launches
def test_cli_force_overwrites_existing_output(tmp_path):
    """An existing output is left alone without --force (exit 2, naming the file and the flag)
    and replaced with it (the negative half is also in test_config_errors.py)."""
    import h5py
    out = tmp_path / "out"
    first = C.sets(*SMALL, "material.k=1.0")
    second = C.sets(*SMALL, "material.k=1.5")
    r = run_limited(C.run_cmd(0, "--out", out, "--quiet", *first))
    assert r.returncode == 0, r
    name = out / f"{C.STEM}_0000.h5"
    before = name.read_bytes()

    r = run_limited(C.run_cmd(0, "--out", out, "--quiet", *second))
    COUNTS["cli 1 rank"] += 1
    check_bad(r, str(name), "--force", 0)
    assert name.read_bytes() == before, "the output changed without --force"

    r = run_limited(C.run_cmd(0, "--out", out, "--quiet", "--force", *second))
    COUNTS["cli 1 rank"] += 1
    assert r.returncode == 0 and "Traceback" not in r.stderr, r
    assert C.h5_files(out) == [name.name] and not C.h5_files(out, part=True), os.listdir(out)
    with h5py.File(name, "r") as f:
        assert config.loads(f.attrs["run_file"]).k == 1.5, "--force did not replace the output"
        assert f["particles/id"].shape == (C.N_SHORT,)


def _unprivileged():
    """A command prefix under which root obeys file permissions (no CAP_DAC_OVERRIDE)."""
    if os.geteuid() != 0:
        return ()
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: cannot make a directory unwritable")
    caps = "-dac_override,-dac_read_search"
    return (setpriv, f"--bounding-set={caps}", f"--inh-caps={caps}")


@launches
@pytest.mark.parametrize("where", ["dir", "parent"])
def test_cli_output_directory_not_writable(tmp_path, where):
    ro = tmp_path / "ro"
    ro.mkdir()
    out = ro if where == "dir" else ro / "sub"
    ro.chmod(0o555)
    try:
        r = run_limited(C.run_cmd(0, "--out", out, *C.sets(*SMALL)), prefix=_unprivileged())
    finally:
        ro.chmod(0o755)
    COUNTS["cli 1 rank"] += 1
    check_bad(r, str(out), "not writable" if where == "dir" else "cannot create output directory", 0)


@launches
@pytest.mark.parametrize("case", ["wrong_type", "huge_Nx", "overflow_G_a", "out_is_file", "out_read_only"])
def test_cli_bad_input_under_mpirun(tmp_path, case):
    """Every rank ends alike: exit 2, one parsph line (from rank 0), no MPI_Abort, no hang.

    A read-only output directory runs ``mpirun`` under setpriv (root without
    CAP_DAC_OVERRIDE), so that every rank's ``os.access`` sees the permissions.
    """
    out, prefix = tmp_path / "out", ()
    if case == "out_is_file":
        out.write_text("x")
        text, extra, key, word = BASE_TEXT, list(C.sets(*SMALL)), str(out), "cannot create output directory"
    elif case == "out_read_only":
        out.mkdir()
        out.chmod(0o555)
        prefix = _unprivileged()
        text, extra, key, word = BASE_TEXT, list(C.sets(*SMALL)), str(out), "not writable"
    else:
        text, extra, key, word = BAD_FILES[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    try:
        r = run_limited(C.mpirun(2, C.parsph("run", path, "--out", out, *extra)), prefix=prefix)
    finally:
        if out.is_dir():
            out.chmod(0o755)
    COUNTS["cli mpirun -n 2"] += 1
    check_bad(r, key, word, 2)


# ---- the command line under hypothesis ---------------------------------------------------------

def toml_text(raw):
    """TOML text that tomllib reads back as ``raw``: any value the strategies draw (NaN, +-inf,
    ints beyond 64 bits, datetimes, nested tables and arrays, any printable key name)."""
    def quoted(x):  # a TOML basic string: JSON's escapes are TOML's, plus DEL
        return json.dumps(x, ensure_ascii=False).replace("\x7f", "\\u007f")

    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)  # nan, inf, -inf, 1e+300, -0.0 are TOML too
        if isinstance(v, str):
            return quoted(v)
        if isinstance(v, (datetime.datetime, datetime.date, datetime.time)):
            return v.isoformat()
        if isinstance(v, list):
            return "[" + ", ".join(map(value, v)) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{quoted(k)} = {value(x)}" for k, x in v.items()) + "}"
        raise TypeError(type(v))

    top = [f"{quoted(s)} = {value(v)}" for s, v in raw.items() if not isinstance(v, dict)]
    tables = [f"[{quoted(s)}]\n" + "".join(f"{quoted(k)} = {value(v)}\n" for k, v in keys.items())
              for s, keys in raw.items() if isinstance(keys, dict)]
    return "\n".join(top) + "\n" + "\n".join(tables)


MEMORY = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")  # what the memory check reads
# Nx at and above which the paper box (Ly = L) cannot fit in this machine's memory at any h / dx >= 1
# (Nx^2 particles of at least 500 bytes each: above 80% of the memory)
NX_TOO_MANY = math.isqrt(MEMORY // 500) + 1
OUT_KINDS = ("missing", "empty", "read-only", "missing under read-only")
CLI_CASES = ("bad value", "bad key", "huge Nx", "unusable directory")
REQUIRED_IN_BASE = [(s, k) for s in BASE for k in BASE[s] if SCHEMA[s][k].default is REQUIRED]


@st.composite
def bad_runs(draw, case):
    """(raw run file, output directory kind, key the one error line must name, a word of its reason)."""
    raw = base()
    out_kind = draw(st.sampled_from(OUT_KINDS))
    if case in ("bad value", "bad key"):
        case = draw(st.sampled_from(("wrong type", "out of range") if case == "bad value" else
                                    ("missing key", "unknown key")))
    if case == "wrong type":
        s, k = draw(st.sampled_from(ALL_KEYS))
        raw.setdefault(s, {})[k] = draw(_wrong(SCHEMA[s][k].kind))
        return raw, out_kind, name_of(s, k), ""
    if case == "out of range":
        s, k, v = draw(out_of_range_numbers())
        raw.setdefault(s, {})[k] = v
        return raw, out_kind, name_of(s, k), ""
    if case == "missing key":
        s, k = draw(st.sampled_from(REQUIRED_IN_BASE))
        del raw[s][k]
        return raw, out_kind, name_of(s, k), "missing"
    if case == "unknown key":
        s = draw(st.sampled_from(list(SCHEMA)))
        k = draw(key_names.filter(lambda x: x not in SCHEMA[s]))
        raw.setdefault(s, {})[k] = draw(st.one_of(numbers, st.text(max_size=5), st.booleans()))
        return raw, out_kind, name_of(s, k), "unknown"
    if case == "huge Nx":  # refused before anything is allocated
        if draw(st.booleans()):  # the paper's h: h / dx = Nx / 40 (at most 1e6): too many neighbours
            raw["numerics"]["Nx"] = draw(st.integers(max(NX_TOO_MANY, 10 ** 6), 4 * 10 ** 7))
            return raw, out_kind, "numerics.Nx", "neighbours"
        else:  # h / dx given: dt auto, a short t_end (t_end / dt stays under 1e12): the memory estimate
            num = raw["numerics"]
            del num["h"]
            num.update(h_over_dx=draw(st.floats(1.0, 2.0)), dt="auto",
                       Nx=draw(st.integers(NX_TOO_MANY, max(10 ** 7, 2 * NX_TOO_MANY))))
            raw["output"].update(t_end=1e-4, times=[1e-4])
        return raw, out_kind, "numerics.Nx", "GB"
    assert case == "unusable directory", case  # a good run file (short, in case it is accepted)
    for item in SMALL:
        (s, k), v = item.split("=")[0].split("."), tomllib.loads("v = " + item.split("=")[1])["v"]
        raw[s][k] = v
    out_kind = draw(st.sampled_from(("read-only", "missing under read-only", "a file")))
    word = "not writable" if out_kind == "read-only" else "cannot create output directory"
    return raw, out_kind, None, word


def _cli_property(ranks, case, example):
    raw, out_kind, key, word = example
    text = toml_text(raw)
    # the run file is what the strategy meant: the in-process validation names the same key
    try:
        cfg = config.loads(text)
    except ConfigError as e:
        assert key is not None and e.key == key, f"{case}: {key}: in process the error names {e.key!r}: {e}"
    else:
        assert key is None or case == "huge Nx", f"{case}: {key} accepted in process"
        if case == "huge Nx":
            need = cfg.n_particles * memory.bytes_per_particle(cfg)
            assert need > 0.8 * MEMORY, f"Nx = {cfg.Nx}: {need / 1e9:.3g} GB fits"
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        path = d / "bad.toml"
        path.write_text(text, encoding="utf-8")
        ro = d / "ro"
        out = {"missing": d / "out", "empty": d / "out", "read-only": ro, "missing under read-only": ro / "out",
               "a file": d / "file"}[out_kind]
        if out_kind == "empty":
            out.mkdir()
        elif out_kind == "a file":
            out.write_text("x")
        elif "read-only" in out_kind:
            ro.mkdir()
            ro.chmod(0o555)
        prefix = _unprivileged() if "read-only" in out_kind else ()
        cmd = C.parsph("run", path, "--out", out)
        try:
            r = run_limited(C.mpirun(ranks, cmd) if ranks > 1 else cmd, prefix=prefix)
        finally:
            if ro.exists():
                ro.chmod(0o755)
        COUNTS[f"cli property, {'1 rank' if ranks == 1 else f'mpirun -n {ranks}'}"] += 1
        check_bad(r, str(out) if key is None else key, word, 0 if ranks == 1 else ranks)
        if key is not None:  # a bad run file is refused before the output directory is touched
            if out_kind in ("missing", "missing under read-only"):
                assert not out.exists(), f"{out} created for a refused run"
            else:
                assert not os.listdir(out), f"a refused run wrote into {out}: {os.listdir(out)}"


@launches
@pytest.mark.parametrize("case", CLI_CASES)
@fuzz_settings(3)
@given(data=st.data())
def test_cli_property_one_rank(case, data):
    """Bad run files and output directories drawn from the strategies above, on ``parsph run``:
    exit 2, one ``parsph: error:`` line naming the key, no traceback, no hang."""
    _cli_property(1, case, data.draw(bad_runs(case)))


@launches
@pytest.mark.parametrize("case", CLI_CASES)
@fuzz_settings(2)
@given(data=st.data())
def test_cli_property_two_ranks(case, data):
    """The same under ``mpirun -n 2``: every rank ends alike, no MPI_Abort, no hang."""
    _cli_property(2, case, data.draw(bad_runs(case)))


# ---- the memory check, with a stubbed memory figure ------------------------------------------------

class _StubComm:
    """Enough of a communicator for case.fits_in_memory: ``allgather`` reports the stubbed
    memory of each of ``hosts`` nodes (several ranks of one node count once)."""

    def __init__(self, mem, hosts, ranks):
        self.mem, self.hosts, self.ranks = mem, hosts, ranks

    def allgather(self, item):
        return [(f"node{r % self.hosts}", self.mem) for r in range(self.ranks)]


class _StubMPI:
    @staticmethod
    def Get_processor_name():
        return "node0"


@fuzz_settings(200)
@given(st.data())
def test_memory_check_for_huge_particle_counts(data):
    """Random large Nx, Ly and Lz in 2-D and 3-D against a stubbed memory figure: refused
    (ConfigError on numerics.Nx with the estimate in GB) exactly when the particles need more
    than 80% of the nodes' memory, accepted otherwise.

    The run's linear stability limit is stubbed too (a constant): its lattice sums cost 0.1-0.3 s
    for every new h / dx (35 s of the 200 examples), and the time step is not this property's subject
    (the validation properties above run it)."""
    from parsph.simulation import case
    from parsph.physics import limits
    raw = base()
    dim = data.draw(st.sampled_from([2, 3]))
    num = raw["numerics"]
    del num["h"]
    num.update(Nx=data.draw(st.one_of(st.integers(1000, 10 ** 6), st.integers(10 ** 6, 10 ** 9))),
               h_over_dx=data.draw(st.floats(1.0, 3.0)), dt="auto")
    raw["scene"]["dim"] = dim
    raw["domain"]["Ly"] = data.draw(st.floats(0.002, 1.0))
    raw["domain"]["Lz"] = data.draw(st.floats(0.002, 1.0))
    raw["output"].update(t_end=1e-9, times=[1e-9])
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(limits, "_linear_cached", lambda *args: (1e-5, "damping"))
            cfg = validate_raw(raw)
    except ConfigError as e:  # e.g. Ly / dx beyond 2^40 rows: not this property's subject
        COUNTS["memory check (stubbed memory), refused earlier"] += 1
        assert e.key != "numerics.Nx" or "GB" not in str(e), e
        return
    need = cfg.n_particles * memory.bytes_per_particle(cfg)
    # memory from far below to far above the need, on 1 to 4 nodes of 1 to 8 ranks each
    mem = int(need * 10 ** data.draw(st.floats(-3.0, 3.0)))
    hosts = data.draw(st.integers(1, 4))
    comm = _StubComm(mem, hosts, hosts * data.draw(st.integers(1, 8)))
    with pytest.MonkeyPatch.context() as mp:  # the stubbed nodes' names
        mp.setattr(case, "MPI", _StubMPI)
        try:
            case.fits_in_memory(comm, cfg)
        except ConfigError as e:
            COUNTS["memory check (stubbed memory), refused"] += 1
            assert need > 0.8 * mem * hosts, f"refused: {need:.3g} B of {mem * hosts:.3g} B: {e}"
            assert e.key == "numerics.Nx", e
            msg = str(e)
            assert "\n" not in msg and msg.startswith("numerics.Nx: "), msg
            assert f"{need / 1e9:.3g} GB" in msg and f"{cfg.n_particles:,} particles" in msg, msg
            assert f"{mem * hosts / 1e9:.3g} GB" in msg and f"{hosts} node(s)" in msg, msg
        else:
            COUNTS["memory check (stubbed memory), accepted"] += 1
            assert need <= 0.8 * mem * hosts, f"accepted: {need:.3g} B of {mem * hosts:.3g} B"

