"""An outage plan as a file (``OUT.outages.json``, written by ``ionav-viz outage-log``): the outages
an outaged log lacks its GNSS in, so that an estimate made on that log is scored on exactly them.

Times are the source's own stamps (:meth:`~ionav_viz.core.drive.Drive.stamp_s`: UNIX seconds for
message logs, the CSV's time of day for IO-VNBD). Outage ``k`` lasts from ``start_stamps_s[k]`` (its
last GNSS fix, the estimators' start state) to ``start_stamps_s[k] + outage_s`` (where it is
scored); the outaged log has no GNSS message stamped in ``(start, end]``.

The file is plain JSON (never a pickle), checked field by field when read.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..core.errors import InputError

PLAN_FORMAT = "ionav-viz outage plan"
PLAN_VERSION = 1


@dataclass(frozen=True)
class PlanFile:
    """What ``OUT.outages.json`` holds.

    Attributes:
        source: the drive's source file (as given), ``source_sha256`` its checksum (:func:`checksum`).
        drive: the drive's name; ``outage_s``: the length of every outage (s).
        placement: the placement in words, ``placement_options``: its parameters.
        start_stamps_s: each outage's start, on the source's own clock (s); ``start_s`` the same in
            seconds since the drive's first sample.
        clock: what the stamps are (UNIX seconds, or IO-VNBD time of day).
        removed_topics: the GNSS topics (or columns) the outaged log lacks inside each outage.
    """

    source: str
    source_sha256: str
    drive: str
    outage_s: float
    placement: str
    placement_options: dict[str, Any]
    start_stamps_s: tuple[float, ...]
    start_s: tuple[float, ...]
    clock: str
    removed_topics: tuple[str, ...] = ()

    def to_json(self) -> str:
        body = {"format": PLAN_FORMAT, "version": PLAN_VERSION, **asdict(self)}
        body["outages"] = [{"start_stamp_s": a, "end_stamp_s": a + self.outage_s, "start_s": b, "end_s": b + self.outage_s}
                           for a, b in zip(self.start_stamps_s, self.start_s, strict=True)]
        del body["start_stamps_s"], body["start_s"]
        return json.dumps(body, indent=2) + "\n"


def read_plan(path: str | Path) -> PlanFile:
    """A plan file, checked; an error naming the file and the field otherwise."""
    path = Path(path)
    try:
        if path.stat().st_size > 64 << 20:
            raise InputError(f"{path}: {path.stat().st_size} bytes is too large for an outage plan", "give the OUT.outages.json outage-log wrote", param="plan")
        body = json.loads(path.read_bytes())
    except FileNotFoundError:
        raise InputError(f"{path}: no such plan file", "give the OUT.outages.json that 'ionav-viz outage-log' wrote", param="plan") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not an outage plan ({type(exc).__name__}: {str(exc).splitlines()[0]})",
                         "give the OUT.outages.json that 'ionav-viz outage-log' wrote", param="plan") from None

    def bad(field: str, why: str) -> InputError:
        return InputError(f"{path}: field {field!r} {why}", "give the OUT.outages.json that 'ionav-viz outage-log' wrote", param="plan")

    if not isinstance(body, dict) or body.get("format") != PLAN_FORMAT:
        raise bad("format", f"is not {PLAN_FORMAT!r}")
    if body.get("version") != PLAN_VERSION:
        raise bad("version", f"is {body.get('version')!r}; this ionav-viz reads version {PLAN_VERSION}")
    for field, kind in (("source", str), ("source_sha256", str), ("drive", str), ("placement", str), ("clock", str),
                        ("placement_options", dict), ("outages", list)):
        if not isinstance(body.get(field), kind):
            raise bad(field, f"is missing or not a {kind.__name__}")
    outage_s = body.get("outage_s")
    if isinstance(outage_s, bool) or not isinstance(outage_s, (int, float)) or not math.isfinite(outage_s) or outage_s <= 0:
        raise bad("outage_s", "is not a positive number of seconds")
    starts, starts_s = [], []
    for i, o in enumerate(body["outages"]):
        values = [o.get(k) if isinstance(o, dict) else None for k in ("start_stamp_s", "start_s")]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values):
            raise bad(f"outages[{i}]", "needs finite start_stamp_s and start_s (s)")
        starts.append(float(values[0]))
        starts_s.append(float(values[1]))
    removed = body.get("removed_topics", [])
    if not isinstance(removed, list) or not all(isinstance(t, str) for t in removed):
        raise bad("removed_topics", "is not a list of names")
    return PlanFile(body["source"], body["source_sha256"], body["drive"], float(outage_s), body["placement"],
                    body["placement_options"], tuple(starts), tuple(starts_s), body["clock"], tuple(removed))


def checksum(path: str | Path) -> str:
    """SHA-256 of a source: a file's bytes; for a folder (a ROS 2 bag, a KITTI drive) the names and
    sizes of its files (reading every camera image of a KITTI drive would take minutes)."""
    path = Path(path)
    digest = hashlib.sha256()
    if path.is_dir():
        for f in sorted(p for p in path.rglob("*") if p.is_file()):
            digest.update(f"{f.relative_to(path).as_posix()}\t{f.stat().st_size}\n".encode("utf-8", "surrogateescape"))
        return "dir:" + digest.hexdigest()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@dataclass(frozen=True)
class FromPlan:
    """A placement: exactly the outages of a plan file (``--plan``; ``plan=`` in the API). The plan
    is read and checked when this is made; :meth:`for_drive` checks it against the drive's source
    (the same checksum) and gives the :class:`~.outages.Planned` outages on the drive's own time."""

    path: str | Path
    event_types = ()  # the events the plan needs detected: none

    def __post_init__(self) -> None:
        object.__setattr__(self, "_plan", read_plan(self.path))

    @property
    def file(self) -> PlanFile:
        return self._plan  # type: ignore[attr-defined]

    def for_drive(self, drive: Any) -> Any:
        from .outages import Planned

        plan = self.file
        source = Path(drive.source)
        if source.exists() and checksum(source) != plan.source_sha256:
            raise InputError(f"{self.path}: the plan was made on another file than {source} (its checksum differs)",
                             f"give the drive the plan was made on ({plan.source})", param="plan")
        times = tuple(round(float(s - drive.stamp_s(0.0)), 6) for s in plan.start_stamps_s)
        return Planned(times, f"{len(times)} {plan.outage_s:g} s outages from {Path(self.path).name} ({plan.placement})", str(self.path))
