"""Files as every writer and every checker of the package handles them: one atomic write, one sha256.

Standard library only. The provenance writer (lineage.records, standard library alone) writes its
records through `write_text` and hashes files with `sha256`, so this module is loaded by every job
and, like records, exempt from code inputs (lineage/imports.py): it writes the bytes it is given and
hashes the bytes it reads, so it cannot change a result.
"""

from __future__ import annotations

import hashlib
import os
import secrets
from collections.abc import Callable
from pathlib import Path


def write_atomic(path: str | Path, fill: Callable[[Path], object]) -> Path:
    """Write `path` through a temporary file and rename it into place: a reader sees the old file or
    the new one, never half, also on a shared file system (NFS, Lustre) with writers on several nodes.

    `fill(tmp)` writes the temporary file, named uniquely per writer in `path`'s folder and created
    with the permissions a plain `open` gives. Its bytes are flushed to disk (fsync) before the
    rename, so another node never sees the new name before them. On any error the temporary file is
    removed and the error raised.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    try:
        fill(tmp)
        fd = os.open(tmp, os.O_WRONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_text(path: str | Path, text: str) -> Path:
    """`text` to `path`, atomically (write_atomic)."""
    return write_atomic(path, lambda tmp: tmp.write_text(text))


def sha256(path: str | Path) -> str:
    """The hex sha256 of a file's bytes."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()
