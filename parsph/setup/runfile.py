"""Run files as TOML text: ``--set section.key=value`` overrides, and a raw run-file dict written back as TOML
(the text an output file stores, from which a restart reads the run again)."""
import tomllib

from parsph.errors import ConfigError


def parse_value(text):
    """A --set value: TOML syntax (numbers, true/false, lists, quoted strings) or a bare string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(raw, overrides):
    """Apply ``section.key=value`` strings to a raw run-file dict (in place)."""
    for item in overrides:
        if "=" not in item:
            raise ConfigError(item, "an override must look like section.key=value")
        name, text = item.split("=", 1)
        parts = name.strip().split(".")
        if len(parts) != 2 or not all(parts):
            raise ConfigError(name, "an override key must look like section.key")
        section, key = parts
        if not isinstance(raw.get(section, {}), dict):
            raise ConfigError(section, "expected a table")
        raw.setdefault(section, {})[key] = parse_value(text.strip())
    return raw


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


def dumps(raw):
    """Write a raw run-file dict back as TOML (tables of scalars and lists only)."""
    lines = []
    for section, keys in raw.items():
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
