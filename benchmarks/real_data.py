"""The real development set (issue 45): five people's ShearSense CSVs, found beside the
repository, imported once through the product's own ``import shearsense`` into a cache
outside the repository, and reused by every benchmark and test that reads real people.

The set is not ours to redistribute: it is never copied into the project. Where it is
absent (a user's machine, a clone without ``../shared``) :func:`dev_set` is None and
callers skip with :func:`skip_reason`'s one line.

    from benchmarks.real_data import dev_sessions, dev_set, skip_reason
    if dev_set() is None: print(skip_reason()); return
    sessions = dev_sessions()     # a folder of session files, imported on first use
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import time
from pathlib import Path

ENV = "TACTILE_STUDIO_DEV_SET"
RELATIVE = Path("shared") / "data" / "shearsense-dev"  # beside the repository
SUFFIXES = (".csv.xz", ".csv.gz", ".csv.bz2", ".csv")
REPO = Path(__file__).resolve().parents[1]


def _checkouts(root: Path) -> list[Path]:
    """``root`` and, when it is a git worktree (``.git`` is a file naming the main
    repository's ``.git/worktrees/<name>``), the main checkout: a worktree kept in
    ``wt/<name>`` finds the set beside the main checkout, as CI's clone does."""
    out = [root]
    git = root / ".git"
    if git.is_file():
        text = git.read_text(errors="replace").strip()
        if text.startswith("gitdir:"):
            gitdir = Path(text.split(":", 1)[1].strip())
            if gitdir.parent.name == "worktrees":
                out.append(gitdir.parent.parent.parent)
    return out


def _candidates() -> list[Path]:
    if os.environ.get(ENV):
        return [Path(os.environ[ENV]).expanduser()]
    return [c.parent / RELATIVE for c in _checkouts(REPO)]


def dev_set() -> Path | None:
    """The development set's folder, or None when it is not there."""
    for folder in _candidates():
        if folder.is_dir() and dev_files(folder):
            return folder
    return None


def skip_reason() -> str:
    """One line for a skipped benchmark or test."""
    where = os.environ.get(ENV) or f"../{RELATIVE.as_posix()}"
    return f"development set not found at {where}"


def dev_files(folder: Path) -> list[Path]:
    """The set's CSV files (compressed or not), sorted by name."""
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and p.name.lower().endswith(SUFFIXES))


def cache_root() -> Path:
    """``$XDG_CACHE_HOME/tactile-studio/shearsense-dev`` (``~/.cache`` by default)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "tactile-studio" / "shearsense-dev"


# What turns the CSVs into sessions (the importers, the session format and writer, the
# grid, the protocols whose keys name the gestures): a package stands for all its files.
IMPORT_CODE = ("tactile_studio.storage.exchange", "tactile_studio.storage.format",
               "tactile_studio.sensor.layout", "tactile_studio.resources")


def fingerprint(files: list[Path]) -> str:
    """Names and sizes of the set's files and the importer's version: a changed set, or
    one the importer would now read differently, imports into a new folder."""
    from tactile_studio.learn.data.cache import code_version

    h = hashlib.sha256(f"importer {code_version(IMPORT_CODE)}\n".encode())
    for f in files:
        h.update(f"{f.name}\0{f.stat().st_size}\n".encode())
    return h.hexdigest()[:16]


def dev_sessions(verbose: bool = False) -> Path:
    """The development set as session files, imported once (through the product's
    ``import shearsense``, which reads the compressed files directly) and cached; the
    folder appears whole or not at all, so a killed import is redone, never half-read."""
    folder = dev_set()
    if folder is None:
        raise FileNotFoundError(skip_reason())
    files = dev_files(folder)
    target = cache_root() / fingerprint(files)
    if (target / ".complete").is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".importing-", dir=target.parent))
    try:
        seconds, _ = import_files(files, staging)
        (staging / ".complete").write_text(f"{len(files)} files\n")
        try:
            staging.rename(target)
        except OSError:  # another process finished first: use its copy
            if not (target / ".complete").is_file():
                raise
        if verbose:
            print(f"  imported the development set ({len(files)} files) in {seconds:.1f} s "
                  f"into {target}")
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target


def import_files(files: list[Path], out: Path) -> tuple[float, float]:
    """``import shearsense FILES --out OUT`` as the CLI runs it: (wall, CPU) seconds (the
    CPU time says what the import costs whatever the neighbours do)."""
    from tactile_studio.storage.exchange.importers.shearsense import import_shearsense_study

    start, cpu = time.perf_counter(), time.process_time()
    import_shearsense_study(files, out)
    return time.perf_counter() - start, time.process_time() - cpu
