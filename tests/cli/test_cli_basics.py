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


def test_lazy_command_map_matches_the_modules():
    """Every command a ``shprobe.cli`` module registers is in ``COMMANDS`` under that module,
    and nothing else is (the group imports a module only when one of its commands is used)."""
    import importlib
    import pkgutil

    import click

    import shprobe.cli as pkg
    from shprobe.cli.main import COMMANDS

    registered = {}
    for info in pkgutil.iter_modules(pkg.__path__):
        mod = importlib.import_module(f"shprobe.cli.{info.name}")
        if hasattr(mod, "register"):
            g = click.Group()
            mod.register(g)
            registered.update(dict.fromkeys(g.commands, info.name))
    assert registered == COMMANDS


def test_a_command_imports_only_its_own_modules():
    code = ("import sys; from shprobe.cli.main import main; main(['view', '--help']); "
            "print(sorted(m for m in sys.modules if m.startswith('shprobe.cli.')))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    # cli.output holds the group's -q/-v state, which every command reads
    assert r.stdout.strip().splitlines()[-1] == (
        "['shprobe.cli.main', 'shprobe.cli.output', 'shprobe.cli.view']")


def test_terminal_progress_plain_lines_off_a_terminal():
    """Off a terminal each stage is one plain line, no control codes, no blank lines."""
    import io

    from shprobe.cli.progress import TerminalProgress
    from shprobe.progress import stage, track

    buf = io.StringIO()
    rep = TerminalProgress(stream=buf, log_after=0)
    assert list(track(range(3), rep, "tracing rays", index=1, count=2)) == [0, 1, 2]
    with stage(rep, "gathering", total=5, index=2, count=2) as bar:
        bar.advance(5)
    assert buf.getvalue() == "1/2: tracing rays …\n2/2: gathering …\n"
    # by default a log gets the line of a stage still under way after a second, only
    import time

    buf = io.StringIO()
    rep = TerminalProgress(stream=buf, log_after=0.2)
    with stage(rep, "quick", index=1, count=2):
        pass
    with stage(rep, "slow", index=2, count=2):
        time.sleep(0.5)
        assert buf.getvalue() == "2/2: slow …\n"
    assert buf.getvalue() == "2/2: slow …\n"
    quiet = io.StringIO()
    list(track(range(3), TerminalProgress(quiet=True, stream=quiet), "x"))
    assert quiet.getvalue() == ""


def test_quiet_flag_silences_the_wrote_line(tmp_path):
    from click.testing import CliRunner

    from shprobe.cli.main import cli

    out = tmp_path / "c.json"
    r = CliRunner().invoke(cli, ["-q", "prefilter", "--preset", "grace", "--format", "json",
                                 "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert out.exists() and "wrote" not in r.output
