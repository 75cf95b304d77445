"""Entry point: the ``shprobe`` command group and its one-line error handling."""

from __future__ import annotations

import sys

import click

from .._version import __version__
from ..errors import ShprobeError

#: Each command → the module of ``shprobe.cli`` whose ``register(group)`` adds it. A module is
#: imported when one of its commands is first looked up (click's lazily loaded subcommands), so
#: a command pays only for its own layers: ``shprobe view`` forks its file loaders ~0.2 s
#: sooner than with every module imported first. ``tests/cli/test_cli_basics.py`` checks this map
#: against what the modules register.
COMMANDS: dict[str, str] = {
    "sh": "sh",
    "demo": "prefilter", "error": "prefilter", "irradiance": "prefilter", "prefilter": "prefilter",
    "basis-images": "render", "edit": "render", "export": "render", "render": "render",
    "window": "render",
    "hbasis": "hbasis", "prt": "prt", "fit": "fit", "report": "report", "batch": "batch",
    "view": "view",
    "splat": "splat",
    "grid": "grid",
    "lightmap": "lightmap_figures",  # the lightmap group (cli.lightmap) with its figures
}


class LazyGroup(click.Group):
    """The top-level group: commands from `COMMANDS`, their modules imported on use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(self.commands) | set(COMMANDS))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            import importlib

            importlib.import_module(f"{__package__}.{COMMANDS[cmd_name]}").register(self)
        return self.commands.get(cmd_name)


@click.group(cls=LazyGroup,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "--version", "-V", prog_name="shprobe")
@click.option("--max-memory", metavar="SIZE", default=None,
              help="Refuse work estimated to need more memory than SIZE (e.g. 2G); default: "
                   "80 % of the available memory (lowered by SHPROBE_MAX_MEMORY).")
@click.option("-q", "--quiet", is_flag=True, help="Print no progress and no 'wrote …' line.")
@click.option("-v", "--verbose", is_flag=True, help="Print more detail about the work done.")
@click.pass_context
def cli(ctx: click.Context, max_memory: str | None, quiet: bool, verbose: bool) -> None:
    """shprobe: spherical-harmonic lighting — irradiance environment maps, SH rotation,
    H-basis, precomputed radiance transfer, lighting from photographs, batch tables and an
    interactive viewer.

    Start with `shprobe demo`, which needs no files.
    """
    from ..limits import Limits
    from .output import Verbosity

    limits = Limits.parse(max_memory)
    ctx.obj = Verbosity(quiet=quiet, verbose=verbose and not quiet, limits=limits)
    # the workflows take the limits in their settings; every other check the command makes
    # (readers, estimates) reads them from this scope, which ends with the command
    ctx.with_resource(limits.applied())


#: Setting names the library's messages use → the CLI flags that set them.
SETTING_FLAGS: dict[str, str] = {
    "the max_memory limit": "--max-memory",
    "sh_degree": "--sh-degree",
    "albedo given": "--albedo given",
    "azimuth must be": "--azimuth must be",
    "elevation must be": "--elevation must be",
    "turntable needs": "--turntable needs",
}


def cli_terms(message: str) -> str:
    """A library message in the CLI's terms: each setting it names becomes its flag."""
    import re

    for name, flag in SETTING_FLAGS.items():
        message = re.sub(rf"(?<![\w-]){re.escape(name)}(?![\w-])", flag, message)
    return message


def _err(msg: str) -> None:
    click.echo(f"shprobe: error: {cli_terms(msg)}", err=True)


def _on_signal(signum: int, frame) -> None:
    raise SystemExit(128 + signum)  # unwinds: temporary outputs are removed on the way


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; bad input gives one line on stderr and a non-zero exit, no traceback.

    SIGTERM and SIGHUP unwind like Ctrl-C, so no temporary file is left behind; an unexpected
    exception is one line too, with a request to report it (SHPROBE_DEBUG=1 shows the
    traceback).
    """
    import os
    import signal

    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            try:
                signal.signal(sig, _on_signal)
            except ValueError:  # not the main thread (e.g. called from a worker)
                pass
    try:
        rv = cli.main(args=argv, prog_name="shprobe", standalone_mode=False)
    except click.exceptions.Exit as e:
        return e.exit_code
    except click.exceptions.NoArgsIsHelpError as e:  # a bare group: its help, as --help does
        click.echo(e.ctx.get_help() if e.ctx else e.format_message())
        return 0
    except click.exceptions.Abort:
        _err("aborted")
        return 130
    except click.ClickException as e:
        _err(e.format_message().replace("\n", " "))
        return e.exit_code
    except ShprobeError as e:
        _err(str(e))
        return 1
    except FileNotFoundError as e:
        _err(f"{e.filename}: no such file")
        return 1
    except OSError as e:
        name = f"{e.filename}: " if e.filename else ""
        _err(f"{name}{e.strerror or e}")
        return 1
    except KeyboardInterrupt:
        _err("interrupted")
        return 130
    except MemoryError:
        _err("out of memory (try a smaller size or degree)")
        return 1
    except Exception as e:  # a bug: still one line, and how to report it
        if os.environ.get("SHPROBE_DEBUG"):
            raise
        msg = str(e).splitlines()[0] if str(e) else ""
        _err(f"internal error {type(e).__name__}{': ' + msg if msg else ''} — please report "
             "it (run with SHPROBE_DEBUG=1 for the traceback)")
        return 70
    return rv if isinstance(rv, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
