"""Reading a user's CSV file: header and numbered rows, with errors that name the file."""

from __future__ import annotations

import csv
from pathlib import Path

from rhi.errors import InvalidInput


def read_rows(path: str | Path) -> tuple[Path, list[str], dict[str, int], list[tuple[int, list[str]]]]:
    """Read a CSV file.

    Returns:
        (path, column names lower-cased, {column: index}, [(line number, cells), ...]).

    Raises:
        InvalidInput: unreadable or empty file.
    """
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            body = list(enumerate(reader, start=2))
    except OSError as exc:
        raise InvalidInput(f"path: cannot read {str(path)!r} ({exc.strerror})") from None
    except (csv.Error, UnicodeDecodeError) as exc:
        raise InvalidInput(f"path: {str(path)!r} is not a readable CSV file ({exc})") from None
    if header is None:
        raise InvalidInput(f"{path.name}: empty file (no header)")
    cols = [h.strip().lower() for h in header]
    return path, cols, {c: i for i, c in enumerate(cols)}, body
