"""The one in-memory model of a drive, and the conventions that hold everywhere.

Conventions (every reader converts to these; nothing downstream converts again):

* Time ``t_s``: seconds since the first sample of the drive, strictly increasing. A drive read with
  a span (``--span``, :class:`~ionav_viz.sources.load.ReadOptions`) keeps the whole log's clock: its
  ``t_s`` starts where the span does.
  ``start_time_of_day_s`` is the UTC time of day of that first sample.
* Position ``lat_deg``/``lon_deg``: WGS84 decimal degrees, east and north positive.
* ``heading_deg``: GNSS course over ground, degrees clockwise from true north, in [0, 360).
* ``yaw_rate_radps``: body yaw rate about the up axis, **counter-clockwise (left turn)
  positive** (ISO 8855 / ROS REP 103). A left turn therefore *decreases* ``heading_deg``:
  d(heading)/dt = -yaw_rate.
* ``accel_long_mps2``: longitudinal specific force along the body x axis (forward positive)
  as the sensor measures it, so road grade and mount tilt leak gravity into it.
* ``speed_mps``: GNSS speed over ground (m/s); ``speed_can_mps``: the vehicle's own speed (CAN or
  wheel odometry, m/s), when the source has one.
* ``accel_{x,y,z}_mps2`` and ``gyro_{x,y,z}_radps`` (optional, :data:`IMU_COLUMNS`): the full IMU in
  the body frame, x forward, y left, z up (REP 103), for sources that have all six axes.
* ``gnss_fault``: per sample, 0 where the GNSS fix is trustworthy ground truth, else the bits of
  :class:`~ionav_viz.core.gnss_quality.GnssFault` saying why (set by the readers' loader).

Samples stay at their native rate and time stamps; resampling to the 1-second windows of
the paper happens in :mod:`ionav_viz.nav.windows`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .imu import ImuCharacter

REQUIRED_COLUMNS = (
    "t_s",
    "lat_deg",
    "lon_deg",
    "speed_mps",
    "heading_deg",
    "accel_long_mps2",
    "yaw_rate_radps",
)
#: The full IMU, when the source has one (message logs, KITTI): specific force and angular rate
#: on the three axes of the vehicle body frame (REP 103: x forward, y left, z up), as measured (not
#: bias-corrected; gravity included, so a level car at rest reads +9.81 m/s² on z).
#: ``accel_x_mps2`` is ``accel_long_mps2`` and ``gyro_z_radps`` is ``yaw_rate_radps``.
IMU_COLUMNS = ("accel_x_mps2", "accel_y_mps2", "accel_z_mps2", "gyro_x_radps", "gyro_y_radps", "gyro_z_radps")
#: The GNSS receiver's own fixes, speed and course, when the drive's position columns are a
#: separate reference trajectory (post-processed GNSS/INS, RTK): what estimators are given, while
#: the reference is the truth they are scored against (:meth:`Drive.as_received`).
RECEIVER_COLUMNS = ("gnss_lat_deg", "gnss_lon_deg", "gnss_speed_mps", "gnss_heading_deg")
OPTIONAL_COLUMNS = (
    "height_m",
    "n_satellites",
    "gnss_sigma_m",
    "gnss_fix",
    "gnss_speed_fitted",
    "speed_can_mps",
    "accel_lat_mps2",
    "steering_angle_deg",
    "wheel_speed_fl_radps",
    "wheel_speed_fr_radps",
    "wheel_speed_rl_radps",
    "wheel_speed_rr_radps",
    *IMU_COLUMNS,
    *RECEIVER_COLUMNS,
)


@dataclass
class Drive:
    """A drive as columns of equal length (one row per sample), plus metadata.

    Attributes:
        name: run name, e.g. ``V-Vw8``.
        source: where it came from (a file path).
        rate_hz: nominal sample rate (Hz), e.g. 10.0 for IO-VNBD.
        start_time_of_day_s: UTC time of day of the first sample (s).
        columns: ``REQUIRED_COLUMNS`` always, ``OPTIONAL_COLUMNS`` when the source has them;
            float64 arrays, one value per sample. ``gnss_sigma_m`` is the horizontal standard
            deviation of the fix the source reports (m); ``gnss_fix`` is 0 where the source had no
            fix at that sample (a log's IMU goes on through a GNSS gap; the position there is only
            interpolated) and 1 elsewhere; ``gnss_speed_fitted`` is 1 where the receiver's speed and
            course are fitted to its fixes (the source gave no velocity: they carry no information
            the positions do not) and 0 where it measured them.
        gnss_fault: uint16 per sample, 0 = good GNSS truth (see :mod:`ionav_viz.core.gnss_quality`);
            all good when not given.
        receiver_fault: with :data:`RECEIVER_COLUMNS`, the same for the receiver's fixes (which
            of them the filters may use); None otherwise.
        start_stamp_s: the source's own time stamp of the first sample (s): UNIX seconds for
            message logs and KITTI, the CSV's time since the start of the day for IO-VNBD (which
            carries no date); None: unknown (then :meth:`stamp_s` uses ``start_time_of_day_s``).
        imu: what the reader found of a log's IMU (:class:`~ionav_viz.core.imu.ImuCharacter`:
            rate, sample kind, clock offset, mount); None for sources that do not say (IO-VNBD
            CSVs, drives built in code).
        frame_origin_deg: ``(lat_deg, lon_deg)`` of the local east/north frame when it is not this
            drive's own (:attr:`local_origin_deg`): a span (``--span``) keeps its whole drive's frame,
            as it keeps its clock. None: the drive's own.
    """

    name: str
    source: str
    rate_hz: float
    start_time_of_day_s: float
    columns: dict[str, np.ndarray] = field(repr=False)
    gnss_fault: np.ndarray | None = field(default=None, repr=False)
    receiver_fault: np.ndarray | None = field(default=None, repr=False)
    start_stamp_s: float | None = None
    imu: ImuCharacter | None = field(default=None, repr=False)
    frame_origin_deg: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        missing = [c for c in REQUIRED_COLUMNS if c not in self.columns]
        if missing:
            raise ValueError(f"drive {self.name}: missing columns {missing}")
        n = len(self.columns["t_s"])
        for key, values in self.columns.items():
            if key not in REQUIRED_COLUMNS and key not in OPTIONAL_COLUMNS:
                raise ValueError(f"drive {self.name}: unknown column {key!r}")
            if len(values) != n:
                raise ValueError(f"drive {self.name}: column {key} has {len(values)} rows, expected {n}")
            self.columns[key] = np.asarray(values, dtype=np.float64)
        if self.gnss_fault is None:
            self.gnss_fault = np.zeros(n, dtype=np.uint16)
        self.gnss_fault = np.asarray(self.gnss_fault, dtype=np.uint16)
        if len(self.gnss_fault) != n:
            raise ValueError(f"drive {self.name}: gnss_fault has {len(self.gnss_fault)} rows, expected {n}")

    def __len__(self) -> int:
        return len(self.columns["t_s"])

    @property
    def t_s(self) -> np.ndarray:
        return self.columns["t_s"]

    @property
    def lat_deg(self) -> np.ndarray:
        return self.columns["lat_deg"]

    @property
    def lon_deg(self) -> np.ndarray:
        return self.columns["lon_deg"]

    @property
    def speed_mps(self) -> np.ndarray:
        return self.columns["speed_mps"]

    @property
    def heading_deg(self) -> np.ndarray:
        return self.columns["heading_deg"]

    @property
    def accel_long_mps2(self) -> np.ndarray:
        return self.columns["accel_long_mps2"]

    @property
    def yaw_rate_radps(self) -> np.ndarray:
        return self.columns["yaw_rate_radps"]

    @property
    def gnss_ok(self) -> np.ndarray:
        """Whether each sample's GNSS fix is trustworthy ground truth."""
        return self.gnss_fault == 0

    @property
    def local_origin_deg(self) -> tuple[float, float]:
        """``(lat_deg, lon_deg)`` of the drive's first trustworthy GNSS fix (the first sample's where
        none is): the origin of the local east/north frame that exports and external trajectories
        use. Not the first sample's: a receiver without a fix yet writes (0, 0), which put the frame
        at the equator, 5,800 km from a drive in England, where the plane is 15 % off scale.
        The receiver's fix where a reference is beside it (:meth:`as_received`: the estimators' and
        the exports' frame). A span of a drive keeps the whole drive's (``frame_origin_deg``), so
        the exports of two spans, and an estimate made on the whole log, share one frame."""
        if self.frame_origin_deg is not None:
            return self.frame_origin_deg
        received = self.as_received()
        ok = np.flatnonzero(received.gnss_ok)
        i = int(ok[0]) if len(ok) else 0
        return float(received.lat_deg[i]), float(received.lon_deg[i])

    @property
    def speed_fitted(self) -> np.ndarray:
        """Whether each sample's receiver speed and course were fitted to the fixes (the source gave
        no velocity; ``gnss_speed_fitted``), not measured: bool per sample."""
        flag = self.columns.get("gnss_speed_fitted")
        return np.zeros(len(self), dtype=bool) if flag is None else flag != 0

    @property
    def velocity_fitted(self) -> bool:
        """Whether the whole drive's receiver speed and course are fitted to the fixes (a log
        without a velocity topic): the filters weigh them as the noisier measurements they are."""
        return len(self) > 0 and bool(self.speed_fitted.all())

    @property
    def has_reference(self) -> bool:
        """Whether the positions are a reference trajectory beside the receiver's own fixes."""
        return RECEIVER_COLUMNS[0] in self.columns

    def as_received(self) -> Drive:
        """The drive as its GNSS receiver saw it: positions, speed and course from
        :data:`RECEIVER_COLUMNS`, quality from ``receiver_fault``. What estimators are given; the
        drive itself when it has no separate reference."""
        if not self.has_reference:
            return self
        columns = {k: v for k, v in self.columns.items() if k not in RECEIVER_COLUMNS}
        columns |= {"lat_deg": self.columns["gnss_lat_deg"], "lon_deg": self.columns["gnss_lon_deg"],
                    "speed_mps": self.columns["gnss_speed_mps"], "heading_deg": self.columns["gnss_heading_deg"]}
        return Drive(self.name, self.source, self.rate_hz, self.start_time_of_day_s, columns,
                     gnss_fault=self.receiver_fault,
                     start_stamp_s=self.start_stamp_s, imu=self.imu, frame_origin_deg=self.frame_origin_deg)

    def stamp_s(self, t_s: np.ndarray | float) -> np.ndarray | float:
        """The source's own time stamp (s, see ``start_stamp_s``) of drive time ``t_s`` (s since the first sample)."""
        start = self.start_stamp_s if self.start_stamp_s is not None else self.start_time_of_day_s
        return start + t_s

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self) else 0.0

    @property
    def distance_m(self) -> float:
        """The distance driven (m): the steps between consecutive trustworthy fixes (:attr:`gnss_ok`;
        a straight line across each stretch without one), 0 with fewer than two. Not over every
        fix: a receiver that reports (0, 0) without a fix would add twice the way to the equator."""
        from .geo import steps_en_m

        ok = self.gnss_ok
        if ok.sum() < 2:
            return 0.0
        east, north = steps_en_m(self.lat_deg[ok], self.lon_deg[ok])
        return float(np.hypot(east, north).sum())


def measured_imu(drive: Drive) -> tuple[np.ndarray, np.ndarray] | None:
    """The drive's full IMU as ``(accel (n, 3) m/s^2, gyro (n, 3) rad/s)`` in the body frame, or None
    when it lacks an axis or carries a placeholder: an axis that never changes is not a sensor (an
    MCAP converted from a two-channel drive carries a level IMU, gravity on z and zeros)."""
    if not all(c in drive.columns and np.ptp(drive.columns[c]) > 0 for c in IMU_COLUMNS):
        return None
    return (np.column_stack([drive.columns[c] for c in IMU_COLUMNS[:3]]),
            np.column_stack([drive.columns[c] for c in IMU_COLUMNS[3:]]))


def drive_labels(drives: list[Drive]) -> list[str]:
    """A label per drive for a table or a JSON key: its name, or its file where another of
    ``drives`` has the same name (``a/V-x.csv`` and ``b/V-x.csv`` are both ``V-x``: keyed by name
    alone, one replaced the other); one file given twice keeps one label."""
    sources: dict[str, set[str]] = {}
    for d in drives:
        sources.setdefault(d.name, set()).add(str(d.source))
    return [d.name if len(sources[d.name]) == 1 else str(d.source or d.name) for d in drives]
