"""The top level of the ``parsph`` command: its version and its help (in process, no MPI).

    .venv/bin/python -m pytest -q tests/test_command_line.py
"""
import importlib.metadata
import re

import pytest

from parsph.cli import main

COMMANDS = ("run", "check", "converge", "plot")


def test_version_is_the_installed_distributions(capsys):
    """``parsph --version``: exit 0 and the version the installed metadata (pyproject.toml) gives."""
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out == f"parsph {importlib.metadata.version('parsph')}\n"


def test_help_names_every_command_in_plain_text(capsys):
    """``parsph --help``: each of the four commands in the description and in the list, no reST markup."""
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    description = text.split("positional arguments")[0]
    for c in COMMANDS:
        assert re.search(rf"\b{c}\b", description), (c, description)
        assert re.search(rf"^\s+{c}\s+\S", text, re.M), (c, text)  # its line in the list of commands
    assert "``" not in text and ":mod:" not in text, text
