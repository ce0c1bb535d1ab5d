"""Reader (and writer) of IO-VNBD vehicle files ``V-*.csv``.

The format, as the real files have it (see the dataset notes): 29 columns, a header whose
names after the first carry a leading space and the dataset's own typos ("fof"), 10 Hz rows
from the car's CAN bus and a Racelogic VBOX GNSS logger, units km/h, g, deg/s, decimal
degrees. Some files carry cp1252 bytes.

Everything is converted to :class:`ionav_viz.core.drive.Drive` units here, once:

* km/h -> m/s, g -> m/s^2 (9.80665), deg/s -> rad/s.
* Latitude/longitude given as VBOX minutes (|lat| > 90) are divided by 60 and the
  longitude negated (VBOX minutes are west-positive).
* Yaw-rate sign. The column is read as **clockwise positive** (compass style, like the
  heading column) unless told otherwise, and converted to the drive model's
  counter-clockwise-positive yaw rate. The sign is then checked against the GNSS heading
  change: if the drive's own data clearly says the opposite (correlation below -0.5 over at
  least 5 s of turning at speed), the reader flips it and warns. ``yaw_sign='cw'|'ccw'``
  forces the interpretation and skips the check.
* Time: "time since start of day" becomes ``t_s`` from the first row; a wrap past midnight
  is unwrapped. Time going backwards is an error naming the row; rows repeating the previous
  time stamp are dropped with a warning. Gaps (0.2 s periods, longer dropouts) are kept as
  they are: :mod:`ionav_viz.nav.windows` bridges short gaps and splits the drive at long ones.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.signals import signals_surfaced
from ..core.units import DEG_TO_RAD, G_MPS2, KMH_TO_MPS, wrap_360
from .imu.axes import STRONG, heading_rate_ccw_radps, yaw_correlation
from .mcap_reader import MAGIC as MCAP_MAGIC
from .plausibility import check_plausible, check_units_agree
from .rosbag_reader import ROS1_MAGIC

log = logging.getLogger("ionav_viz")

#: The exact header names of a real ``V-*.csv`` file, in order (without leading spaces).
HEADER = (
    "No of GPS Satellites Available",
    "Time Since Start of Day (seconds)",
    "Latitude (degrees)",
    "Longitude (degrees)",
    "Velocity (km/hr)",
    "Heading (degrees)",
    "Height (km)",
    "Vertical velocity (km/hr)",
    "Sample period (seconds)",
    "Steering Angle (degrees)",
    "Wheel Speed Front Left (rad/sec)",
    "Wheel Speed Front Right (rad/sec)",
    "Wheel Speed Rear Left (rad/sec)",
    "Wheel Speed Rear Right (rad/sec)",
    "Yaw Rate (deg/sec)",
    "Indicated Vehicle Speed (km/hr)",
    "Indicated Longitudinal Acceleration (g)",
    "Indicated Lateral Acceleration (g)",
    "Handbrake (0 or 1)",
    "Gear Requested (Number fof gear employed 1-5)",
    "Gear (Number fof gear employed 1-5)",
    "Engine Speed (rev/min)",
    "Coolant Temperature (degrees)",
    "Clutch Position (0 or 1)",
    "Brake Pressure (psi)",
    "Brake Position (0 or 1)",
    "Battery Voltage (volts)",
    "Air Temperature (degrees)",
    "Accelerator Pedal Position (0 or 1)",
)

#: The header line as the real files write it: a leading space before every name but the first.
HEADER_LINE = ",".join([HEADER[0]] + [" " + h for h in HEADER[1:]])

_ANGLE = {"degrees": 1.0, "deg": 1.0}
_SPEED = {"km/hr": KMH_TO_MPS, "km/h": KMH_TO_MPS, "kmh": KMH_TO_MPS, "kph": KMH_TO_MPS, "m/s": 1.0, "mph": 0.44704}
_ACCEL = {"g": G_MPS2, "m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0}
_RATE = {"deg/sec": DEG_TO_RAD, "deg/s": DEG_TO_RAD, "rad/sec": 1.0, "rad/s": 1.0}
_WHEEL = {"rad/sec": 1.0, "rad/s": 1.0}

# Drive-model column <- (header label before the unit, {unit in the header: factor to SI}, required).
# The first unit is the dataset's own, assumed when a header gives none; another known unit is
# converted (a CSV written in SI units reads the same), an unknown one is refused.
_COLUMNS = {
    "n_satellites": ("no of gps satellites available", {"": 1.0}, False),
    "time_of_day_s": ("time since start of day", {"seconds": 1.0, "s": 1.0, "sec": 1.0}, True),
    "lat_deg": ("latitude", _ANGLE, True),
    "lon_deg": ("longitude", _ANGLE, True),
    "speed_mps": ("velocity", _SPEED, True),
    "heading_deg": ("heading", _ANGLE, True),
    # The header says km, but the values (20-535) are metres above sea level.
    "height_m": ("height", {"km": 1.0, "m": 1.0}, False),
    "steering_angle_deg": ("steering angle", _ANGLE, False),
    "wheel_speed_fl_radps": ("wheel speed front left", _WHEEL, False),
    "wheel_speed_fr_radps": ("wheel speed front right", _WHEEL, False),
    "wheel_speed_rl_radps": ("wheel speed rear left", _WHEEL, False),
    "wheel_speed_rr_radps": ("wheel speed rear right", _WHEEL, False),
    "yaw_rate_raw": ("yaw rate", _RATE, True),
    "speed_can_mps": ("indicated vehicle speed", _SPEED, False),
    "accel_long_mps2": ("indicated longitudinal acceleration", _ACCEL, True),
    "accel_lat_mps2": ("indicated lateral acceleration", _ACCEL, False),
}

YAW_SIGNS = ("auto", "cw", "ccw")
_DAY_S = 86400.0


def _label(header: str) -> str:
    """'  Yaw Rate (deg/sec)' -> 'yaw rate'."""
    return re.sub(r"\s+", " ", header.split("(")[0]).strip().lower()


def _unit(header: str) -> str | None:
    """'  Yaw Rate (deg/sec)' -> 'deg/sec'; None when the name carries no unit."""
    found = re.search(r"\(([^)]*)\)", header)
    return re.sub(r"\s+", "", found.group(1)).lower() if found else None


def _factor(path: Path, header: str, units: dict[str, float]) -> float:
    """Factor from the unit the header names to drive-model units; an unknown unit is refused."""
    unit = _unit(header)
    if unit is None or "" in units:
        return next(iter(units.values()))
    if unit not in units:
        raise InputError(f"{path}: column {header.strip()!r}: unknown unit {unit!r}",
                         f"ionav-viz reads this column in {', '.join(u for u in units)}; fix the header")
    if unit != next(iter(units)):
        log.info("%s: column %r in %s, converted", path, header.strip(), unit)
    return units[unit]


#: Files above this size are refused rather than risking memory (IO-VNBD's largest run is 27 MB).
MAX_FILE_BYTES = 2 * 1024**3
_BOMS = (b"\xff\xfe", b"\xfe\xff")
#: Logs ionav-viz reads, known by their first bytes: an MCAP or a ROS 1 bag renamed .csv is named as such.
_LOG_MAGICS = ((MCAP_MAGIC, "an MCAP log", ".mcap"), (ROS1_MAGIC, "a ROS 1 bag", ".bag"))


def _encodings(path: Path) -> list[str]:
    """Encodings to try, in order: UTF-16 when a BOM says so, else UTF-8, cp1252, latin-1."""
    with open(path, "rb") as f:
        head = f.read(65536)
    if head.startswith(_BOMS):
        return ["utf-16"]
    for magic, what, suffix in _LOG_MAGICS:
        if head.startswith(magic):
            raise InputError(f"{path}: {what}, named {path.suffix or 'without a suffix'}, not a CSV file",
                             f"rename it to {path.with_suffix(suffix).name} (ionav-viz reads a log by its suffix)")
    if b"\x00" in head:
        raise InputError(f"{path}: binary data, not a CSV text file", "pass an IO-VNBD V-*.csv file")
    return ["utf-8-sig", "cp1252", "latin-1"]


def _last_line_is_cut(path: Path, encoding: str, n_fields: int) -> bool:
    """Whether the file ends mid-line: no final newline and fewer fields than the header."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        f.seek(max(0, size - 65536))
        tail = f.read()
    if tail.endswith(b"\n") or tail.endswith(b"\n\x00"):
        return False
    last = tail.decode(encoding, errors="replace").splitlines()[-1] if tail else ""
    return 0 < len(last.split(",")) < n_fields


def _read_csv(path: Path, **options):
    """``pandas.read_csv``, stopped by Ctrl-C, SIGTERM and SIGHUP as everything else is: its C
    parser turns the signal's exception inside ``read()`` into a ``ParserError`` otherwise, which
    read as a file that is not a CSV (:func:`~ionav_viz.core.signals.signals_surfaced`)."""
    import pandas as pd

    with signals_surfaced():
        return pd.read_csv(path, **options)


def _read_columns(path: Path, encoding: str) -> tuple[dict[str, str], object, int]:
    """Header labels -> header names, the needed columns as float64 (pandas C parser), and the
    number of header fields."""
    header = _read_csv(path, encoding=encoding, nrows=0, skipinitialspace=True)
    _refuse_repeated_columns(path, encoding)
    by_label: dict[str, str] = {}
    for name in header.columns:
        by_label.setdefault(_label(str(name)), name)
    missing = [label for key, (label, _, req) in _COLUMNS.items() if req and label not in by_label]
    if missing:
        raise InputError(
            f"{path}: missing column(s) {', '.join(repr(m) for m in missing)}",
            "expected the IO-VNBD V-*.csv header (see 'IO-VNBD CSV' in docs/formats.md)",
        )
    wanted = [by_label[label] for label, _, _ in _COLUMNS.values() if label in by_label]
    try:
        frame = _read_csv(path, encoding=encoding, usecols=wanted, skipinitialspace=True, dtype=np.float64)
    except ValueError as exc:
        if isinstance(exc, UnicodeDecodeError):
            raise
        _locate_bad_cell(path, encoding, wanted, required=wanted)
        raise InputError(f"{path}: not a readable CSV ({_first_line(exc)})") from None
    return by_label, frame, len(header.columns)


def _refuse_repeated_columns(path: Path, encoding: str) -> None:
    """A column ionav-viz reads named twice in the header (pandas renamed the second ``NAME.1`` and
    the first was read silently, whichever held the data): refused, naming both."""
    import csv

    with open(path, encoding=encoding, newline="") as f:
        names = next(csv.reader([f.readline(1 << 16)]), [])
    used = {label for label, _, _ in _COLUMNS.values()}
    seen: dict[str, int] = {}
    for k, name in enumerate(names, start=1):
        label = _label(name.strip())
        if label in used and label in seen:
            raise InputError(f"{path}: column {name.strip()!r} appears twice in the header (columns "
                             f"{seen[label]} and {k})",
                             "keep one: ionav-viz cannot tell which holds the data")
        seen.setdefault(label, k)


def _check_field_counts(path: Path, encoding: str, n_fields: int, n_rows: int, cut_last: bool) -> None:
    """Every row must have the header's number of fields: a shifted row would silently misalign.

    Fields are counted per line with numpy, block by block (a row one field short followed by one
    a field long has the right total); only a mismatch scans line by line to name it.
    """
    if not encoding.startswith("utf-16") and _field_counts_match(path, n_fields):
        return
    with open(path, encoding=encoding, errors="replace", newline="") as f:
        for number, line in enumerate(f, start=1):
            fields = line.rstrip("\r\n").count(",") + 1
            if fields != n_fields and line.strip() and not (cut_last and number == n_rows + 1):
                raise InputError(
                    f"{path}: line {number} has {fields} fields, the header has {n_fields}",
                    "a shifted or broken row; fix or delete it",
                )


def _field_counts_match(path: Path, n_fields: int) -> bool:
    """Whether every line (the last may lack its newline) has ``n_fields - 1`` commas; False also
    for blank lines or a cut last line, which the line-by-line scan then judges."""
    carry = 0  # commas of the line still open at the end of the previous block
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            data = np.frombuffer(block, dtype=np.uint8)
            commas = np.flatnonzero(data == ord(","))
            newlines = np.flatnonzero(data == ord("\n"))
            per_line = np.diff(np.searchsorted(commas, newlines), prepend=0)
            if len(per_line):
                per_line[0] += carry
                if np.any(per_line != n_fields - 1):
                    return False
                carry = len(commas) - int(np.searchsorted(commas, newlines[-1]))
            else:
                carry += len(commas)
    return carry in (0, n_fields - 1)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _locate_bad_cell(path: Path, encoding: str, columns: list[str], required: list[str]) -> None:
    """Raise an InputError naming the first cell of ``required`` that is not a finite number."""
    import pandas as pd

    cells = _read_csv(path, encoding=encoding, usecols=columns, skipinitialspace=True, dtype=str, keep_default_na=False)
    for name in required:
        text = cells[name].fillna("").str.strip()
        numbers = pd.to_numeric(text, errors="coerce").to_numpy(dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(numbers))
        if bad.size:
            row, cell = int(bad[0]), text.iloc[int(bad[0])]
            what = ("empty cell" if cell == ""
                    else (f"not a finite number ({cell!r})"
                          if cell.lower() in ("nan", "inf", "-inf", "+inf", "infinity", "-infinity")
                          else f"non-numeric value {cell!r}"))
            raise InputError(f"{path}: row {row + 2}, column {name.strip()!r}: {what}", "fix or delete that row")


def read_iovnbd(path: str | Path, *, name: str | None = None, yaw_sign: str = "auto") -> Drive:
    """Read an IO-VNBD vehicle file into a :class:`Drive` (SI units, documented conventions).

    Raises :class:`InputError` naming the file, row (1-based line number in the file) or
    column for anything that cannot be read. Only the columns the drive model uses are parsed
    (as numbers, by pandas' C parser), so memory stays near 16 x 8 bytes per row; files over
    2 GiB are refused. A last line cut off mid-way (a log that ended abruptly) is dropped with a
    warning.
    """
    path = Path(path)
    if yaw_sign not in YAW_SIGNS:
        raise InputError(f"unknown yaw sign {yaw_sign!r}", "use one of auto, cw, ccw")
    _check_size(path)
    by_label, frame, encoding = _read_frame(path)
    values, file_units = _si_columns(path, frame, by_label, encoding)

    time_of_day = values.pop("time_of_day_s")
    t_s = _unwrap_midnight(time_of_day, path)
    keep = _drop_repeated_times(t_s, path)
    t_s = t_s[keep]
    values = {k: v[keep] for k, v in values.items()}
    line_of_row = np.flatnonzero(keep) + 2
    if len(t_s) < 2:
        raise InputError(f"{path}: fewer than 2 rows with distinct time stamps",
                         "check the 'Time Since Start of Day' column")

    _warn_time_gaps(t_s - t_s[0], line_of_row, path)
    _fix_degrees(values, path)
    values["yaw_rate_radps"] = values.pop("yaw_rate_raw")  # the limits do not depend on the sign
    names = {key: by_label[label].strip() for key, (label, _, _) in _COLUMNS.items() if label in by_label}
    names["yaw_rate_radps"] = names["yaw_rate_raw"]
    check_plausible(values, path, lambda i: f"row {line_of_row[i]}", names, file_units)
    check_units_agree(values, t_s, path, names)
    raw_yaw = values.pop("yaw_rate_radps")
    values["yaw_rate_radps"] = _yaw_rate_ccw(raw_yaw, values, t_s, yaw_sign, path)
    values["heading_deg"] = wrap_360(values["heading_deg"])
    values["t_s"] = t_s - t_s[0]

    return Drive(
        name=name or run_name_of(path),
        source=str(path),
        rate_hz=_nominal_rate(t_s),
        start_time_of_day_s=float(time_of_day[0] % _DAY_S),
        columns=values,
        start_stamp_s=float(time_of_day[0]),
    )


def _check_size(path: Path) -> None:
    """Refuse a file that cannot be read, is larger than :data:`MAX_FILE_BYTES` or holds nothing."""
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    if size > MAX_FILE_BYTES:
        raise InputError(f"{path}: {size / 2**30:.1f} GiB is larger than the 2 GiB ionav-viz reads at once",
                         "split the log into drives of a few hours (IO-VNBD's largest run is 27 MB)")
    with open(path, "rb") as f:
        head = f.read(4096)
    if not head.strip(b" \t\r\n\xef\xbb\xbf\xff\xfe"):
        raise InputError(f"{path}: empty file", "an IO-VNBD V-*.csv starts with the 29-column header")


def _read_frame(path: Path):
    """The used columns as a data frame, in the first encoding that decodes the file: the header's
    names by label, the frame (a last line cut off mid-way dropped) and the encoding."""
    import pandas as pd

    frame = by_label = encoding = None
    n_fields = 0
    for encoding in _encodings(path):
        try:
            by_label, frame, n_fields = _read_columns(path, encoding)
            break
        except UnicodeDecodeError:
            continue
        except pd.errors.EmptyDataError:
            raise InputError(f"{path}: empty file", "an IO-VNBD V-*.csv starts with the 29-column header") from None
        except pd.errors.ParserError as exc:
            raise InputError(f"{path}: not a readable CSV ({_first_line(exc)})",
                             "every row needs the header's columns") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    if frame is None:
        raise InputError(f"{path}: text in an unknown encoding")
    cut = len(frame) > 0 and _last_line_is_cut(path, encoding, n_fields)
    _check_field_counts(path, encoding, n_fields, len(frame), cut)
    if cut:
        log.warning("%s: the file ends mid-line; dropped its last row (%d)", path, len(frame) + 1)
        frame = frame.iloc[:-1]
    if len(frame) < 2:
        raise InputError(f"{path}: fewer than 2 data rows", "a drive needs samples to replay")
    return by_label, frame, encoding


def _si_columns(path: Path, frame, by_label: dict[str, str],
                encoding: str) -> tuple[dict[str, np.ndarray], dict[str, tuple[float, str]]]:
    """Each known column in SI units (optional columns left empty by the logger left out; a
    required one with a cell that is not a number is an error naming it), and the file's unit of
    each (its factor to SI and its name)."""
    values: dict[str, np.ndarray] = {}
    file_units: dict[str, tuple[float, str]] = {}
    required = [by_label[label] for label, _, req in _COLUMNS.values() if req]
    for key, (label, units, req) in _COLUMNS.items():
        header = by_label.get(label)
        if header is None:
            continue
        factor = _factor(path, header, units)
        file_units["yaw_rate_radps" if key == "yaw_rate_raw" else key] = (factor, _unit(header) or next(iter(units)))
        numbers = frame[header].to_numpy(dtype=np.float64)
        finite = np.isfinite(numbers)
        if req and not finite.all():
            _locate_bad_cell(path, encoding, required, required)
        if not req and not finite.any():
            continue  # an optional column left empty by the logger
        values[key] = numbers * factor
    return values, file_units


def run_name_of(path: Path) -> str:
    """``.../V-Vw8.csv`` -> ``V-Vw8``."""
    return Path(path).stem


def _unwrap_midnight(time_of_day: np.ndarray, path: Path) -> np.ndarray:
    dt = np.diff(time_of_day)
    wraps = (dt < -_DAY_S / 2) & (time_of_day[:-1] > _DAY_S - 3600.0)
    t = time_of_day + _DAY_S * np.concatenate([[0.0], np.cumsum(wraps)])
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        row = int(back[0]) + 1
        raise InputError(
            f"{path}: row {row + 2}: time goes backwards ({t[row - 1] if row else t[0]:.3f} s -> {t[row]:.3f} s)",
            "the file may be two logs joined together; split it at that row",
        )
    return t


def _drop_repeated_times(t_s: np.ndarray, path: Path) -> np.ndarray:
    keep = np.concatenate([[True], np.diff(t_s) > 0])
    dropped = int((~keep).sum())
    if dropped:
        first = int(np.flatnonzero(~keep)[0])
        log.warning("%s: dropped %d row(s) repeating the previous time stamp (first at row %d)", path, dropped,
                    first + 2)
    return keep


#: A hole in the time stamps longer than this splits the drive: no 1 s window spans it (the
#: windows' ``max_gap_s``, :func:`ionav_viz.nav.windows.make_windows`).
GAP_S = 1.0


def _warn_time_gaps(t_s: np.ndarray, line_of_row: np.ndarray, path: Path) -> None:
    """Say where rows are missing for more than :data:`GAP_S` (a logger that stopped), on the
    drive's own clock with the file's rows on either side: no window or outage spans a gap."""
    dt = np.diff(t_s)
    gaps = np.flatnonzero(dt > max(GAP_S, 2.0 * float(np.median(dt))))  # a log of 1 Hz or less is refused for its rate
    if not gaps.size:
        return
    said = [f"{dt[i]:.1f} s from {t_s[i]:.1f} s (row {line_of_row[i]}) to {t_s[i + 1]:.1f} s (row {line_of_row[i + 1]})"
            for i in gaps[:3]]
    more = f" and {gaps.size - 3} more" if gaps.size > 3 else ""
    log.warning("%s: no rows for %s%s; no window or outage spans %s (the stretches either side are evaluated apart)",
                path, "; ".join(said), more, "the gap" if gaps.size == 1 else "a gap")


def _fix_degrees(values: dict[str, np.ndarray], path: Path) -> None:
    """Detect VBOX minutes (every |latitude| above 90) and check ranges; errors name the row."""
    lat, lon = values["lat_deg"], values["lon_deg"]
    above = np.abs(lat) > 90.0
    if above.all():
        log.info("%s: latitude/longitude in VBOX minutes; converted to degrees", path)
        lat, lon = lat / 60.0, -lon / 60.0
        values["lat_deg"], values["lon_deg"] = lat, lon
    for name, x, limit in (("latitude", lat, 90.0), ("longitude", lon, 180.0)):
        bad = np.flatnonzero(np.abs(x) > limit)
        if bad.size:
            row = int(bad[0])
            raise InputError(
                f"{path}: row {row + 2}: {name} {x[row]:g} out of range [-{limit:g}, {limit:g}]",
                "fix or delete that row (a file in VBOX minutes has every latitude above 90)",
            )


def _yaw_rate_ccw(raw: np.ndarray, values: dict, t_s: np.ndarray, yaw_sign: str, path: Path) -> np.ndarray:
    if yaw_sign == "ccw":
        return raw
    assumed = -raw  # documented default: the column is clockwise positive
    if yaw_sign == "cw":
        return assumed
    corr = yaw_correlation(assumed, heading_rate_ccw_radps(t_s, values["heading_deg"], values["speed_mps"]))
    if corr is not None and corr < -STRONG:
        log.warning(
            "%s: yaw-rate column is counter-clockwise positive (correlation with the GNSS heading "
            "change %.2f); flipped it. Force with --yaw-sign cw|ccw",
            path,
            corr,
        )
        return raw
    return assumed


def _nominal_rate(t_s: np.ndarray) -> float:
    median_dt = float(np.median(np.diff(t_s)))
    return round(1.0 / median_dt, 1) if median_dt > 0 else 0.0


def write_iovnbd(path: str | Path, rows: dict[str, np.ndarray], decimals: dict[str, int]) -> None:
    """Write raw IO-VNBD columns (file units, keyed by :data:`HEADER` names) as a real file does.

    Rows end with CRLF, the header carries the leading spaces; written to a temporary file and
    renamed on success.
    """
    from ..core.fileio import atomic_write_bytes

    n = len(next(iter(rows.values())))
    formatted = []
    for header in HEADER:
        d = decimals[header]
        col = np.asarray(rows[header], dtype=np.float64)
        formatted.append(np.char.mod(f"%.{d}f", col) if d > 0 else np.char.mod("%d", np.rint(col).astype(np.int64)))
    lines = [HEADER_LINE]
    table = np.stack(formatted, axis=1) if n else np.empty((0, len(HEADER)), dtype=str)
    lines.extend(",".join(r) for r in table)
    atomic_write_bytes(Path(path), ("\r\n".join(lines) + "\r\n").encode("ascii"))
