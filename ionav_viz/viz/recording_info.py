"""Reading a replay's recording back: its drive, outages (span, each estimator's final error, the
extent drawn for it) and estimators, from the ``.rrd`` alone (what screenshots frame and title)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.fileio import utf8_alias
from ..nav.registry import BASELINE
from . import entities as ent
from .style import GNSS_LABEL

#: The time plots whose lines a screenshot frames (its y axes): each an entity or a folder of them.
PLOT_ORIGINS = (ent.DISPLACEMENTS, ent.YAW_RATES, ent.ACCEL, *(ent.error_group(m) for m in ent.ERROR_METRICS))


@dataclass
class OutageInfo:
    """One outage of a recording, as drawn: where it is and how each estimator ended it.

    Attributes:
        number: 1-based, as in the recording's ``gnss/state`` ("outage 3 (20-30 s)").
        start_s, end_s: its span on the ``time`` timeline (s).
        final_error_m: per estimator name, the 2D position error at the outage's end (m).
        local_points: truth, every estimate and the outage's scale bar in the local view's screen
            frame (m), for framing.
        lat_deg, lon_deg: the same on the map.
    """

    number: int
    start_s: float
    end_s: float
    final_error_m: dict[str, float]
    local_points: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray

    @property
    def span(self) -> str:
        return f"{self.start_s:.0f}-{self.end_s:.0f} s"


@dataclass
class RecordingInfo:
    """What a screenshot needs to know about a recording, read from the ``.rrd`` itself."""

    path: Path
    drive: str
    end_s: float
    states: list[tuple[float, float, str]]  # (start s, end s, label) of every outage state, real ones too, and receiver losses
    outages: list[OutageInfo]
    lat_deg: np.ndarray  # the GNSS track
    lon_deg: np.ndarray
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)  # name -> (label, colour)
    truth_label: str = GNSS_LABEL  # what the green track is: the GNSS fixes, or a reference beside them
    plots: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)  # time plot origin -> (t s, value), every line
    ellipses: set[str] = field(default_factory=set)  # the estimators whose 95 % ellipses are drawn
    warned: bool = False  # whether the summary tab lists warnings (a line more)
    health: list[tuple[str, tuple[int, int, int]]] = field(default_factory=list)  # the filter-health lines (label, colour)

    def y_extent(self, origin: str, t0_s: float, t1_s: float) -> tuple[float, float] | None:
        """The least and greatest value the time plot ``origin`` draws between ``t0_s`` and
        ``t1_s`` (every line of it), or None when it draws nothing there."""
        t, v = self.plots.get(origin, (np.zeros(0), np.zeros(0)))
        inside = v[(t >= t0_s) & (t <= t1_s) & np.isfinite(v)]
        return (float(inside.min()), float(inside.max())) if len(inside) else None

    def state_at(self, t_s: float) -> str | None:
        """The ``gnss/state`` label at ``t_s`` other than GNSS: an outage (the one ending there, when
        one ends as the next starts) or a receiver's loss beside a reference; None with GNSS."""
        for start, end, label in self.states:
            if start <= t_s <= end + 1e-6:
                return label
        return None

    def outage(self, number: int) -> OutageInfo:
        if not 1 <= number <= len(self.outages):
            raise InputError(f"{self.path}: no outage {number} (the recording has {len(self.outages)})",
                             "choose an outage number from the replay's list, or worst", param="outages")
        return self.outages[number - 1]

    def worst(self, estimator: str = BASELINE) -> OutageInfo:
        """The outage with the largest final position error of ``estimator``."""
        if estimator not in self.estimators:
            raise InputError(f"{self.path}: no estimator {estimator!r} in the recording",
                             f"choose one of {', '.join(self.estimators) or 'none'}", param="worst_of")
        scored = [o for o in self.outages if np.isfinite(o.final_error_m.get(estimator, np.nan))]
        if not scored:
            raise InputError(f"{self.path}: 'worst' needs outages with {estimator} errors in the recording",
                             "replay with outages first", param="times")
        return max(scored, key=lambda o: o.final_error_m[estimator])


def _rows(batch, column: str) -> tuple[np.ndarray, np.ndarray]:
    """A list<list<[2]>> column as (points (N, 2), per-row offsets into them (rows+1))."""
    import pyarrow as pa

    col = batch.column(column)
    if isinstance(col, pa.ChunkedArray):
        col = col.combine_chunks()
    strips = col.flatten()
    row_off = np.asarray(col.offsets)
    strip_off = np.asarray(strips.offsets)
    pts = np.asarray(strips.flatten().flatten(), dtype=np.float64).reshape(-1, 2)
    return pts, strip_off[row_off] - strip_off[0]


def _times_of(batch) -> np.ndarray:
    return batch.column("time").cast("int64").to_numpy() / 1e9


def _last_in(times: np.ndarray, t0: float, t1: float) -> int | None:
    """Index of the last of the sorted ``times`` with t0 < time <= t1, or None."""
    k = int(np.searchsorted(times, t1 + 1e-6, side="right")) - 1
    return k if k >= 0 and times[k] > t0 else None


class _Rows:
    """Rows of one drawn entity: times and per-row points (strips joined), over all its chunks."""

    def __init__(self) -> None:
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._index: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def add(self, batch, column: str) -> None:
        self._parts.append((_times_of(batch), *_rows(batch, column)))
        self._index = None

    def last_in(self, t0: float, t1: float) -> np.ndarray:
        """Points of the last row with t0 < time <= t1 (empty if none)."""
        if self._index is None:  # every row in time order: (time, chunk, row in chunk)
            times = np.concatenate([t for t, _, _ in self._parts])
            chunk = np.concatenate([np.full(len(t), i) for i, (t, _, _) in enumerate(self._parts)])
            row = np.concatenate([np.arange(len(t)) for t, _, _ in self._parts])
            order = np.argsort(times, kind="stable")
            self._index = (times[order], chunk[order], row[order])
        times, chunk, row = self._index
        k = _last_in(times, t0, t1)
        if k is None:
            return np.zeros((0, 2))
        _, pts, off = self._parts[chunk[k]]
        return pts[off[row[k]]:off[row[k] + 1]]


def read_recording_info(path: Path) -> RecordingInfo:
    """Drive name, length, outages (span, final errors, drawn extent) and estimators of a ionav-viz recording."""
    with utf8_alias(path) as readable:
        return _read_recording_info(path, readable)


def _read_recording_info(path: Path, readable: Path) -> RecordingInfo:
    scan = _scan_chunks(path, _chunks(path, readable))
    if not scan.states:
        raise InputError(f"{path}: not an ionav-viz replay recording (no /{ent.GNSS_STATE})", "make one with 'ionav-viz replay DRIVE'")
    scan.states.sort()
    spans = []
    for i, (t, label) in enumerate(scan.states):
        if label != ent.GNSS_AVAILABLE_STATE:  # outages, and where a receiver beside a reference lost the sky
            nxt = scan.states[i + 1][0] if i + 1 < len(scan.states) else scan.end_s
            spans.append((float(t), float(nxt), label))
    outages = _outages(spans, scan.errors, scan.drawn)
    ll = np.concatenate(scan.track) if scan.track else np.zeros((0, 2))
    plots = {o: (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])) for o, parts in scan.plots.items()}
    return RecordingInfo(path, scan.drive, scan.end_s, spans, outages, ll[:, 0], ll[:, 1], scan.estimators, scan.truth_label, plots,
                         scan.ellipses, scan.warned, list(scan.health.values()))


def _unreadable(path: Path, exc: Exception) -> InputError:
    """The error for a file Rerun's reader cannot read (its errors are of various classes)."""
    return InputError(f"{path}: not a readable Rerun recording ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
                      "make one with 'ionav-viz replay DRIVE'")


def _chunks(path: Path, readable: Path):
    """The chunks of the recording at ``readable`` (``path`` as the user named it), as a stream."""
    import warnings

    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():  # a file without a footer (cut off, or an old one) is read by scanning
            warnings.simplefilter("ignore")
            reader = RrdReader(readable)
            recordings = reader.recordings()
    except Exception as exc:  # the reader raises various errors for files that are not .rrd
        raise _unreadable(path, exc) from None
    if not recordings:
        raise InputError(f"{path}: no recording inside", "make one with 'ionav-viz replay DRIVE'")
    try:
        return reader.stream()
    except Exception as exc:
        raise _unreadable(path, exc) from None


@dataclass
class _Scan:
    """What one pass over a recording's chunks collects."""

    drive: str
    end_s: float = 0.0
    states: list = field(default_factory=list)  # (time, GNSS state label)
    track: list[np.ndarray] = field(default_factory=list)  # the truth's positions (lat, lon), per chunk
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)  # label, colour
    truth_label: str = GNSS_LABEL
    plots: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)  # plot origin -> (t, value) per chunk
    errors: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)  # position error (t, m) per chunk
    drawn: dict[str, _Rows] = field(default_factory=dict)  # each outage frame's rows
    ellipses: set[str] = field(default_factory=set)
    warned: bool = False
    health: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)  # NIS line entity -> (label, colour)

    def add(self, path: Path, chunk, entity: str) -> None:
        """One chunk's share (``entity``: its path)."""
        batch = chunk.to_record_batch()
        names = batch.schema.names
        series = ent.parse_error_series(entity)
        if chunk.is_static and series is not None and series[0] == "position_error_m":
            self.estimators[series[1]] = _series_style(batch)
            return
        if chunk.is_static and entity.strip("/") == ent.displacement("gnss"):
            self.truth_label = _series_style(batch)[0] or self.truth_label
            return
        if entity == "/__properties":
            for n in names:
                if n.endswith(":name"):
                    values = [v for v in batch.column(n).to_pylist() if v]
                    self.drive = str(values[0][0] if isinstance(values[0], list) else values[0]) if values else self.drive
            return
        if chunk.is_static and entity.strip("/").startswith(ent.HEALTH + "/") and "/nis/" in entity:
            self.health[entity] = _series_style(batch)
            return
        if chunk.is_static and entity.strip("/") == ent.OVERVIEW:
            text = next((batch.column(n).to_pylist() for n in names if n.endswith(":text")), [])
            self.warned = any("warning(s)" in str(t) for t in text)
            return
        if chunk.is_static or "time" not in names:
            return
        parts = entity.strip("/").split("/")
        if len(parts) == 3 and parts[2] == "ellipse" and parts[0] in (ent.LOCAL, ent.INSPECT, ent.MAP):
            self.ellipses.add(parts[1])
        times = _times_of(batch)
        if len(times):
            self.end_s = max(self.end_s, float(times.max()))
        if entity.strip("/") == ent.GNSS_STATE:
            col = _column(path, entity, names, ":state")
            self.states += list(zip(times, (v[0] for v in batch.column(col).to_pylist())))
        elif entity.strip("/") == ent.truth_position(ent.MAP):
            col = _column(path, entity, names, ":positions")
            self.track.append(np.asarray(batch.column(col).flatten().flatten(), dtype=np.float64).reshape(-1, 2))
        if entity.strip("/").startswith(PLOT_ORIGINS):  # a time plot's line: its values frame the plot's y axis
            plot = next(o for o in PLOT_ORIGINS if entity.strip("/").startswith(o))
            values = np.asarray(batch.column(_column(path, entity, names, ":scalars")).flatten(), dtype=np.float64)
            self.plots.setdefault(plot, []).append((times, values))
            if series is not None and series[0] == "position_error_m":
                self.errors.setdefault(series[1], []).append((times, values))
        if ent.is_outage_frame(entity):
            col = _column(path, entity, names, ":strips", ":line_strings")
            self.drawn.setdefault(entity.strip("/"), _Rows()).add(batch, col)


def _scan_chunks(path: Path, chunks) -> _Scan:
    """Every chunk read into a :class:`_Scan`; a chunk laid out otherwise than ionav-viz logs it is
    an error naming its entity."""
    scan = _Scan(path.stem)
    entity = ""
    try:
        for chunk in chunks:
            entity = ""  # reading the next chunk: a file cut off fails here
            entity = str(chunk.entity_path)
            scan.add(path, chunk, entity)
    except InputError:
        raise
    except Exception as exc:  # values of other types or shapes than ionav-viz logs (pyarrow's errors are not one class)
        if not entity:
            raise _unreadable(path, exc) from None
        raise InputError(f"{path}: {entity} is not laid out as ionav-viz logs it ({type(exc).__name__}: {str(exc)[:120]})",
                         "replay the drive again with this version of ionav-viz") from None
    return scan


def _outages(spans: list[tuple[float, float, str]], errors: dict[str, list[tuple[np.ndarray, np.ndarray]]],
             drawn: dict[str, _Rows]) -> list[OutageInfo]:
    """Each synthetic outage of ``spans``: every estimator's final position error and the tracks
    drawn at its end (the log's own losses left out)."""
    finite = {}  # per estimator, its error samples in time order (without the NaN line breaks)
    for name, parts_ in errors.items():
        t, v = np.concatenate([p[0] for p in parts_]), np.concatenate([p[1] for p in parts_])
        order = np.argsort(t, kind="stable")
        keep = order[np.isfinite(v[order])]
        finite[name] = (t[keep], v[keep])
    outages = []
    for start, end, label in spans:
        if ent.parse_outage_state(label) is None:
            continue  # the log's own losses (ent.real_outage_state)
        final = {}
        for name, (t, v) in finite.items():
            k = _last_in(t, start, end)
            final[name] = float(v[k]) if k is not None else float("nan")
        local = [rows.last_in(start, end) for key, rows in drawn.items() if key.startswith(ent.LOCAL + "/")]
        geo = [rows.last_in(start, end) for key, rows in drawn.items() if key.startswith(ent.MAP + "/")]
        ll = np.concatenate(geo) if geo else np.zeros((0, 2))
        outages.append(OutageInfo(len(outages) + 1, start, end, final, np.concatenate(local) if local else np.zeros((0, 2)),
                                  ll[:, 0], ll[:, 1]))
    return outages


def _column(path: Path, entity: str, names: list[str], *suffixes: str) -> str:
    """The column of ``entity`` whose name ends in one of ``suffixes``; a recording without it was
    not written by this version of ionav-viz (or was crafted)."""
    found = next((n for n in names if n.endswith(suffixes)), None)
    if found is None:
        raise InputError(f"{path}: {entity} holds no {' or '.join(s.lstrip(':') for s in suffixes)} (it is logged as another type)",
                         "replay the drive again with this version of ionav-viz")
    return found


def _series_style(batch) -> tuple[str, tuple[int, int, int]]:
    """(label, RGB) of a static ``SeriesLines`` row."""
    label, rgb = "", (128, 128, 128)
    for n in batch.schema.names:
        values = batch.column(n).to_pylist()
        if not values or not values[0]:
            continue
        if n.endswith(":names"):
            label = str(values[0][0])
        elif n.endswith(":colors"):
            packed = int(values[0][0])  # 0xRRGGBBAA
            rgb = ((packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255)
    return label, rgb


def report_json(path: Path) -> str:
    """The report a recording carries (``report``: what ``evaluate --json`` prints), or an error
    saying the recording has none (made before it carried one)."""
    with utf8_alias(path) as readable:
        import warnings

        from rerun.chunk import RrdReader

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for chunk in RrdReader(readable).stream():
                    if str(chunk.entity_path).strip("/") != ent.REPORT:
                        continue
                    batch = chunk.to_record_batch()
                    column = next((n for n in batch.schema.names if n.endswith(":text")), None)
                    if column is not None:
                        values = batch.column(column).to_pylist()
                        if values and values[0]:
                            return str(values[0][0] if isinstance(values[0], list) else values[0])
        except Exception as exc:
            raise _unreadable(path, exc) from None
    raise InputError(f"{path}: the recording carries no report (made by an earlier ionav-viz?)", "replay the drive again, or give 'evaluate --json' output",
                     param="result")
