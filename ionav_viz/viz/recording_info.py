"""Reading a replay's recording back: its drive, outages (span, each estimator's final error, the
extent drawn for it) and estimators, from the ``.rrd`` alone (what screenshots frame and title)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.fileio import utf8_alias
from ..experiment.registry import BASELINE
from . import entities as ent
from .style import GNSS_LABEL

#: The time plots whose lines a screenshot frames (its y axes): each an entity or a folder of them.
PLOT_ORIGINS = (ent.DISPLACEMENTS, ent.YAW_RATES, ent.ACCEL, *(ent.error_group(m) for m in ent.ERROR_METRICS))


@dataclass
class OutageInfo:
    """One outage of a recording, as drawn: where it is and how each estimator ended it.

    Attributes:
        number: 1-based, as in the recording's ``gnss/state`` ("outage 3 (20-30 s)", or for one of
            the log's own losses "real GNSS outage 2 (118.0-132.7 s)").
        start_s, end_s: its span on the ``time`` timeline (s).
        final_error_m: per estimator name, the 2D position error at the outage's end (m).
        local_points: truth, every estimate and the outage's scale bar in the local view's screen
            frame (m), for framing.
        lat_deg, lon_deg: the same on the map.
        real: one of the log's own GNSS losses (``replay --on gnss-outage``), not a synthetic outage.
        label: its ``gnss/state`` label (a real loss's span is from its last to its first good fix).
    """

    number: int
    start_s: float
    end_s: float
    final_error_m: dict[str, float]
    local_points: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    real: bool = False
    label: str = ""

    @property
    def span(self) -> str:
        return f"{self.start_s:.0f}-{self.end_s:.0f} s"

    @property
    def name(self) -> str:
        """``outage 3`` or ``real GNSS outage 2``."""
        return f"real GNSS outage {self.number}" if self.real else f"outage {self.number}"

    @property
    def head(self) -> str:
        """Its name and span: ``outage 3 (20-30 s)``, ``real GNSS outage 2 (118.0-132.7 s)``."""
        return self.label if self.real and self.label else f"{self.name} ({self.span})"


@dataclass
class RecordingInfo:
    """What a screenshot needs to know about a recording, read from the ``.rrd`` itself."""

    path: Path
    drive: str
    end_s: float
    # (start s, end s, label) of every outage state, real ones too, and receiver losses
    states: list[tuple[float, float, str]]
    outages: list[OutageInfo]  # the synthetic outages
    lat_deg: np.ndarray  # the GNSS track
    lon_deg: np.ndarray
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)  # name -> (label, colour)
    truth_label: str = GNSS_LABEL  # what the green track is: the GNSS fixes, or a reference beside them
    # time plot origin -> (t s, value), every line
    plots: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    ellipses: set[str] = field(default_factory=set)  # the estimators whose 95 % ellipses are drawn
    warned: bool = False  # whether the summary tab lists warnings (a line more)
    # the filter-health lines (label, colour)
    health: list[tuple[str, tuple[int, int, int]]] = field(default_factory=list)
    # the log's own GNSS losses, bridged (replay --on gnss-outage)
    real_outages: list[OutageInfo] = field(default_factory=list)
    receiver: bool = False  # whether the receiver's own fixes are drawn beside a reference (--truth-topic)

    @property
    def framed(self) -> list[OutageInfo]:
        """The outages a screenshot frames by number or as the worst: the synthetic ones; in a
        recording through the log's own losses alone, those."""
        return self.outages or self.real_outages

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
        """Outage ``number`` (1-based) of :attr:`framed`: a synthetic one, or in a recording through
        the log's own losses alone, real GNSS outage ``number``."""
        kind = "outage" if self.outages or not self.real_outages else "real GNSS outage"
        if not 1 <= number <= len(self.framed):
            raise InputError(f"{self.path}: no {kind} {number} (the recording has {len(self.framed)})",
                             "choose an outage number from the replay's list, or worst", param="outages")
        return self.framed[number - 1]

    def worst(self, estimator: str = BASELINE) -> OutageInfo:
        """The outage of :attr:`framed` with the largest final position error of ``estimator``."""
        if estimator not in self.estimators:
            raise InputError(f"{self.path}: no estimator {estimator!r} in the recording",
                             f"choose one of {', '.join(self.estimators) or 'none'}", param="worst_of")
        scored = [o for o in self.framed if np.isfinite(o.final_error_m.get(estimator, np.nan))]
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
        raise InputError(f"{path}: not an ionav-viz replay recording (no /{ent.GNSS_STATE})",
                         "make one with 'ionav-viz replay DRIVE'")
    scan.states.sort()
    spans = []
    for i, (t, label) in enumerate(scan.states):
        if label != ent.GNSS_AVAILABLE_STATE:  # outages, and where a receiver beside a reference lost the sky
            nxt = scan.states[i + 1][0] if i + 1 < len(scan.states) else scan.end_s
            spans.append((float(t), float(nxt), label))
    outages = _outages(spans, scan.errors, scan.drawn)
    ll = np.concatenate(scan.track) if scan.track else np.zeros((0, 2))
    plots = {o: (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))
             for o, parts in scan.plots.items()}
    return RecordingInfo(path, scan.drive, scan.end_s, spans, outages, ll[:, 0], ll[:, 1], scan.estimators,
                         scan.truth_label, plots, scan.ellipses, scan.warned, list(scan.health.values()),
                         _real_outages(spans, scan), scan.receiver)


def _unreadable(path: Path, exc: Exception) -> InputError:
    """The error for a file Rerun's reader cannot read (its errors are of various classes)."""
    return InputError(f"{path}: not a readable Rerun recording "
                      f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
                      "make one with 'ionav-viz replay DRIVE'")


def rrd_reader(readable: Path):
    """Rerun's reader (``rerun.chunk.RrdReader``) of the ``.rrd`` at ``readable``, Rerun's own
    Python warnings silenced: a file without a footer (cut off, or an old one) is read by scanning,
    with a RerunWarning and its source line printed above our one-line error, which says what is
    wrong with the file. Every recording ionav-viz reads is opened here. (Rerun's native log is
    off unless ``-v`` or ``--debug``: ``RUST_LOG``, :func:`ionav_viz.cli.app._setup_logging`.)"""
    import warnings

    from rerun.chunk import RrdReader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return RrdReader(readable)


def _chunks(path: Path, readable: Path):
    """The chunks of the recording at ``readable`` (``path`` as the user named it), as a stream."""
    import warnings

    try:
        with warnings.catch_warnings():  # a file without a footer (cut off, or an old one) is read by scanning
            warnings.simplefilter("ignore")
            reader = rrd_reader(readable)
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
    # plot origin -> (t, value) per chunk
    plots: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)
    # position error (t, m) per chunk
    errors: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)
    drawn: dict[str, _Rows] = field(default_factory=dict)  # each outage frame's rows
    ellipses: set[str] = field(default_factory=set)
    warned: bool = False
    # NIS line entity -> (label, colour)
    health: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)
    # real losses' final errors (t, m)
    real_errors: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)
    # (view, est) -> a track per real loss
    real_tracks: dict[tuple[str, str], list[np.ndarray]] = field(default_factory=dict)
    end_fixes: dict[str, np.ndarray] = field(default_factory=dict)  # view -> the first good fix after each real loss
    receiver: bool = False

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
        if entity.strip("/") == ent.receiver(ent.LOCAL):
            self.receiver = True
            return
        if entity == "/__properties":
            for n in names:
                if n.endswith(":name"):
                    values = [v for v in batch.column(n).to_pylist() if v]
                    self.drive = (str(values[0][0] if isinstance(values[0], list) else values[0])
                                  if values else self.drive)
            return
        if chunk.is_static and entity.strip("/").startswith(ent.HEALTH + "/") and "/nis/" in entity:
            self.health[entity] = _series_style(batch)
            return
        if chunk.is_static and entity.strip("/") == ent.OVERVIEW:
            text = next((batch.column(n).to_pylist() for n in names if n.endswith(":text")), [])
            self.warned = any("warning(s)" in str(t) for t in text)
            return
        parts = entity.strip("/").split("/")
        if chunk.is_static and len(parts) == 3 and parts[0] in (ent.LOCAL, ent.MAP):
            if entity.strip("/") == ent.real_outage_tracks(parts[0], parts[1]):
                self.real_tracks[(parts[0], parts[1])] = _strips(
                    batch, _column(path, entity, names, ":strips", ":line_strings"))
            elif entity.strip("/") == ent.end_fixes(parts[0]):
                self.end_fixes[parts[0]] = np.asarray(
                    batch.column(_column(path, entity, names, ":positions")).flatten().flatten(),
                    dtype=np.float64).reshape(-1, 2)
            return
        if chunk.is_static or "time" not in names:
            return
        if len(parts) == 3 and parts[2] == "ellipse" and parts[0] in (ent.LOCAL, ent.INSPECT, ent.MAP):
            self.ellipses.add(parts[1])
        times = _times_of(batch)
        if entity.strip("/") in (ent.GNSS_STATE, ent.GNSS_QUALITY, ent.EVENTS_STATE):
            # a lane's empty states end it at the drive's end, and pad the recording to its ruler's end: not data
            values = [v[0] if v else None for v in batch.column(_column(path, entity, names, ":state")).to_pylist()]
            kept = [i for i, v in enumerate(values) if v is not None]
            times, values = times[kept], [values[i] for i in kept]
        if len(times):
            self.end_s = max(self.end_s, float(times.max()))
        if entity.strip("/") == ent.GNSS_STATE:
            # a state shared by several spans has a value per span (its times): the state is what is read
            self.states += list(zip(times, (ent.base_state(v) for v in values)))
        elif entity.strip("/") == ent.truth_position(ent.MAP):
            col = _column(path, entity, names, ":positions")
            self.track.append(np.asarray(batch.column(col).flatten().flatten(), dtype=np.float64).reshape(-1, 2))
        if entity.strip("/").startswith(PLOT_ORIGINS):  # a time plot's line: its values frame the plot's y axis
            plot = next(o for o in PLOT_ORIGINS if entity.strip("/").startswith(o))
            values = np.asarray(batch.column(_column(path, entity, names, ":scalars")).flatten(), dtype=np.float64)
            self.plots.setdefault(plot, []).append((times, values))
            if series is not None and series[0] == "position_error_m":
                self.errors.setdefault(series[1], []).append((times, values))
            elif len(parts) == 4 and entity.strip("/") == ent.real_outage_errors(parts[3]):
                self.real_errors.setdefault(parts[3], []).append((times, values))
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
        raise InputError(f"{path}: {entity} is not laid out as ionav-viz logs it ({type(exc).__name__}: "
                         f"{str(exc)[:120]})",
                         "replay the drive again with this version of ionav-viz") from None
    return scan


def _outages(spans: list[tuple[float, float, str]], errors: dict[str, list[tuple[np.ndarray, np.ndarray]]],
             drawn: dict[str, _Rows]) -> list[OutageInfo]:
    """Each synthetic outage of ``spans``: every estimator's final position error and the tracks
    drawn at its end (the log's own losses left out)."""
    finite = {name: _in_time_order(parts_) for name, parts_ in errors.items()}
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
        outages.append(OutageInfo(len(outages) + 1, start, end, final,
                                  np.concatenate(local) if local else np.zeros((0, 2)), ll[:, 0], ll[:, 1]))
    return outages


def _real_outages(spans: list[tuple[float, float, str]], scan: _Scan) -> list[OutageInfo]:
    """Each of the log's own GNSS losses of ``spans`` (``replay --on gnss-outage``): every
    estimator's final position error and its track through the loss, with the first good fix after it."""
    finite = {name: _in_time_order(parts_) for name, parts_ in scan.real_errors.items()}
    outages = []
    for start, end, label in spans:
        number = ent.parse_real_outage_state(label)
        if number is None or (outages and outages[-1].number == number):
            continue
        final = {}
        for name, (t, v) in finite.items():
            k = _last_in(t, start, end)
            final[name] = float(v[k]) if k is not None else float("nan")
        drawn = {}
        for view in (ent.LOCAL, ent.MAP):
            tracks = [strips[number - 1] for (v, _), strips in scan.real_tracks.items() if v == view and
                      len(strips) >= number]
            ends = scan.end_fixes.get(view, np.zeros((0, 2)))
            bar = [rows.last_in(start, end) for key, rows in scan.drawn.items() if key == ent.LOCAL_SCALE and
                   view == ent.LOCAL]
            drawn[view] = np.concatenate([*tracks, ends[number - 1 : number], *bar, np.zeros((0, 2))])
        outages.append(OutageInfo(number, start, end, final, drawn[ent.LOCAL], drawn[ent.MAP][:, 0],
                                  drawn[ent.MAP][:, 1], real=True, label=label))
    return outages


def _in_time_order(parts_: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """A series' (t, value) chunks joined in time order, without its NaN line breaks."""
    t, v = np.concatenate([p[0] for p in parts_]), np.concatenate([p[1] for p in parts_])
    order = np.argsort(t, kind="stable")
    keep = order[np.isfinite(v[order])]
    return t[keep], v[keep]


def _strips(batch, column: str) -> list[np.ndarray]:
    """The strips of a static list<list<[2]>> column's last row, each ``(n_i, 2)``."""
    import pyarrow as pa

    col = batch.column(column)

    if isinstance(col, pa.ChunkedArray):
        col = col.combine_chunks()
    row = col[len(col) - 1].values  # the row's strips
    off = np.asarray(row.offsets)
    flat = np.asarray(row.flatten().flatten(), dtype=np.float64).reshape(-1, 2)
    return [flat[off[i] - off[0]:off[i + 1] - off[0]] for i in range(len(off) - 1)]


def _column(path: Path, entity: str, names: list[str], *suffixes: str) -> str:
    """The column of ``entity`` whose name ends in one of ``suffixes``; a recording without it was
    not written by this version of ionav-viz (or was crafted)."""
    found = next((n for n in names if n.endswith(suffixes)), None)
    if found is None:
        raise InputError(f"{path}: {entity} holds no {' or '.join(s.lstrip(':') for s in suffixes)} (it is logged as "
                         "another type)",
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

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for chunk in rrd_reader(readable).stream():
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
    if is_fleet_recording(path):
        raise InputError(f"{path}: a fleet overview (evaluate --fleet-rrd), which carries no report for the figures",
                         "figures takes the fleet's report instead: 'ionav-viz evaluate DRIVES --json > fleet.json', "
                         "then 'figures fleet.json'",
                         param="result")
    raise InputError(f"{path}: the recording carries no report (made by an earlier ionav-viz?)",
                     "replay the drive again, or give 'evaluate --json' output", param="result")


#: How a fleet overview's recording id starts (a replay's is its drive's name and outage length;
#: :mod:`ionav_viz.viz.fleet` writes it).
FLEET_ID_PREFIX = "fleet overview: "


def is_fleet_recording(path: Path) -> bool:
    """Whether the ``.rrd`` at ``path`` is a fleet overview (False for anything else, unreadable included)."""
    try:
        with utf8_alias(Path(path)) as readable:
            return any(str(r.recording_id).startswith(FLEET_ID_PREFIX) for r in rrd_reader(readable).recordings())
    except Exception:  # not a recording: the replay screenshot's checks say why
        return False
