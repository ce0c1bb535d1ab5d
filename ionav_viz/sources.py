"""Loading a drive from whatever the user names: one entry point over all readers."""

from __future__ import annotations

from pathlib import Path

from .drive import Drive
from .errors import InputError
from .resolve import resolve_drive


def load_drive(spec: str, root: Path | None = None, yaw_sign: str = "auto") -> Drive:
    """Resolve ``spec`` (path, bundled scenario or run name) and read it into a :class:`Drive`."""
    path = resolve_drive(spec, root)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        from .iovnbd import read_iovnbd

        return read_iovnbd(path, yaw_sign=yaw_sign)
    raise InputError(f"{path}: unsupported file type {suffix or '(none)'}", "ionav-viz reads IO-VNBD V-*.csv files")
