"""The CLI skeleton: help, version, one-line errors."""

from __future__ import annotations

import subprocess
import sys

from shprobe import __version__
from shprobe.cli.main import main


def test_version(capsys):
    assert main(["--version"]) == 0
    assert __version__ in capsys.readouterr().out


def test_help_lists_groups(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "Usage" in out and "shprobe" in out


def test_unknown_command_is_one_line_error(capsys):
    assert main(["no-such-command"]) != 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("shprobe: error:") and "\n" not in err


def test_console_script_runs_without_traceback():
    r = subprocess.run([sys.executable, "-m", "shprobe", "--bogus-flag"], capture_output=True,
                       text=True)
    assert r.returncode != 0
    assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1


def test_bare_groups_print_their_help(capsys):
    for args in ([], ["sh"], ["prt"], ["hbasis"]):
        assert main(args) == 0
        out = capsys.readouterr()
        assert out.out.startswith("Usage: shprobe") and "Commands:" in out.out
        assert out.err == ""
