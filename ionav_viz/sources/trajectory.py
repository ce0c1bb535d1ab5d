"""Reading an estimated trajectory that an estimator outside ionav-viz wrote (``--external NAME=PATH``).

Stamps are on the clock of the outaged log the estimator ran on (:mod:`ionav_viz.experiment.plan_file`:
UNIX seconds for message logs, the time of day for IO-VNBD). Positions are WGS84 degrees, or
metres in the **local frame**: east (x) and north (y) on the azimuthal equidistant plane about the
drive's first trustworthy GNSS fix (``Drive.local_origin_deg``), up ignored. Formats:

* ``PATH:TOPIC`` of an MCAP file or a ROS bag: ``sensor_msgs/NavSatFix`` (latitude, longitude;
  no-fix messages skipped), or ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
  ``PoseWithCovarianceStamped`` in the local frame; stamped by the header (the log time when 0).
* ``.tum``: evo's TUM format, one pose per line ``t x y z qx qy qz qw`` (``#`` comments), x and y
  in the local frame.
* ``.csv``: a header ``time_s,lat_deg,lon_deg`` or ``time_s,east_m,north_m``, one row per pose;
  further columns are ignored except the covariance below.

How sure the estimator was (optional, :attr:`Trajectory.cov_en_m2`): the east/north position
covariance (m^2) of each pose, from the CSV columns ``cov_ee_m2,cov_en_m2,cov_nn_m2`` (all three,
anywhere after the first three), from ``PoseWithCovarianceStamped`` and ``Odometry`` (the x/y block
of ``pose.covariance``, ROS's ENU local frame) or from ``NavSatFix`` (the east/north block of
``position_covariance`` unless its type is 0, unknown). It must be finite and positive
semi-definite on every pose that has one; a log whose messages all carry zeros (or -1 first,
unknown) has none.

Samples are sorted by stamp. Poses sharing a stamp are one pose written twice when within
:data:`SAME_POSE_M` (kept once, with a warning); farther apart they conflict, and the trajectory is refused.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.covariance import COVARIANCE_MAX_M2, covariance_en, covariance_faults
from ..core.errors import InputError
from ..core.fileio import check_regular_input, check_regular_tree, check_text_head
from ..core.geo import steps_en_m

#: A trajectory file larger than this is refused (a day at 100 Hz in CSV is about 300 MB).
MAX_BYTES = 2 << 30
#: Two poses with one stamp closer than this (m) are one pose written twice (dropped, with a warning);
#: farther apart they conflict (refused).
SAME_POSE_M = 0.001
log = logging.getLogger("ionav_viz")
_TRAJECTORY_HINT = "write time_s,lat_deg,lon_deg (or time_s,east_m,north_m) CSV, a TUM file, or give LOG:TOPIC"
#: The CSV columns of a pose's east/north covariance (m^2).
COVARIANCE_COLUMNS = ("cov_ee_m2", "cov_en_m2", "cov_nn_m2")
_COVARIANCE_HINT = ("give each pose's east/north covariance (m^2) with cov_ee_m2 >= 0, cov_nn_m2 >= 0 and "
                    f"cov_en_m2^2 <= cov_ee_m2 * cov_nn_m2, each at most {COVARIANCE_MAX_M2:g}")


@dataclass(frozen=True)
class Trajectory:
    """Poses of an external estimate: ``stamps_s`` (sorted, unique) with either ``lat_deg``/``lon_deg``
    or ``east_m``/``north_m`` in the local frame (the other pair None)."""

    source: str
    stamps_s: np.ndarray
    lat_deg: np.ndarray | None = None
    lon_deg: np.ndarray | None = None
    east_m: np.ndarray | None = None
    north_m: np.ndarray | None = None
    #: per pose, the east/north position covariance (m^2, ``(n, 2, 2)``), or None (none given)
    cov_en_m2: np.ndarray | None = None

    @property
    def local(self) -> bool:
        return self.east_m is not None


def read_trajectory(spec: str | Path) -> Trajectory:
    """The trajectory ``spec`` names (see the module docstring), checked; an error naming the file otherwise."""
    text = str(spec)
    path = Path(text)
    topic = None
    if not path.exists() and ":" in text:
        head, topic = text.rsplit(":", 1)
        path = Path(head)
    if not path.exists():
        raise InputError(f"{path}: no such trajectory file", _TRAJECTORY_HINT, param="external")
    # a named pipe hung the reader
    check_regular_input(path, "external", hint=_TRAJECTORY_HINT, folder_ok=topic is not None)
    if path.is_dir():
        check_regular_tree(path, "external", hint=_TRAJECTORY_HINT)  # a ROS 2 bag's files
    if topic is not None:
        return _from_log(path, topic)
    suffix = path.suffix.lower()
    if path.is_file() and path.stat().st_size > MAX_BYTES:
        raise InputError(f"{path}: {path.stat().st_size} bytes is too large for a trajectory", _TRAJECTORY_HINT,
                         param="external")
    if suffix in (".tum", ".csv"):  # a 1 GB sparse file was read whole as its header and quoted in the message (a hang)
        check_text_head(path, "external", hint=_TRAJECTORY_HINT, what="a trajectory")
    if suffix == ".tum":
        return _from_tum(path)
    if suffix == ".csv":
        return _from_csv(path)
    raise InputError(f"{path}: a trajectory is a .csv, a .tum or LOG:TOPIC", _TRAJECTORY_HINT, param="external")


def _checked(path: str, stamps: list[float] | np.ndarray, a: np.ndarray, b: np.ndarray, local: bool,
             cov: np.ndarray | None = None) -> Trajectory:
    t = np.asarray(stamps, dtype=float)
    if len(t) < 2:
        raise InputError(f"{path}: fewer than 2 poses", _TRAJECTORY_HINT, param="external")
    bad = ~(np.isfinite(t) & np.isfinite(a) & np.isfinite(b))
    if not local:
        bad |= (np.abs(a) > 90) | (np.abs(b) > 180)
    else:
        bad |= (np.abs(a) > 2e6) | (np.abs(b) > 2e6)
    if bad.any():
        i = int(np.argmax(bad))
        what = ("east/north (m) beyond 2000 km of the local origin"
                if local else "latitude/longitude outside WGS84's range")
        raise InputError(f"{path}: pose {i + 1} (stamp {float(t[i])!r}): not finite, or {what}", _TRAJECTORY_HINT,
                         param="external")
    if cov is not None:
        _check_covariance(path, t, cov)
    order = np.argsort(t, kind="stable")
    t, a, b = t[order], a[order], b[order]
    cov = cov[order] if cov is not None else None
    repeated = np.diff(t) == 0
    if repeated.any():
        apart_m = np.hypot(np.diff(a), np.diff(b)) if local else np.hypot(*steps_en_m(a, b))
        conflict = repeated & (apart_m > SAME_POSE_M)
        if conflict.any():
            k = int(np.argmax(conflict))
            i, j = sorted((int(order[k]), int(order[k + 1])))
            raise InputError(f"{path}: poses {i + 1} and {j + 1} share the stamp {float(t[k])!r} s and lie "
                             f"{float(apart_m[k]):.4g} m apart",
                             "write one pose per stamp: two positions at one instant cannot both be the estimate",
                             param="external")
        log.warning("%s: %d pose(s) repeat the stamp and position of another; each is kept once", path,
                    int(repeated.sum()))
    keep = np.concatenate([[True], ~repeated])
    t, a, b = t[keep], a[keep], b[keep]
    cov = cov[keep] if cov is not None else None
    if local:
        return Trajectory(path, t, east_m=a, north_m=b, cov_en_m2=cov)
    return Trajectory(path, t, lat_deg=a, lon_deg=b, cov_en_m2=cov)


def _check_covariance(path: str, t: np.ndarray, cov: np.ndarray) -> None:
    """Refuse a pose covariance that is not finite or not positive semi-definite
    (:func:`~ionav_viz.core.covariance.covariance_faults`): a one-line error naming the first such pose."""
    faults = covariance_faults(cov)
    bad = np.logical_or.reduce(list(faults.values()))
    if bad.any():
        i = int(np.argmax(bad))
        fault = next(f for f, mask in faults.items() if mask[i])
        ee, en, nn = (float(x) for x in cov[i, (0, 0, 1), (0, 1, 1)])
        raise InputError(f"{path}: pose {i + 1} (stamp {float(t[i])!r}): covariance ee={ee!r}, en={en!r}, nn={nn!r} "
                         f"m^2 is {fault}",
                         _COVARIANCE_HINT, param="external")


def _from_csv(path: Path) -> Trajectory:
    try:
        with open(path, encoding="utf-8") as f:
            header = [h.strip() for h in f.readline().split(",")]
            have = [c for c in COVARIANCE_COLUMNS if c in header]
            if have and len(have) < len(COVARIANCE_COLUMNS):
                raise InputError(f"{path}: covariance column(s) "
                                 f"{', '.join(c for c in COVARIANCE_COLUMNS if c not in header)} missing beside "
                                 f"{', '.join(have)}",
                                 "give all three of " + ",".join(COVARIANCE_COLUMNS) + ", or none", param="external")
            cols = (0, 1, 2) + tuple(header.index(c) for c in have if header.index(c) > 2)
            # a header without rows: numpy's "input contained no data" warning on stderr
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                data = np.loadtxt(f, delimiter=",", ndmin=2, usecols=cols) if header else np.zeros((0, len(cols)))
    except InputError:
        raise
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not a trajectory CSV ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else ''})", _TRAJECTORY_HINT,
                         param="external") from None
    names = tuple(header[:3])
    if names not in (("time_s", "lat_deg", "lon_deg"), ("time_s", "east_m", "north_m")):
        raise InputError(f"{path}: header {','.join(header[:3])[:80]!r} is not time_s,lat_deg,lon_deg or "
                         "time_s,east_m,north_m", _TRAJECTORY_HINT, param="external")
    cov = covariance_en(data[:, 3], data[:, 4], data[:, 5]) if data.shape[1] == 6 else None
    return _checked(str(path), data[:, 0], data[:, 1], data[:, 2], names[1] == "east_m", cov)


def _from_tum(path: Path) -> Trajectory:
    rows = []
    try:
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, start=1):
                line = line.strip()
                if not line or line.startswith("#"):
                    continue
                cells = line.split()
                if len(cells) != 8:
                    raise InputError(f"{path}: line {n} has {len(cells)} values, TUM has 8 (t x y z qx qy qz qw)",
                                     _TRAJECTORY_HINT, param="external")
                rows.append([float(c) for c in cells[:3]])
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not a TUM trajectory ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else ''})", _TRAJECTORY_HINT,
                         param="external") from None
    data = np.asarray(rows, dtype=float).reshape(-1, 3)
    return _checked(str(path), data[:, 0], data[:, 1], data[:, 2], True)


def _from_log(path: Path, topic: str) -> Trajectory:
    from .load import open_message_log, source_kind
    from .message_log import GNSS_SCHEMAS, ODOMETRY_SCHEMAS, POSE_SCHEMAS, get_field, stamp_ns

    log = open_message_log(path, source_kind(path))
    if log is None:
        raise InputError(f"{path}: LOG:TOPIC needs an MCAP file or a ROS bag", _TRAJECTORY_HINT, param="external")
    found = [c for c in log.channels() if c.topic == topic]
    if not found:
        raise InputError(f"{path}: no topic {topic!r}", f"topics: {', '.join(c.topic for c in log.channels())}",
                         param="external")
    channel = found[0]
    fixes = channel.schema in GNSS_SCHEMAS[:2]
    if not fixes and channel.schema not in ODOMETRY_SCHEMAS + POSE_SCHEMAS:
        raise InputError(f"{path}: {topic} is a {channel.schema}", "give a NavSatFix, Odometry or PoseStamped topic",
                         param="external")
    t, a, b, cov = [], [], [], []
    try:
        for _, log_ns, msg in log.messages([channel]):
            try:
                ns = stamp_ns(get_field(msg, "header", "stamp"))
            except (KeyError, AttributeError, TypeError, ValueError):
                ns = 0
            stamp = (ns if ns > 0 else log_ns) * 1e-9
            if fixes:
                if int(get_field(msg, "status", "status")) < 0 or not math.isfinite(float(get_field(msg, "latitude"))):
                    continue
                t.append(stamp)
                a.append(float(get_field(msg, "latitude")))
                b.append(float(get_field(msg, "longitude")))
                cov.append(_fix_covariance(msg))
            else:
                pose = get_field(msg, "pose") if channel.schema in POSE_SCHEMAS[:2] else get_field(msg, "pose", "pose")
                t.append(stamp)
                a.append(float(get_field(pose, "position", "x")))
                b.append(float(get_field(pose, "position", "y")))
                cov.append(None if channel.schema in POSE_SCHEMAS[:2]
                           else _pose_covariance(get_field(msg, "pose", "covariance")))
    except InputError:
        raise
    except (KeyError, AttributeError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: topic {topic}: message lacks a field ({type(exc).__name__}: {exc})",
                         _TRAJECTORY_HINT, param="external") from None
    except Exception as exc:
        raise log.damaged(exc) from None
    return _checked(f"{path}:{topic}", t, np.asarray(a), np.asarray(b), not fixes, _log_covariance(cov))


def _fix_covariance(msg) -> tuple[float, float, float] | None:
    """A NavSatFix's east/north covariance (m^2), None when its type is unknown (0) or absent."""
    from .message_log import get_field

    try:
        if int(get_field(msg, "position_covariance_type")) <= 0:
            return None
        c = [float(v) for v in get_field(msg, "position_covariance")]
    except (KeyError, AttributeError, TypeError, ValueError):
        return None
    return (c[0], c[1], c[4]) if len(c) == 9 else None


def _pose_covariance(values) -> tuple[float, float, float] | None:
    """The x/y (east/north) block of a 6 x 6 row-major pose covariance (m^2), None when all zero or
    marked unknown (-1 first, ROS's convention)."""
    try:
        c = [float(v) for v in values]
    except (TypeError, ValueError):
        return None
    if len(c) != 36 or not any(c) or c[0] == -1.0:
        return None
    return (c[0], c[1], c[7])


def _log_covariance(entries: list) -> np.ndarray | None:
    """The poses' covariances, or None when no message carried one; a pose without one among poses
    with one is refused by the check as not finite (NaN)."""
    if all(e is None for e in entries):
        return None
    rows = np.array([e if e is not None else (np.nan, np.nan, np.nan) for e in entries], dtype=float).reshape(-1, 3)
    return covariance_en(rows[:, 0], rows[:, 1], rows[:, 2])
