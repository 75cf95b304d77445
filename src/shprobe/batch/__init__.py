"""Probe libraries at scale: one row per probe (SH coefficients, irradiance matrix, ∫L dω,
dominant direction, certified minimum irradiance, the window ``auto`` picks, optional
exact-irradiance error and thumbnail) computed on Dask and written to Parquet, resumable.
See docs/batch.md. Layer: above hbasis / prt / fitting, below the CLI.
"""

from .engine import BatchSettings, Engine, parts_dir, read_table, run_batch
from .inputs import expand_inputs
from .result import BatchResult
from .rows import COLUMNS, BatchOptions, content_hash, probe_row, schema

__all__ = ["COLUMNS", "BatchOptions", "BatchResult", "BatchSettings", "Engine", "content_hash",
           "expand_inputs", "parts_dir", "probe_row", "read_table", "run_batch", "schema"]
