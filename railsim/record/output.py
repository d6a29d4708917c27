"""Atomic file writers for run outputs (temp file in the same folder, then ``os.replace``).

A run interrupted half-way never leaves a half-written ``trips.csv`` behind: every file either has its
previous content or its new complete content. ``mkstemp`` creates its temp file with mode 0600; the file is
given the mode a plain ``open()`` would have (``0666`` less the user's umask, typically 0644) before it
replaces the old one, so colleagues and web servers can read a run's ``report.html``. CSV is written with a fixed column order and fixed float
formatting (``repr`` round-trip floats) so the same seed gives byte-identical files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml


def _umask() -> int:
    """The process's umask (read by setting it and putting it back: POSIX has no getter)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, with the permissions the user's umask gives new files."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=str(path.parent))
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError) and exc.filename is None:  # a failed write() names no file: name ours
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise


def _fmt(value: Any) -> Any:
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(round(value, 6))
    if value is None:
        return ""
    return value


def write_csv(path: Path, rows: Iterable[Mapping[str, Any]], columns: Sequence[str]) -> None:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_fmt(row.get(c)) for c in columns])
    write_bytes(path, buf.getvalue().encode("utf-8"))


def write_parquet(path: Path, rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> None:
    import pandas as pd

    frame = pd.DataFrame([{c: r.get(c) for c in columns} for r in rows], columns=list(columns))
    buf = io.BytesIO()
    frame.to_parquet(buf, index=False)
    write_bytes(path, buf.getvalue())


def write_table(
    out_dir: Path,
    stem: str,
    rows: Sequence[Mapping[str, Any]],
    columns: Sequence[str],
    formats: Sequence[str] = ("csv",),
) -> list[Path]:
    written = []
    for fmt in formats:
        path = Path(out_dir) / f"{stem}.{fmt}"
        if fmt == "csv":
            write_csv(path, rows, columns)
        elif fmt == "parquet":
            write_parquet(path, rows, columns)
        else:
            raise ValueError(f"unknown table format {fmt!r}")
        written.append(path)
    return written


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "item"):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _clean(obj: Any) -> Any:
    if isinstance(obj, float) and (math.isnan(obj) or math.isinf(obj)):
        return None
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    return obj


def write_json(path: Path, data: Any) -> None:
    text = json.dumps(_clean(data), indent=2, sort_keys=True, default=_json_default)
    write_bytes(path, (text + "\n").encode("utf-8"))


def write_yaml(path: Path, data: Any) -> None:
    write_bytes(path, yaml.safe_dump(data, sort_keys=False, allow_unicode=True).encode("utf-8"))
