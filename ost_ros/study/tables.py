"""The one CSV writer of the studies: rows (dicts or dataclasses) as a table, header from the
first row."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any


def as_dict(row: Any) -> dict[str, Any]:
    if isinstance(row, dict):
        return row
    if is_dataclass(row) and not isinstance(row, type):
        return asdict(row)
    raise TypeError(f"a table row is a dict or a dataclass, not {type(row).__name__}")


def write_csv(path: Path, rows: Sequence[Any], digits: int | None = None) -> None:
    """One line per row (an empty file for none); ``digits``: floats rounded to that many."""
    if not rows:
        path.write_text("")
        return
    dicts = [as_dict(r) for r in rows]
    if digits is not None:
        dicts = [{k: round(v, digits) if isinstance(v, float) else v for k, v in d.items()} for d in dicts]
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(dicts[0]))
        w.writeheader()
        w.writerows(dicts)
