"""What a drive's IMU is, as its reader found it (:class:`ImuCharacter`): the rate and nature of its
samples, its clock against the receiver's, its mount on the car and how much its holder wobbles.
Computed by :mod:`ionav_viz.sources.imu.character`, carried by the drive (``Drive.imu``), read by
the filters (``gins`` chooses its mechanisation from it) and shown in reports and recordings."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

#: ``sample_kind``: each sample the mean over its interval (an increment: a 100 Hz IMU the reader
#: averages into the 10 Hz grid, or a logger that averages), or one instantaneous reading (a
#: phone's sensor event), which aliases what the car shakes faster than half the rate.
AVERAGED, SINGLE = "averaged", "single"
SAMPLE_KINDS = (AVERAGED, SINGLE)


@dataclass(frozen=True)
class ImuCharacter:
    """A log's IMU (see the module docstring).

    Attributes:
        native_rate_hz: the IMU's own rate (readings per second, as logged).
        readings_per_sample: readings averaged into each of the drive's samples by the reader.
        sample_kind: :data:`AVERAGED` or :data:`SINGLE`; ``sample_kind_source``: how it is known
            (``"reader"``: it averaged several readings per sample; ``"assumed"``: a log cannot
            tell, the default for a low rate; ``"given"``: the user said).
        clock_offset_s: the IMU's stamps minus the receiver's for one instant (s; positive: stamped
            late), as estimated or given; ``clock_offset_sigma_s`` its uncertainty (inf: none);
            ``clock_offset_applied``: the samples were moved by it; ``clock_offset_note``: how it
            was found or why not.
        mount_deg: roll, pitch, yaw of the IMU on the car (degrees, :mod:`ionav_viz.core.rotation`'s
            convention) as estimated or given, None when not known; ``mount_sigma_deg`` their
            uncertainties; ``mount_applied``.
        wobble_dps: the spread of the pitch and roll rates' successive samples while driving
            (deg/s per sample): how much the holder shakes, as the samples see it.
        speed_lag_s: how late the receiver's speed is against the IMU (s, :mod:`ionav_viz.core.gnss_lag`);
            ``speed_lag_used``: resolved and large enough for ``gins`` to weigh it;
            ``speed_lag_note``: the estimate in words, or why there is none.
    """

    native_rate_hz: float
    readings_per_sample: float
    sample_kind: str
    sample_kind_source: str
    clock_offset_s: float = 0.0
    clock_offset_sigma_s: float = math.inf
    clock_offset_applied: bool = False
    clock_offset_note: str = ""
    mount_deg: tuple[float, float, float] | None = None
    mount_sigma_deg: tuple[float, float, float] | None = None
    mount_applied: bool = False
    wobble_dps: float = math.nan
    speed_lag_s: float = 0.0
    speed_lag_used: bool = False
    speed_lag_note: str = ""

    @property
    def single_readings(self) -> bool:
        return self.sample_kind == SINGLE

    def describe(self) -> str:
        """One line for reports: ``IMU 10 Hz, single readings (assumed), clock +0.30 s ± 0.01
        (applied), mount roll +1.0, pitch -0.5, yaw +8.2 deg (applied), holder wobble 2.7 deg/s, receiver
        speed 0.70 s late``."""
        kind = (f"averaged ({self.readings_per_sample:.0f} readings per sample)" if self.sample_kind_source == "reader"
                else f"{'single readings' if self.single_readings else 'averages'} ({self.sample_kind_source})")
        parts = [f"IMU {self.native_rate_hz:.0f} Hz, {kind}"]
        if math.isfinite(self.clock_offset_sigma_s) or self.clock_offset_applied:
            sigma = f" ± {self.clock_offset_sigma_s:.2f}" if math.isfinite(self.clock_offset_sigma_s) else ""
            parts.append(f"clock {self.clock_offset_s:+.2f} s{sigma} "
                         f"({'applied' if self.clock_offset_applied else 'not applied'})")
        elif self.clock_offset_note:
            parts.append(f"clock offset not resolved ({self.clock_offset_note})")
        if self.mount_deg is not None:
            roll, pitch, yaw = self.mount_deg
            parts.append(f"mount roll {roll:+.1f}, pitch {pitch:+.1f}, yaw {yaw:+.1f} deg "
                         f"({'applied' if self.mount_applied else 'not applied'})")
        if math.isfinite(self.wobble_dps):
            parts.append(f"holder wobble {self.wobble_dps:.1f} deg/s")
        if self.speed_lag_used:
            parts.append(f"receiver speed {self.speed_lag_s:.2f} s late")
        return ", ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
