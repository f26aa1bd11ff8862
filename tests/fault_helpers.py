"""What the fault tests share: a real full disk for this process (a file-size limit), and
the one error line a command ends with."""

from __future__ import annotations

import resource
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def file_size_limit(limit: int) -> Iterator[None]:
    """Writes past ``limit`` bytes per file fail with EFBIG here, as on a full disk."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))


def one_error_line(capsys) -> str:  # noqa: ANN001 - pytest's fixture
    """The command's one ``tactile-studio:`` line on stderr (exactly one, no traceback)."""
    err = capsys.readouterr().err
    assert "Traceback" not in err
    (line,) = [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]
    return line
