"""The one place results are read and written: parquet read here, json and parquet written here.

Reading: pyarrow opens files in C++, out of sight of Python's audit hook, so a job's provenance record
(lineage.records.tracked) would not see what it read. Here every parquet file is opened with
Python's `open` and handed to pyarrow as a file object: the `open` audit event fires, and the
bytes read are the same. Nothing else in the package calls pyarrow's or pandas' parquet readers
(tests/test_lineage_reads.py checks it).

Writing: every derived result's json and parquet goes through `write_json` and `write_parquet`,
atomically (files.write_atomic) and with fixed settings, so the same object gives the same bytes.
The recording format (rawformat) writes a group's files through these same two; files.py stays
below, standard library alone, as the provenance writer's atomic write and sha256
(tests/test_one_home.py checks that no module writes through rawformat).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .files import write_atomic


def read_table(path: str | Path, columns: list[str] | None = None) -> pa.Table:
    # One thread: a recording is a few thousand rows, and pyarrow's parquet thread pool can abort
    # the interpreter's exit ("terminate called without an active exception", apache/arrow#34314):
    # `esnap check-separation` did so in 5 of 60 runs here, 0 of 40 with use_threads=False.
    with open(path, "rb") as f:
        return pq.read_table(f, columns=columns, use_threads=False)


def read_parquet(path: str | Path, columns: list[str] | None = None) -> pd.DataFrame:
    return read_table(path, columns).to_pandas()


def parquet_rows(path: str | Path) -> int:
    """Row count from the footer alone."""
    with open(path, "rb") as f:
        return pq.read_metadata(f).num_rows


def parquet_from_bytes(data: bytes) -> pd.DataFrame:
    """A parquet file its caller already read (with `open`, so the read was seen) as a frame:
    the gate hashes and parses the same bytes, and one file needs no dataset layer or threads."""
    return pq.ParquetFile(pa.BufferReader(data)).read(use_threads=False).to_pandas(use_threads=False)


def write_parquet(df: pd.DataFrame, path: str | Path) -> None:
    # Fixed writer settings so that the same frame gives the same bytes; atomic (a crash never leaves half a file).
    write_atomic(
        path,
        lambda tmp: df.to_parquet(tmp, index=False, engine="pyarrow", compression="zstd"),
    )


def write_json(obj, path: str | Path) -> None:
    def w(tmp):
        with open(tmp, "w") as f:
            json.dump(obj, f, indent=1, sort_keys=True)
            f.write("\n")

    write_atomic(path, w)
