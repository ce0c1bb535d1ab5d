"""``ionav-viz convert`` and ``info``: MCAP out, and what an MCAP log holds."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from ..core.errors import InputError
from . import common as c
from .app import app


@app.command()
def convert(
    drive_spec: str = typer.Argument(..., metavar="DRIVE", help="An IO-VNBD CSV (path, bundled scenario or run name)."),
    output: Path = typer.Option(..., "-o", "--output", help="The .mcap file to write (ROS 2 cdr: Imu, NavSatFix, TwistStamped)."),
    data_root_opt: Optional[Path] = c.DataRoot,
    yaw_sign: str = c.YawSign,
) -> None:
    """Convert a drive to a ROS 2 MCAP log that opens in Foxglove and 'ros2 bag'."""
    from ..sources.load import load_drive
    from ..sources.mcap_writer import TOPICS, write_mcap
    from ..sources.resolve import data_root

    if output.suffix.lower() != ".mcap":
        raise typer.BadParameter(f"{output}: the output must end in .mcap", param_hint="-o")
    drive = load_drive(drive_spec, data_root(data_root_opt), yaw_sign)
    n = write_mcap(drive, output)
    print(f"{n} messages on {', '.join(TOPICS.values())} ({len(drive)} samples, {drive.duration_s:.1f} s)", file=sys.stderr)
    print(output)


@app.command()
def info(
    path: Path = typer.Argument(..., metavar="FILE.mcap", help="An MCAP log."),
    imu_topic: Optional[str] = c.ImuTopic,
    gnss_topic: Optional[str] = c.GnssTopic,
    speed_topic: Optional[str] = c.SpeedTopic,
) -> None:
    """List the channels of an MCAP log and which ones ionav-viz would read."""
    from ..sources.mcap_reader import list_channels, select_channels

    if not path.is_file():
        raise InputError(f"{path}: no such file")
    channels = list_channels(path)
    try:
        sel = select_channels(path, imu_topic, gnss_topic, speed_topic)
        roles = {ch.topic: ch.role for ch in (sel.imu, sel.gnss, sel.speed) if ch is not None}
        problem = None
    except InputError as exc:
        roles, problem = {}, str(exc)
    width = max([len(ch.topic) for ch in channels] + [5])
    print(f"{'topic'.ljust(width)}  {'messages':>9}  encoding  schema  -> use")
    for ch in channels:
        print(f"{ch.topic.ljust(width)}  {ch.count:>9}  {ch.encoding:<8}  {ch.schema}  -> {roles.get(ch.topic, '-')}")
    if problem:
        print(f"cannot replay as is: {problem}", file=sys.stderr)
