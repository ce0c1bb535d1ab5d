"""``ionav-viz convert`` and ``info``: MCAP out, and what a log (MCAP, ROS bag, KITTI folder) holds."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Optional

import typer

from ..core.errors import InputError, printable
from . import common as c
from .app import app

if TYPE_CHECKING:
    from ..api.options import ReadOptions


@app.command()
@c.with_source_options
def convert(
    drive_spec: str = typer.Argument(..., metavar="DRIVE",
                                     help="A drive: IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 bag folder, KITTI raw folder, "
                                          "bundled scenario or run name."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="The .mcap file to write (ROS 2 cdr: Imu, NavSatFix, TwistStamped)."),
    read: ReadOptions | None = None,  # ReadOptions (c.with_source_options)
    quiet: bool = c.QuietOpt,
) -> None:
    """Convert a drive to a ROS 2 MCAP log that opens in Foxglove and 'ros2 bag'."""
    from .. import api

    done = api.convert(drive_spec, output, read)
    if not quiet:
        print(f"{done.messages} messages on {', '.join(done.topics)} ({done.samples} samples, {done.duration_s:.1f} s)",
              file=sys.stderr)
    print(done.path)


@app.command()
def info(
    path: Path = typer.Argument(..., metavar="LOG",
                                help="An MCAP log, a ROS 1 .bag, a ROS 2 bag folder (or its metadata.yaml) or a KITTI "
                                     "raw drive folder."),
    imu_topic: Optional[str] = c.ImuTopic,
    gnss_topic: Optional[str] = c.GnssTopic,
    gnss_velocity_topic: Optional[str] = c.GnssVelocityTopic,
    vehicle_speed_topic: Optional[str] = c.VehicleSpeedTopic,
    truth_topic: Optional[str] = c.TruthTopic,
) -> None:
    """List a log's topics (type, messages) and which ones ionav-viz would read."""
    from ..sources.load import open_message_log, source_kind
    from ..sources.resolve import resolve_drive

    # a pipe (was "empty file"), a device, a dangling link or a loop: named as replay names them
    if os.path.lexists(path):
        resolve_drive(str(path), None)
    if not path.exists():
        raise InputError(f"{path}: no such file or folder",
                         "check the path (relative to the current directory); info takes a log's file or folder, not a "
                         "drive's name")
    kind = source_kind(path)
    if kind == "kitti":
        _info_kitti(path)
        return
    source = open_message_log(path, kind)
    if source is None:
        raise InputError(f"{path}: an IO-VNBD CSV file has no topics",
                         "info lists the topics of MCAP logs and ROS bags; replay or evaluate the CSV directly")
    from ..sources.message_log import describe_log

    found = describe_log(source, imu_topic, gnss_topic, gnss_velocity_topic, vehicle_speed_topic, truth_topic)
    # names come from the file: escaped, so that none can clear the screen or forge a line (an 'error:' one)
    rows = [(printable(ch.topic), str(ch.count), printable(ch.encoding), printable(ch.schema), ch.role or "-")
            for ch in found.channels]
    header = ("topic", "messages", "encoding", "type", "use")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        cells = [row[0].ljust(widths[0]), row[1].rjust(widths[1]), row[2].ljust(widths[2]), row[3].ljust(widths[3]),
                 row[4]]
        print("  ".join(cells).rstrip())
    if found.problem:
        print(f"cannot replay as is: {printable(found.problem)}", file=sys.stderr)


def _info_kitti(path: Path) -> None:
    from ..sources.kitti import NAVSTAT_LOCKED, describe_kitti

    d = describe_kitti(path)
    statuses = ", ".join(f"{n} x navstat {s}{' (locked)' if s == NAVSTAT_LOCKED else ''}"
                         for s, n in sorted(d.navstat_counts.items()))
    print(f"KITTI raw OXTS: {printable(str(d.oxts))}")
    print(f"{d.packets} packets over {d.duration_s:.1f} s ({d.rate_hz:.1f} Hz): {statuses}")
    print("used: lat/lon/alt and vn/ve as truth, af and wu as inertial inputs, navstat as quality, pos_accuracy as "
          "sigma, numsats")
