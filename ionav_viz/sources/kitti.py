"""KITTI raw drive folders: the OXTS RT3003 GPS/IMU packets into a :class:`~ionav_viz.core.drive.Drive`.

A KITTI raw drive (``2011_09_26_drive_0001_sync`` or ``…_extract``) holds ``oxts/timestamps.txt``
(one ``YYYY-MM-DD HH:MM:SS.fffffffff`` per packet) and ``oxts/data/0000000000.txt`` … (one file
per packet, one line of the 30 documented OXTS fields, in this order)::

    lat lon alt roll pitch yaw vn ve vf vl vu ax ay az af al au wx wy wz wf wl wu
    pos_accuracy vel_accuracy navstat numsats posmode velmode orimode

Either the drive folder or its ``oxts`` folder may be given. The mapping:

* truth: ``lat``/``lon`` (deg, WGS84) and ``alt`` (m) of the OXTS solution; speed ``hypot(vn, ve)``
  (m/s) and course ``atan2(ve, vn)`` (deg clockwise from north) from its north and east velocities;
  ``pos_accuracy`` (m) is the fix's horizontal standard deviation (``gnss_sigma_m``) and
  ``numsats`` the satellite count (``n_satellites``).
* inertial inputs: forward acceleration ``af`` (m/s^2) and yaw rate ``wu`` (rad/s, about the up
  axis, counter-clockwise positive: already REP 103's sign). ``af``, ``al``, ``au`` and ``wf``,
  ``wl``, ``wu`` are the vehicle's level frame (forward and left parallel to the earth's surface,
  up perpendicular to it), so ``af`` carries no gravity from the road's slope and ``au`` reads
  about +9.81 m/s^2: the body frame's x, y, z of the other sources.
* KITTI's ``yaw`` is the heading counter-clockwise from east (rad); it is not the course (that
  comes from the velocities) and is not used: ionav-viz's courses are clockwise from north.
* quality: ``navstat`` is the OXTS navigation status; only 4 (locked: the GNSS-aided solution is
  running) is truth. Packets with any other status (0 invalid, 1 raw IMU only, 2 initialising,
  3 locking, 5 and above not navigating) are dropped from the truth like a receiver's no-fix
  messages: a stretch of them longer than 1 s is a GNSS gap (``gnss_fix`` 0, never scored).

The ``_sync`` folders are at 10 Hz and kept at their own stamps; the ``_extract`` folders are at
100 Hz and averaged onto the 10 Hz grid (:mod:`.resample`). Stamps are the folder's clock time;
the time of day of the drive is the first stamp's.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.grid import GRID_RATE_HZ
from .imu.character import ImuSettings
from .plausibility import first_implausible, implausible
from .resample import ImuBins, LogStreams, assemble_drive, drop_strays

log = logging.getLogger("ionav_viz")

FIELDS = ("lat", "lon", "alt", "roll", "pitch", "yaw", "vn", "ve", "vf", "vl", "vu", "ax", "ay", "az", "af", "al", "au",
          "wx", "wy", "wz", "wf", "wl", "wu", "pos_accuracy", "vel_accuracy", "navstat", "numsats", "posmode",
          "velmode", "orimode")
COLUMN = {name: i for i, name in enumerate(FIELDS)}
#: The OXTS navigation status of a locked (GNSS-aided, real-time) solution.
NAVSTAT_LOCKED = 4
#: Values checked at the boundary: OXTS field -> the drive-model column whose limits apply.
#: Every field the reader uses is checked (a column without limits must still be a finite number).
_CHECKED = {"lat": "lat_deg", "lon": "lon_deg", "alt": "height_m", "af": "accel_long_mps2", "al": "accel_long_mps2",
            "au": "accel_long_mps2", "wf": "yaw_rate_radps", "wl": "yaw_rate_radps", "wu": "yaw_rate_radps",
            **{v: "velocity_mps" for v in ("vn", "ve", "vf", "vl", "vu")}, "pos_accuracy": "gnss_sigma_m",
            "numsats": "n_satellites", "navstat": "navstat"}


def oxts_folder(path: Path) -> Path | None:
    """The ``oxts`` folder of a KITTI drive folder (or the folder itself), else None."""
    path = Path(path)
    if (path / "oxts").is_dir():
        return path / "oxts"
    if path.is_dir() and (path.name == "oxts" or ((path / "data").is_dir() and (path / "timestamps.txt").is_file())):
        return path
    return None


def _oxts_of(path: Path) -> Path:
    """:func:`oxts_folder`, or the error saying what a KITTI drive folder holds."""
    oxts = oxts_folder(path)
    if oxts is None:
        raise InputError(f"{path}: no oxts folder (oxts/timestamps.txt and oxts/data/)",
                         "give a KITTI raw drive folder (…_sync or …_extract) with its oxts data")
    return oxts


#: Bounds on what is read (real files: one 30-byte line per packet; a packet of 30 numbers in
#: about 250 bytes). Beyond them a file is damaged or crafted (a sparse file of gigabytes), refused
#: before it is read.
MAX_STAMP_LINE_BYTES = 64
MAX_PACKET_FILE_BYTES = 4096
#: Stamps outside these years are not a drive's (numpy's nanosecond clock ends in April 2262).
STAMP_YEARS = (1970, 2200)


def read_stamps_ns(path: Path, n_packets: int | None = None) -> np.ndarray:
    """Stamps (int64 ns since 1970 on the folder's clock) from a KITTI ``timestamps.txt``, in the
    file's order (one line per packet). With ``n_packets``, a file too large for that many lines is
    refused before it is read."""
    size = path.stat().st_size
    if n_packets is not None and size > MAX_STAMP_LINE_BYTES * (n_packets + 1):
        raise InputError(f"{path}: {size} bytes is far more than {n_packets} stamp lines (about 30 bytes each)",
                         "the file is damaged; extract the drive's zip again")
    lines = [line.strip() for line in path.read_text(errors="replace").splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    for i, line in enumerate(lines):
        if not line:
            raise InputError(f"{path}: line {i + 1} is empty",
                             "each line is one packet's stamp (YYYY-MM-DD HH:MM:SS.fffffffff); extract the drive again")
    try:
        coarse = np.array(lines, dtype="datetime64[us]")  # a range of ±290,000 years: no overflow
    except ValueError:
        bad = next(i for i, line in enumerate(lines) if not _is_stamp(line))
        raise InputError(f"{path}: line {bad + 1} is not a stamp ({lines[bad][:40]!r})",
                         "expected YYYY-MM-DD HH:MM:SS.fffffffff; extract the drive again") from None
    years = coarse.astype("datetime64[Y]").astype(np.int64) + 1970
    outside = (years < STAMP_YEARS[0]) | (years >= STAMP_YEARS[1])
    if outside.any():
        bad = int(np.argmax(outside))
        raise InputError(f"{path}: line {bad + 1}: the stamp {lines[bad][:40]!r} is not in the years "
                         f"{STAMP_YEARS[0]}-{STAMP_YEARS[1] - 1}",
                         "the file is damaged; extract the drive again")
    return np.array(lines, dtype="datetime64[ns]").astype(np.int64)


def _is_stamp(text: str) -> bool:
    try:
        np.datetime64(text, "ns")
    except ValueError:
        return False
    return True


def read_packets(oxts: Path) -> tuple[np.ndarray, np.ndarray]:
    """``(stamps ns since 1970, packets (n, 30))`` of a KITTI ``oxts`` folder, or an error naming the file."""
    stamps_file, data = oxts / "timestamps.txt", oxts / "data"
    if not stamps_file.is_file():
        raise InputError(f"{stamps_file}: missing",
                         "a KITTI raw drive's oxts folder holds timestamps.txt and data/; extract the "
                         "drive's zip again")
    if not data.is_dir():
        raise InputError(f"{data}: missing",
                         "a KITTI raw drive's oxts folder holds timestamps.txt and data/; extract the "
                         "drive's zip again")
    files = sorted(p for p in data.iterdir() if p.suffix == ".txt")
    if folder := next((p for p in files if not p.is_file()), None):
        raise InputError(f"{folder}: not a packet file (a folder or a special file)", "extract the drive's zip again")
    if not files:
        raise InputError(f"{data}: no packet files (0000000000.txt, ...)", "extract the drive's zip again")
    for i, f in enumerate(files):
        if f.stem != f"{i:010d}":
            raise InputError(f"{data / f'{i:010d}.txt'}: missing (the packets are numbered from 0000000000.txt "
                             "without gaps)",
                             "extract the drive's zip again")
    t = read_stamps_ns(stamps_file, len(files))
    if len(files) != len(t):
        raise InputError(f"{oxts}: {len(t)} stamps in timestamps.txt but {len(files)} packet files in data/",
                         "the folder is incomplete or mixed from two drives; extract the drive's zip again")
    rows = []
    for f in files:
        if (size := f.stat().st_size) > MAX_PACKET_FILE_BYTES:
            raise InputError(f"{f}: {size} bytes is far more than an OXTS packet (30 numbers, about 250 bytes)",
                             "the file is damaged; extract the drive's zip again")
        values = f.read_text(errors="replace").split()
        if len(values) != len(FIELDS):
            raise InputError(f"{f}: {len(values)} values, an OXTS packet has {len(FIELDS)}",
                             "the file is damaged; extract the drive's zip again")
        rows.append(values)
    try:
        packets = np.array(rows, dtype=float)
    except ValueError:
        i = next(i for i, r in enumerate(rows) if not all(_is_number(v) for v in r))
        raise InputError(f"{files[i]}: not all values are numbers",
                         "the file is damaged; extract the drive's zip again") from None
    return t, packets


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _check_values(oxts: Path, packets: np.ndarray) -> None:
    """Refuse an impossible value, naming the packet's file."""
    for name, column in _CHECKED.items():
        values = packets[:, COLUMN[name]]
        if (i := first_implausible(column, values)) is not None:
            raise InputError(f"{oxts / 'data' / f'{i:010d}.txt'}: {name} {implausible(column, float(values[i]))}",
                             "no car sensor produces that value: the packet is damaged")


def read_kitti(path: str | Path, *, name: str | None = None, yaw_sign: str = "auto") -> Drive:
    """Read a KITTI raw drive folder (or its ``oxts`` folder) into a drive (see the module docstring)."""
    oxts = _oxts_of(Path(path))
    if yaw_sign not in ("auto", "cw", "ccw"):
        raise InputError(f"yaw sign {yaw_sign!r} is not auto, cw or ccw", param="yaw_sign")
    t_ns, p = read_packets(oxts)
    _check_values(oxts, p)
    origin_ns = int(t_ns.min()) - int(t_ns.min()) % 1_000_000_000
    t = (t_ns - origin_ns) * 1e-9  # s after a whole second: float64 keeps the nanoseconds
    order = np.argsort(t, kind="stable")
    keep = np.empty(len(t), dtype=bool)
    keep[order] = drop_strays(oxts, "OXTS", t[order], origin_s=origin_ns // 1_000_000_000)
    line, t, p = np.flatnonzero(keep) + 1, t[keep], p[keep]
    if (back := np.diff(t) < 0).any():  # packets are numbered in the order they were sampled
        i = int(np.argmax(back)) + 1
        raise InputError(f"{oxts / 'timestamps.txt'}: line {line[i]}: time goes backwards ({t[i - 1]:.3f} s -> "
                         f"{t[i]:.3f} s after the first whole second) between packets {line[i - 1] - 1:010d} and "
                         f"{line[i] - 1:010d}",
                         "the stamps and packets are out of step: extract the drive's zip again")
    first = np.concatenate([[True], np.diff(t) > 0])
    if not first.all():
        log.warning("%s: %d OXTS packet(s) repeat an earlier stamp; kept the first of each", oxts, int((~first).sum()))
        t, p = t[first], p[first]
    col = {k: p[:, i] for k, i in COLUMN.items()}
    locked = col["navstat"] == NAVSTAT_LOCKED
    if locked.sum() < 2:
        raise InputError(f"{oxts}: fewer than 2 packets with a locked navigation solution (navstat "
                         f"{NAVSTAT_LOCKED}) of {len(t)}",
                         "the drive needs GNSS-aided truth; this one never locked")
    if not locked.all():
        log.warning("%s: %d of %d OXTS packets are not locked (navstat != %d); their positions are not truth",
                    oxts, int((~locked).sum()), len(t), NAVSTAT_LOCKED)

    imu = ImuBins(1.0 / GRID_RATE_HZ, keep_samples=True, prepare=lambda block: block)
    imu.add_block(np.column_stack([t, col["af"], col["al"], col["au"], col["wf"], col["wl"], col["wu"]]))
    fixes = np.column_stack([t, col["lat"], col["lon"], col["alt"], col["pos_accuracy"]])[locked]
    course_deg = np.degrees(np.arctan2(col["ve"], col["vn"])) % 360.0
    speeds = np.column_stack([t, np.hypot(col["vn"], col["ve"]), course_deg])[locked]
    drive_name = name or (oxts.parent.name if oxts.name == "oxts" else oxts.name)
    streams = LogStreams(imu, fixes, speeds, origin_s=origin_ns // 1_000_000_000,
                         fix_columns={"n_satellites": col["numsats"][locked]})
    # OXTS gives its inertial data in the vehicle frame, averaged at 10 Hz from its 100 Hz IMU
    return assemble_drive(oxts, drive_name, streams, ImuSettings(np.eye(3), yaw_sign, np.eye(3), samples="averaged"))


@dataclass(frozen=True)
class KittiDescription:
    """What a KITTI drive's OXTS folder holds (``ionav-viz info``)."""

    oxts: Path
    packets: int
    duration_s: float
    rate_hz: float
    navstat_counts: dict[int, int]  # navigation status -> packets


def describe_kitti(path: str | Path) -> KittiDescription:
    """Packets, span, rate and navigation statuses of a KITTI drive folder."""
    oxts = _oxts_of(Path(path))
    t, p = read_packets(oxts)
    status, counts = np.unique(p[:, COLUMN["navstat"]].astype(int), return_counts=True)
    duration = float(t.max() - t.min()) * 1e-9 if len(t) else 0.0
    rate = (len(t) - 1) / duration if duration > 0 else 0.0
    return KittiDescription(oxts, len(t), duration, rate, {int(s): int(n) for s, n in zip(status, counts)})
