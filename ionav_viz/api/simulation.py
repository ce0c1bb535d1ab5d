"""Synthetic drives in the exact IO-VNBD format (``ionav-viz simulate``), and MCAP copies of any
drive (``ionav-viz convert``)."""

from __future__ import annotations

import logging
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.fileio import refuse_output_onto_input
from ..dataset.samples import SAMPLES
from ..sim.imu import write_imu_log
from ..sim.simulate import FLEETS, SIMULATED_SCENARIOS, SensorModel, fleet_sensors, write_simulated_drive
from ..sources.load import ReadOptions, load_drive
from .options import DriveLike, input_paths

log = logging.getLogger("ionav_viz")


def simulate(scenario: str, output: str | Path, seed: int = 0, duration_s: float = 120.0, *, fleet: str | None = None,
             ideal: bool = False, gnss_losses: int = 0, imu: str | None = None) -> Path:
    """Simulate a drive of ``scenario`` and write it as an IO-VNBD ``V-*.csv`` (atomically).

    ``fleet``: draw the car's sensor and vehicle errors from a fleet (``"training"``, ``"held-out"``);
    ``ideal``: perfect sensors and flat roads; ``gnss_losses``: tunnel-like GNSS losses to add.
    ``imu``: instead, a logger's MCAP with a full 6-axis IMU of that grade (``"mems"``, ``"phone"``, ``"dash"``:
    :mod:`ionav_viz.sim.imu`), its receiver, and the reference truth on ``/truth/fix``.
    """
    if scenario not in SIMULATED_SCENARIOS:
        raise InputError(f"unknown scenario {scenario!r}", f"choose one of {', '.join(SIMULATED_SCENARIOS)}",
                         param="scenario")
    if imu is not None:
        if fleet is not None or ideal or gnss_losses:
            raise InputError("a simulated IMU log has its grade's sensors: no fleet, ideal sensors or GNSS losses",
                             "leave them out", param="imu")
        return write_imu_log(output, scenario, seed, duration_s, imu)
    if Path(output).suffix.lower() != ".csv":  # -o x.mcap wrote the CSV's text under that name, which no reader takes
        hint = ("choose a name like V-drive.csv, or give --imu mems|phone|dash for a 6-axis MCAP log"
                if Path(output).suffix.lower() == ".mcap" else "choose a name like V-drive.csv")
        raise InputError(f"{output}: a simulated drive is an IO-VNBD CSV file (.csv)", hint, param="output")
    # 1.5 was 1, silently
    if isinstance(gnss_losses, bool) or not isinstance(gnss_losses, numbers.Integral) or gnss_losses < 0:
        raise InputError(f"{gnss_losses!r} GNSS losses: give a whole number, 0 or more", param="gnss_losses")
    if fleet is not None and fleet not in FLEETS:
        raise InputError(f"unknown fleet {fleet!r}", f"choose one of {', '.join(FLEETS)}", param="fleet")
    if fleet is not None and ideal:
        raise InputError("ideal sensors and a fleet's exclude each other", "choose one", param="fleet")
    sensors = SensorModel.ideal() if ideal else fleet_sensors(fleet, seed) if fleet else None
    return write_simulated_drive(output, scenario, seed, duration_s, sensors, gnss_losses=gnss_losses)


def simulate_bundled(folder: str | Path) -> list[Path]:
    """Regenerate every bundled sample drive into ``folder`` (made when missing)."""
    Path(folder).mkdir(parents=True, exist_ok=True)
    return [write_simulated_drive(Path(folder) / s.file, s.scenario, s.seed, s.duration_s,
                                  fleet_sensors(s.fleet, s.seed) if s.fleet else None, gnss_losses=s.gnss_losses,
                                  package_ok=True)
            for s in SAMPLES]


@dataclass(frozen=True)
class Converted:
    """A drive written as an MCAP log: where, how many messages on which topics, of how long a drive."""

    path: Path
    messages: int
    topics: tuple[str, ...]
    samples: int
    duration_s: float


def vehicle_speed_for_log(drive: Drive) -> tuple[np.ndarray, tuple[str, ...]] | None:
    """The drive's vehicle speed as a log carries it (m/s per sample on ``/wheel/odom``) and the
    columns it stands for, or None. Wheel speeds at the nominal radius: odometry and the filter
    calibrate the scale against GNSS."""
    from ..nav.vehicle_speed import speed_in_mps, vehicle_speed

    found = vehicle_speed(drive)
    if found is None:
        return None
    values, unit, described = found
    return speed_in_mps(values, unit), tuple(described.split(" and "))


def convert(drive: DriveLike, output: str | Path, read: ReadOptions | None = None) -> Converted:
    """Write a drive as a ROS 2 MCAP log (``sensor_msgs/Imu``, ``NavSatFix``, ``TwistStamped``;
    atomically), that opens in Foxglove and ``ros2 bag``."""
    from ..sources.mcap_writer import write_mcap

    out = Path(output)
    if out.suffix.lower() != ".mcap":
        raise InputError(f"{out}: the output must end in .mcap", "choose a name like drive.mcap", param="output")
    refuse_output_onto_input(out, input_paths(drive, read))  # before reading: a log converted onto itself would be lost
    d = load_drive(drive, read)
    speed_mps, columns = vehicle_speed_for_log(d) or (None, ())
    written = write_mcap(d, out, speed_mps, columns)
    if written.left_out:
        log.warning("%s: not carried by the MCAP log: %s", out, ", ".join(written.left_out))
    return Converted(out, written.messages, written.topics, len(d), d.duration_s)
