"""Checks every importer makes before reading an input file, with one-line errors."""

from __future__ import annotations

import hashlib
from pathlib import Path

from tactile_studio.errors import UserError


def check_input_file(path: Path, what: str, error: type[UserError] = UserError) -> int:
    """Raise ``error`` naming ``path`` unless it is a non-empty file; return its size."""
    if not path.exists():
        raise error(f"{path}: no such file")
    if path.is_dir():
        raise error(f"{path}: is a folder, not a {what}")
    size = path.stat().st_size
    if size == 0:
        raise error(f"{path}: empty file, not a {what}")
    return size


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, hex (read in 1 MB blocks): an import's source identity,
    a run folder's model fingerprint."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
