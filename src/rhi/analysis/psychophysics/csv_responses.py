"""Reading an experiment's 2AFC responses from a CSV file (one trial per row)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rhi.analysis._csv import read_rows
from rhi.analysis.psychophysics.trials import Responses
from rhi.errors import InvalidInput


def from_csv(path: str | Path) -> Responses:
    """Read an experiment's responses from a CSV file (one trial per row).

    Columns (header required; case and surrounding spaces ignored; others ignored):
    ``subject``, ``device``, ``comparison`` (comparison stiffness [N/m]) and
    ``response`` (1 if the comparison was judged stiffer than the reference, 0 if
    not).

    Args:
        path: CSV file.

    Returns:
        `Responses`, with each trial's file line kept for later error messages.

    Raises:
        InvalidInput: unreadable file, a missing column, an empty subject or device,
            a comparison that is not a positive number, or a response outside
            {0, 1} -- each naming the line and column.
    """
    path, cols, index, body = read_rows(path)
    for column in ("subject", "device", "comparison", "response"):
        if column not in index:
            raise InvalidInput(f"{path.name}: missing column '{column}' (found {cols})")
    subj, dev, comp, resp, lines = [], [], [], [], []
    for line, row in body:
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) < len(cols):
            raise InvalidInput(f"{path.name}, line {line}: {len(row)} fields; the header has {len(cols)}")
        s, d = row[index["subject"]].strip(), row[index["device"]].strip()
        if not s:
            raise InvalidInput(f"{path.name}, line {line}, column 'subject': empty")
        if not d:
            raise InvalidInput(f"{path.name}, line {line}, column 'device': empty")
        text = row[index["comparison"]].strip()
        try:
            c = float(text)
        except ValueError:
            raise InvalidInput(f"{path.name}, line {line}, column 'comparison': {text!r} is not a number") from None
        if not (math.isfinite(c) and c > 0):
            raise InvalidInput(f"{path.name}, line {line}, column 'comparison': {text!r} is not a positive stiffness")
        text = row[index["response"]].strip()
        try:
            r = float(text)
        except ValueError:
            r = float("nan")
        if r not in (0.0, 1.0):
            raise InvalidInput(f"{path.name}, line {line}, column 'response': {text!r} is not 0 or 1")
        subj.append(s)
        dev.append(d)
        comp.append(c)
        resp.append(int(r))
        lines.append(line)
    if not comp:
        raise InvalidInput(f"{path.name}: no data rows")
    return Responses(
        subject=np.array(subj, dtype=object),
        device=np.array(dev, dtype=object),
        comparison=np.array(comp),
        response=np.array(resp),
        line=np.array(lines),
    )
