"""Tables the CLI prints (``info``, ``devices``, ``ports``, ``train``, ``evaluate``), with rich.

In a terminal: boxed, aligned tables sized to the window. Piped, under CI or on a dumb
terminal: the same rows as plain space-aligned text without borders, colour or any
control character, never wrapped, so ``grep``/``awk`` keep working. ``--json`` outputs do
not come through here: they are an interface and stay byte-for-byte as they were.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Sequence
from typing import Any, TextIO

from tactile_studio.jobs import interactive
from tactile_studio.terminal import raw_stream

_FIELD = re.compile(r"^([A-Za-z][\w ]*?):\s+(.*)$")


def console(stream: TextIO) -> Any:
    """A rich Console for a terminal ``stream``."""
    from rich.console import Console

    return Console(file=raw_stream(stream), force_terminal=True, highlight=False)


def table(columns: Sequence[str], rows: Sequence[Sequence[Any]], title: str | None = None,
          stream: TextIO | None = None, header: bool = True,
          right: Sequence[str] = ()) -> None:
    """Print ``rows`` under ``columns`` (``right``: column names aligned right)."""
    stream = stream or sys.stdout
    if not interactive(stream):
        _plain(columns, rows, title, stream, header, right)
        return
    from rich import box
    from rich.table import Table
    from rich.text import Text

    out = console(stream)
    t = Table(title=title, show_header=header, box=box.SIMPLE_HEAD, pad_edge=False,
              header_style="bold")
    for name in columns:
        t.add_column(name, justify="right" if name in right else "left", overflow="fold")
    for row in rows:
        # values are text, never rich markup, and printable (they may come from a file)
        t.add_row(*(Text(_printable(str(v))) for v in row))
    out.print(t)


def _plain(columns: Sequence[str], rows: Sequence[Sequence[Any]], title: str | None,
           stream: TextIO, header: bool, right: Sequence[str]) -> None:
    """Space-aligned columns, no borders or trailing blanks; printable characters only."""
    cells = [[_printable(str(v)) for v in row] for row in rows]
    if header:
        cells.insert(0, list(columns))
    widths = [max((len(r[i]) for r in cells if i < len(r)), default=0)
              for i in range(len(columns))]
    lines = [title] if title else []
    just = [str.rjust if name in right else str.ljust for name in columns]
    lines += ["  ".join(j(v, w) for v, w, j in zip(r, widths, just)).rstrip() for r in cells]
    if lines:
        stream.write("\n".join(lines) + "\n")
    stream.flush()


def _printable_lines(text: str) -> str:
    return "\n".join(_printable(line) for line in text.split("\n"))


def _printable(text: str) -> str:
    return "".join(c if c.isprintable() else " " for c in text)


def fields(lines: Sequence[str], stream: TextIO | None = None) -> None:
    """In a terminal, ``"key: value"`` lines as a two-column table, any other line (a
    nested table, a note) as it is after it. Piped: the lines exactly as given (their
    aligned ``key:`` form is what scripts already parse)."""
    stream = stream or sys.stdout
    if not interactive(stream):
        stream.write("\n".join(_printable_lines(line) for line in lines) + "\n")
        stream.flush()
        return
    rows, rest = [], []
    for line in lines:
        m = _FIELD.match(line) if "\n" not in line else None
        if m and not rest:
            rows.append((m.group(1), m.group(2)))
        else:
            rest.append(line)
    table(("field", "value"), rows, stream=stream, header=False)
    if rest:
        stream.write("\n".join(_printable_lines(line) for line in rest) + "\n")
        stream.flush()
