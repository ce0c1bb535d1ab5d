"""How message logs (MCAP, ROS 1 and ROS 2 bags) are read: :class:`LogOptions`, shared by the
loader (:mod:`.load`, which the API re-exports) and the reader (:mod:`.message_log`).

The options that take the command line's syntax (``imu_axes``, ``imu_mount``, ``imu_time_offset``,
``imu_samples``, ``truth_origin``) are parsed once, when a :class:`LogOptions` is made, into typed
values (:attr:`LogOptions.parsed`); nothing downstream parses their text again.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError
from .imu.axes import parse_imu_axes
from .imu.character import check_samples, parse_time_offset
from .imu.mount import parse_mount
from .reference import FrameOrigin, parse_origin


@dataclass(frozen=True)
class ParsedLogOptions:
    """The typed values of a :class:`LogOptions`' text options.

    Attributes:
        axes: the 3x3 matrix taking the log's IMU axes to the body frame (identity: as logged).
        mount: the IMU's mount after the axes: a 3x3 rotation body <- IMU, ``"auto"`` (estimated
            and applied), or None (estimated; applied when small, a stop when large).
        time_offset_s: the IMU's stamps minus the receiver's (s), ``"auto"``, or None (estimated,
            applied when clearly off).
        samples: ``"single"``, ``"averaged"`` or None (by the rate).
        origin: where a local-frame reference lies (a :class:`~.reference.FrameOrigin`), ``"auto"``
            (fitted to the fixes), or None (none given).
    """

    axes: np.ndarray
    mount: np.ndarray | str | None = None
    time_offset_s: float | str | None = None
    samples: str | None = None
    origin: FrameOrigin | str | None = None


@dataclass(frozen=True)
class LogOptions:
    """How to read message logs (MCAP, ROS 1 and ROS 2 bags): topics (None: found by message
    type), which time stamps to use and the IMU's axes."""

    imu_topic: str | None = None
    gnss_topic: str | None = None
    #: the receiver's velocity (TwistStamped in a world frame): GNSS speed and course; "none": from the fixes
    gnss_velocity_topic: str | None = None
    stamps: str = "header"
    imu_axes: str | None = None  # e.g. "x=-y,y=x,z=z": body x is the log's -y (see sources.imu.axes)
    #: the vehicle's own speed (nav_msgs/Odometry, or TwistStamped in a body frame); "none" leaves it out
    vehicle_speed_topic: str | None = None
    #: deprecated: the earlier name of ``gnss_velocity_topic``
    speed_topic: str | None = None
    #: a reference trajectory (NavSatFix: post-processed GNSS/INS, RTK) beside the receiver: the truth
    #: every score is measured against, while the estimators get only the GNSS topic
    truth_topic: str | None = None
    #: where a reference in a local frame (Odometry, PoseStamped) lies: "LAT,LON[,YAW]" (degrees; the frame's
    #: origin, x axis YAW counter-clockwise from east) or "auto" (fitted to the receiver's fixes; sources.reference)
    truth_origin: str | None = None
    #: the IMU's mount (after ``imu_axes``): "auto" (estimated from the log), "roll=..,pitch=..,yaw=.."
    #: (degrees) or "quat=w,x,y,z"; None: estimated, applied when small, a stop when large (sources.imu.mount)
    imu_mount: str | None = None
    #: the IMU's clock against the receiver's: "auto" (estimated, refused when it cannot be resolved) or seconds
    #: (its stamps minus the receiver's, e.g. "0.3"); None: estimated, applied when clearly off (sources.imu.clock)
    imu_time_offset: str | None = None
    #: what each IMU sample is at a low rate: "single" (one instantaneous reading) or "averaged" (a mean or
    #: increment over its interval); None: single below 50 Hz, the reader's means above (sources.imu.character)
    imu_samples: str | None = None
    #: the text options above, parsed (made here; see :class:`ParsedLogOptions`)
    parsed: ParsedLogOptions = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.speed_topic is not None:
            warnings.warn("LogOptions(speed_topic=...) is now gnss_velocity_topic (and vehicle_speed_topic for "
                          "wheel or CAN odometry)", DeprecationWarning, stacklevel=3)
            if self.gnss_velocity_topic is None:
                object.__setattr__(self, "gnss_velocity_topic", self.speed_topic)
            object.__setattr__(self, "speed_topic", None)
        if self.stamps not in ("header", "log"):
            raise InputError(f"stamps {self.stamps!r}: choose header or log", param="stamps")
        object.__setattr__(self, "parsed", ParsedLogOptions(
            axes=parse_imu_axes(self.imu_axes) if self.imu_axes else np.eye(3),
            mount=parse_mount(self.imu_mount) if self.imu_mount else None,
            time_offset_s=parse_time_offset(self.imu_time_offset),
            samples=check_samples(self.imu_samples),
            origin=parse_origin(self.truth_origin) if self.truth_origin else None))
