"""Loading a drive from whatever the user names: one entry point over all readers."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..core.drive import Drive
from ..core.errors import InputError
from ..sources.resolve import resolve_drive


@dataclass(frozen=True)
class McapOptions:
    """How to read MCAP logs: topics (None: found by schema) and which time stamps to use."""

    imu_topic: str | None = None
    gnss_topic: str | None = None
    speed_topic: str | None = None
    stamps: str = "header"


def load_drive(spec: str, root: Path | None = None, yaw_sign: str = "auto", mcap: McapOptions | None = None) -> Drive:
    """Resolve ``spec`` (path, bundled scenario or run name) and read it into a :class:`Drive`.

    ``.csv`` files are IO-VNBD vehicle files (``yaw_sign`` applies); ``.mcap`` files are ROS 2 or
    JSON MCAP logs (``mcap`` options apply).
    """
    path = resolve_drive(spec, root)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        from ..sources.iovnbd import read_iovnbd

        return read_iovnbd(path, yaw_sign=yaw_sign)
    if suffix == ".mcap":
        from ..sources.mcap_reader import read_mcap

        opts = mcap or McapOptions()
        return read_mcap(path, imu_topic=opts.imu_topic, gnss_topic=opts.gnss_topic, speed_topic=opts.speed_topic, stamps=opts.stamps)
    raise InputError(f"{path}: unsupported file type {suffix or '(none)'}", "ionav-viz reads IO-VNBD V-*.csv files and MCAP (.mcap) logs")
