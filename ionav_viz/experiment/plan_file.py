"""An outage plan as a file (``OUT.outages.json``, written by ``ionav-viz outage-log``): the outages
an outaged log lacks its GNSS in, so that an estimate made on that log is scored on exactly them.

Times are the source's own stamps (:meth:`~ionav_viz.core.drive.Drive.stamp_s`: UNIX seconds for
message logs, the CSV's time of day for IO-VNBD). Outage ``k`` lasts from ``start_stamps_s[k]`` (its
last GNSS fix, the estimators' start state) to ``start_stamps_s[k] + outage_s`` (where it is
scored); the outaged log has no GNSS message stamped in ``(start, end]`` (a fix stamped within
:data:`~ionav_viz.sources.outage_writer.STAMP_TOL_S` after the start is the start fix, and stays).

The file is plain JSON (never a pickle), checked field by field when read.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.json_out import dumps_json, is_finite_number

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
        body["outages"] = [{"start_stamp_s": a, "end_stamp_s": a + self.outage_s, "start_s": b,
                            "end_s": b + self.outage_s}
                           for a, b in zip(self.start_stamps_s, self.start_s, strict=True)]
        del body["start_stamps_s"], body["start_s"]
        return dumps_json(body) + "\n"  # numpy values in the placement's options, NaN: plain JSON


#: A plan's limits: thousands of outages are a few hundred kilobytes, nested three levels deep.
PLAN_MAX_BYTES = 64 << 20
PLAN_MAX_DEPTH = 16
#: How far (s) a plan's numbers may disagree with each other (they are written with full precision).
PLAN_TOLERANCE_S = 1e-3
_PLAN_HINT = "give the OUT.outages.json that 'ionav-viz outage-log' wrote"


def read_plan(path: str | Path) -> PlanFile:
    """A plan file, checked; an error naming the file and the field (and the outage) otherwise.

    Read as bounded, strict JSON (:func:`~ionav_viz.core.fileio.read_json_bounded`: a regular
    file, no NaN or Infinity, no key twice). Every outage needs finite, non-negative
    ``start_stamp_s`` and ``start_s``; its ``end_stamp_s`` and ``end_s`` (when given) lie
    ``outage_s`` after them; the stamps and drive times keep one offset; outages come in order and
    none overlaps (or repeats) the one before."""
    from ..core.fileio import read_json_bounded

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise InputError(f"{path}: no such plan file", _PLAN_HINT, param="plan")
    body = read_json_bounded(path, param="plan", max_bytes=PLAN_MAX_BYTES, max_depth=PLAN_MAX_DEPTH, hint=_PLAN_HINT,
                             what="an outage plan")

    def bad(field: str, why: str) -> InputError:
        return InputError(f"{path}: field {field!r} {why}", _PLAN_HINT, param="plan")

    if not isinstance(body, dict) or body.get("format") != PLAN_FORMAT:
        raise bad("format", f"is not {PLAN_FORMAT!r}")
    version = body.get("version")
    if isinstance(version, bool) or version != PLAN_VERSION:
        raise bad("version", f"is {version!r}; this ionav-viz reads version {PLAN_VERSION}")
    for field, kind in (("source", str), ("source_sha256", str), ("drive", str), ("placement", str), ("clock", str),
                        ("placement_options", dict), ("outages", list)):
        if not isinstance(body.get(field), kind):
            raise bad(field, f"is missing or not a {kind.__name__}")
    outage_s = body.get("outage_s")
    if not is_finite_number(outage_s) or outage_s <= 0:
        raise bad("outage_s", "is not a positive number of seconds")
    if abs(outage_s - round(outage_s)) > 1e-9:
        raise bad("outage_s", f"({outage_s!r}) is not a whole number of seconds, as every outage is")
    if not body["outages"]:
        raise bad("outages", "holds no outage")
    starts, starts_s = [], []
    for i, o in enumerate(body["outages"]):
        def wrong(field: str, why: str, i: int = i) -> InputError:
            return InputError(f"{path}: outage {i + 1}: field {field!r} {why}", _PLAN_HINT, param="plan")

        if not isinstance(o, dict):
            raise wrong("outages", "is not an object with start_stamp_s, start_s, end_stamp_s and end_s")
        for field in ("start_stamp_s", "start_s", "end_stamp_s", "end_s"):
            if (field in o or field.startswith("start")) and not is_finite_number(o.get(field)):
                raise wrong(field,
                            f"is {'missing' if field not in o else repr(o[field])}, not a finite number of seconds")
        start, start_s = float(o["start_stamp_s"]), float(o["start_s"])
        for field, value in (("start_stamp_s", start), ("start_s", start_s)):
            if value < 0:
                raise wrong(field, f"is negative ({value!r} s)")
        for field, begin, label in (("end_stamp_s", start, "start_stamp_s"), ("end_s", start_s, "start_s")):
            if field not in o:
                continue
            end = float(o[field])
            if end <= begin:
                raise wrong(field,
                            f"({end!r} s) is not after its {label} ({begin!r} s): the outage ends before it starts")
            if abs(end - begin - outage_s) > PLAN_TOLERANCE_S:
                raise wrong(field,
                            f"({end!r} s) is {end - begin:.6g} s after its {label}, and the plan's outage_s is "
                            f"{outage_s!r} s")
        if starts and abs((start - start_s) - (starts[0] - starts_s[0])) > PLAN_TOLERANCE_S:
            raise wrong("start_stamp_s",
                        f"({start!r} s) and start_s ({start_s!r} s) disagree with outage 1's: the stamps are on "
                        "another clock")
        if starts:
            gap = start_s - starts_s[-1]
            if abs(gap) <= PLAN_TOLERANCE_S:
                raise wrong("start_s", f"({start_s!r} s) repeats outage {i}")
            if gap < 0:
                raise wrong("start_s", f"({start_s!r} s) is before outage {i}'s: outages are listed in time order")
            if gap < outage_s - PLAN_TOLERANCE_S:
                raise wrong("start_s",
                            f"({start_s!r} s) is inside outage {i} ({starts_s[-1]!r}-{starts_s[-1] + outage_s!r} s): "
                            "outages may not overlap")
        starts.append(start)
        starts_s.append(start_s)
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
        begin, end = ((float(drive.t_s[0]), float(drive.t_s[-1]))
                      if len(drive) else (0.0, 0.0))  # a --span keeps the drive's clock
        for i, t in enumerate(times):
            if t < begin - PLAN_TOLERANCE_S or t + plan.outage_s > end + PLAN_TOLERANCE_S:
                from ..core.units import stamp_unit_hint

                units = stamp_unit_hint(plan.start_stamps_s, float(drive.stamp_s(begin)), float(drive.stamp_s(end)))
                raise InputError(f"{self.path}: outage {i + 1}: field 'start_stamp_s' ({plan.start_stamps_s[i]!r} s) "
                                 f"puts it at {t:.3f}-{t + plan.outage_s:.3f} s, outside the drive {drive.name} "
                                 f"({begin:g}-{end:.3f} s)",
                                 units or "give the drive and reading options the plan was made with", param="plan")
        return Planned(times,
                       f"{len(times)} {plan.outage_s:g} s outages from {Path(self.path).name} ({plan.placement})",
                       str(self.path))
