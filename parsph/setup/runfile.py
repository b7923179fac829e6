"""Run files as values (:class:`RunFile`): TOML text in, ``--set section.key=value`` overrides, TOML text out
(the text an output file stores, from which a restart reads the run again).

A RunFile holds the tables as TOML gives them, before validation: every
change makes a new one, so a study derives its variants from one base
without copying dicts by hand. :func:`parsph.setup.config.build` validates
one and derives the run.
"""
import tomllib

from parsph.errors import ConfigError


def parse_value(text):
    """A --set value: TOML syntax (numbers, true/false, lists, quoted strings) or a bare string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _copy(tables):
    """Sections and list values copied, so that no caller shares what a RunFile holds."""
    return {s: ({k: list(v) if isinstance(v, list) else v for k, v in keys.items()} if isinstance(keys, dict)
                else keys) for s, keys in tables.items()}


class RunFile:
    """The tables of a run file (``{section: {key: value}}``), unvalidated; an immutable value."""

    __slots__ = ("_tables",)

    def __init__(self, tables=None):
        if not isinstance(tables if tables is not None else {}, dict):
            raise ConfigError("<file>", "not a TOML table")
        self._tables = _copy(tables or {})

    @classmethod
    def parse(cls, text):
        """A run file from TOML text."""
        try:
            return cls(tomllib.loads(text))
        except tomllib.TOMLDecodeError as e:
            raise ConfigError("<file>", f"not valid TOML: {e}") from None

    @classmethod
    def read(cls, path):
        """A run file from a TOML file."""
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError as e:
            raise ConfigError("<file>", f"cannot read {path}: {e.strerror}") from None
        try:
            return cls(tomllib.loads(data.decode("utf-8")))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise ConfigError("<file>", f"{path} is not valid TOML: {e}") from None

    def tables(self):
        """A copy of the tables."""
        return _copy(self._tables)

    def get(self, section, key, default=None):
        keys = self._tables.get(section)
        return keys.get(key, default) if isinstance(keys, dict) else default

    def set(self, section, **keys):
        """This run file with ``section.key = value`` for each keyword (a key already there keeps its place)."""
        tables = self.tables()
        if not isinstance(tables.get(section, {}), dict):
            raise ConfigError(section, "expected a table")
        tables.setdefault(section, {}).update(keys)
        return RunFile(tables)

    def drop(self, section, key):
        """This run file without ``section.key`` (unchanged where it has none)."""
        tables = self.tables()
        if isinstance(tables.get(section), dict):
            tables[section].pop(key, None)
        return RunFile(tables)

    def override(self, items):
        """This run file with ``section.key=value`` strings applied (``parsph run --set``)."""
        out = self
        for item in items:
            if "=" not in item:
                raise ConfigError(item, "an override must look like section.key=value")
            name, text = item.split("=", 1)
            parts = name.strip().split(".")
            if len(parts) != 2 or not all(parts):
                raise ConfigError(name, "an override key must look like section.key")
            section, key = parts
            out = out.set(section, **{key: parse_value(text.strip())})
        return out

    def dump(self):
        """The run file as TOML (tables of scalars and lists only)."""
        lines = []
        for section, keys in self._tables.items():
            if not isinstance(keys, dict):
                continue
            lines.append(f"[{section}]")
            for key, value in keys.items():
                try:
                    lines.append(f"{key} = {_toml_value(value)}")
                except TypeError:
                    raise ConfigError(f"{section}.{key}", f"unsupported value {value!r}") from None
            lines.append("")
        return "\n".join(lines)

    def __eq__(self, other):
        return isinstance(other, RunFile) and self._tables == other._tables

    __hash__ = None

    def __repr__(self):
        return f"RunFile({self._tables!r})"


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(type(v))
