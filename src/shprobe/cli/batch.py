"""``shprobe batch``: a library of probes → one Parquet table (shprobe.batch)."""

from __future__ import annotations

import click

from ..batch.rows import BatchOptions
from ..errors import ShprobeError
from .common import clamp_option, force_option, layout_option, setting_default


def _option_default(name: str):
    return setting_default(BatchOptions, name)


@click.command("batch")
@click.argument("inputs", nargs=-1, required=True, metavar="INPUTS...")
@click.option("--output", "-o", required=True, type=click.Path(dir_okay=False),
              help="Parquet table to write (resumed when it exists).")
@click.option("--lmax", "-n", type=click.IntRange(0, 16), default=_option_default("lmax"),
              show_default=True, help="Highest SH band.")
@layout_option
@clamp_option
@click.option("--reference", type=click.IntRange(2, 256), metavar="GRID",
              default=_option_default("reference"),
              help="Add the exact-irradiance error (R&H §3.1 metric, mean and max) on a "
                   "2GRID x GRID normal grid (slow: a hemispherical integral per normal).")
@click.option("--thumbnails", "thumbnail", type=click.IntRange(0, 1024),
              default=_option_default("thumbnail"),
              metavar="WIDTH", help="Add a tone-mapped PNG thumbnail WIDTH pixels wide.")
@click.option("--window/--no-window", default=_option_default("window"), show_default=True,
              help="Add the window `auto` would choose (--no-window: skip it; it costs more "
                   "than decoding a 2k probe when the lighting needs one).")
@click.option("--scheduler", envvar="DASK_SCHEDULER_ADDRESS", metavar="tcp://HOST:PORT",
              help="Run on this Dask scheduler (default $DASK_SCHEDULER_ADDRESS, else a "
                   "local cluster); 'inline' runs in this process.")
@click.option("--workers", "-j", type=click.IntRange(1, 1024),
              help="Worker processes of the local cluster (default: one per core).")
@click.option("--allow-failures", is_flag=True,
              help="Exit 0 even when some probes failed (their rows carry the message in "
                   "the 'failure' column); by default any failed probe makes the exit 1.")
@force_option
def batch_cmd(inputs, output, lmax, layout, clamp, reference, thumbnail, window, scheduler,
              workers, allow_failures, force):
    """Prefilter a library of probes into one Parquet table, one row per probe.

    INPUTS are image files, folders (searched recursively), globs ('**' recursive) or lists
    of paths (.txt one per line; .csv / .parquet with a 'path' and optional 'layout'
    column). A bad file becomes a row with its message in the 'failure' column; the exit
    is then 1 unless --allow-failures. Re-running with the same --output skips probes
    already done (by content hash); --force starts afresh. See docs/batch.md for the
    columns and for running on a cluster.
    """
    from .extras import require

    require("batch", "batch")
    from ..batch import BatchSettings, Engine, run_batch
    from .output import progress, wrote

    settings = BatchSettings(options=BatchOptions(lmax=lmax, clamp=clamp, reference=reference,
                                                  thumbnail=thumbnail, window=window),
                             layout=layout, engine=Engine(scheduler, workers))
    result = run_batch(inputs, output, settings, progress(), force=force)
    bad = result.failed
    wrote(output, f"{result.rows} probes, {bad} failed"
          + (" (see the 'failure' column)" if bad else ""))
    if bad and not allow_failures:
        raise ShprobeError(f"{bad} of {result.rows} probes failed (their messages are in "
                           "the table's 'failure' column; --allow-failures exits 0)", output)


def register(group: click.Group) -> None:
    """Add ``batch`` to the top-level group."""
    group.add_command(batch_cmd)
