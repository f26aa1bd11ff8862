"""Checks every importer makes before reading an input file, with one-line errors."""

from __future__ import annotations

import hashlib
from pathlib import Path

from tactile_studio.errors import UserError
from tactile_studio.storage.file_guards import not_regular


def check_input_file(path: Path, what: str, error: type[UserError] = UserError) -> int:
    """Raise ``error`` naming ``path`` unless it is a non-empty regular file (a FIFO
    would block the first read, a device never end: storage/file_guards.py); return
    its size. ``what``: "an XDF file", "a ShearSense CSV"..."""
    why = not_regular(path, what)
    if why:
        raise error(f"{path}: {why}")
    size = path.stat().st_size
    if size == 0:
        raise error(f"{path}: empty file, not {what}")
    return size


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, hex (read in 1 MB blocks): an import's source identity,
    a run folder's model fingerprint."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
