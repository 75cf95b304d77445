"""What a batch run returns: [`BatchResult`][shprobe.batch.BatchResult], the table with the
run's counts and time."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["BatchResult"]


@dataclass(frozen=True, repr=False)
class BatchResult:
    """A batch run ([`run_batch`][shprobe.batch.run_batch]).

    Attributes
    ----------
    table
        The batch table (``pyarrow.Table``), one row per probe, sorted by path.
    output
        The ``.parquet`` file written (None: the table only).
    computed
        Rows this run added or replaced (the others were kept from a previous run).
    seconds
        Wall-clock time of the run.
    """

    table: Any
    output: Path | None
    computed: int
    seconds: float

    @property
    def rows(self) -> int:
        """Rows of the table (one per probe)."""
        return int(self.table.num_rows)

    @property
    def failed(self) -> int:
        """Rows whose probe failed (their message is in the ``failure`` column)."""
        return int(self.table.num_rows - self.table.column("failure").null_count)

    def as_dict(self) -> dict[str, Any]:
        """The run's figures as JSON-able values (the table itself is the Parquet file).

        Returns
        -------
        dict
            ``output``, ``rows``, ``failed``, ``computed``, ``kept``, ``seconds``, ``columns``
            and the options the rows depend on.
        """
        from .table import table_meta

        return {"output": None if self.output is None else str(self.output),
                "rows": self.rows, "failed": self.failed, "computed": self.computed,
                "kept": self.rows - self.computed, "seconds": self.seconds,
                "columns": list(self.table.column_names),
                "options": table_meta(self.table).get("options")}

    def __repr__(self) -> str:
        where = "" if self.output is None else f", {str(self.output)!r}"
        return (f"BatchResult({self.rows} rows, {self.failed} failed, {self.computed} computed, "
                f"{self.seconds:.2f} s{where})")
