"""The settings of a batch run: where it runs ([`Engine`][shprobe.batch.Engine]) and
[`BatchSettings`][shprobe.batch.BatchSettings] (what each row computes, the layout, the engine, how
often the output is written)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from .rows import BatchOptions

__all__ = ["BatchSettings", "Engine"]


@dataclass(frozen=True)
class Engine:
    """Where a batch runs: ``client`` (a ``distributed.Client``) if given; else ``scheduler``:
    ``"inline"`` runs in this process, ``"tcp://HOST:PORT"`` (or ``$DASK_SCHEDULER_ADDRESS``
    when ``scheduler`` is None) uses that Dask cluster, otherwise a local cluster of ``workers``
    processes (default: one per core) × 1 thread is started and closed again. On Dask, each
    task computes ``chunk`` probes (below 1 means 1; default `chunk_size`: up to 8, fewer
    for small batches), the largest files first."""

    scheduler: str | None = None
    workers: int | None = None
    client: Any = None
    chunk: int | None = None


@dataclass(frozen=True)
class BatchSettings:
    """Settings of a batch run ([`run_batch`][shprobe.batch.run_batch]); the defaults are ``shprobe
    batch``'s.

    Parameters
    ----------
    options
        What each row computes ([`BatchOptions`][shprobe.batch.BatchOptions]: lmax, clamp, window,
        reference, thumbnail).
    layout
        The probes' layout ('auto': detected per file).
    engine
        Where it runs ([`Engine`][shprobe.batch.Engine]; default a local Dask cluster).
    flush_rows
        Rows per part written to the output while the batch runs.
    flush_seconds
        Seconds after which the rows so far are written anyway.
    """

    options: BatchOptions = field(default_factory=BatchOptions)
    layout: str = "auto"
    engine: Engine = field(default_factory=Engine)
    flush_rows: int = 256
    flush_seconds: float = 30.0

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values (the engine by its scheduler and workers).

        Returns
        -------
        dict
            options, layout, engine, flush_rows, flush_seconds.
        """
        e = self.engine
        return {"options": asdict(self.options), "layout": self.layout,
                "engine": {"scheduler": e.scheduler, "workers": e.workers, "chunk": e.chunk,
                           "client": e.client is not None},
                "flush_rows": self.flush_rows, "flush_seconds": self.flush_seconds}
