"""Headless screenshots of ``.rrd`` recordings, for scenario reviews on machines without a display.

A private Rerun viewer is started in headless mode (``rerun --headless --window-size WxH``) on a
free local port, driven through ``rerun.experimental.ViewerClient`` (open, set the time, change
the blueprint, save a screenshot), and always shut down afterwards, also on Ctrl-C. Its own
output (including the failed OpenStreetMap tile downloads of an offline map view) goes to a log
file, never to the user's terminal. On a machine without a GPU, Mesa's lavapipe Vulkan driver
(Debian package ``mesa-vulkan-drivers``) renders on the CPU; without any renderer the viewer
cannot start and :class:`RendererMissing` says so.

Views: ``all`` (the recording's review layout), ``map``, ``local`` (maximised single views),
``signals`` and ``errors`` (their columns of plots). View titles are rewritten to say drive,
outage and time.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import InputError, ToolFailure
from ..core.signals import STOP_SIGNALS, raise_terminated
from ..nav.protocol import short_label
from ..nav.registry import BASELINE
from . import recording as rerun_log
from .geometry import padded_bounds
from .style import color_word

VIEWS = ("all", "outage", "map", "local", "signals", "errors")
_ORIGINS = {"outage": "inspect", "map": "map", "local": "local", "signals": "signals/displacement_m", "errors": "errors/position_error_m"}


class RendererMissing(ToolFailure):
    """The headless viewer could not start or render (no GPU and no software renderer)."""


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
    states: list[tuple[float, float, str]]  # (start s, end s, label) of every outage state, real ones too
    outages: list[OutageInfo]
    lat_deg: np.ndarray  # the GNSS track
    lon_deg: np.ndarray
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)  # name -> (label, colour)

    def state_at(self, t_s: float) -> str | None:
        """The outage label at ``t_s`` (the one ending there, when one ends as the next starts)."""
        for start, end, label in self.states:
            if start <= t_s <= end + 1e-6:
                return label
        return None

    def outage(self, number: int) -> OutageInfo:
        if not 1 <= number <= len(self.outages):
            raise InputError(f"{self.path}: no outage {number} (the recording has {len(self.outages)})",
                             "choose an outage number from the replay's list, or --time worst", param="outages")
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
    from rerun.chunk import RrdReader

    try:
        reader = RrdReader(path)
        recordings = reader.recordings()
    except Exception as exc:  # the reader raises various errors for files that are not .rrd
        raise InputError(f"{path}: not a readable Rerun recording ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
                         "make one with 'ionav-viz replay DRIVE'") from None
    if not recordings:
        raise InputError(f"{path}: no recording inside", "make one with 'ionav-viz replay DRIVE'")
    drive, end_s, states, track = path.stem, 0.0, [], []
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = {}
    errors: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    drawn: dict[str, _Rows] = {}
    for chunk in reader.stream():
        entity = str(chunk.entity_path)
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if chunk.is_static and entity.startswith("/errors/position_error_m/") and entity.count("/") == 3:
            estimators[entity.rsplit("/", 1)[-1]] = _series_style(batch)
            continue
        if entity == "/__properties":
            for n in names:
                if n.endswith(":name"):
                    values = [v for v in batch.column(n).to_pylist() if v]
                    drive = str(values[0][0] if isinstance(values[0], list) else values[0]) if values else drive
            continue
        if chunk.is_static or "time" not in names:
            continue
        times = _times_of(batch)
        if len(times):
            end_s = max(end_s, float(times.max()))
        parts = entity.strip("/").split("/")
        if entity == "/gnss/state":
            col = next(n for n in names if n.endswith(":state"))
            states += list(zip(times, (v[0] for v in batch.column(col).to_pylist())))
        elif entity == "/map/gnss/position":
            col = next(n for n in names if n.endswith(":positions"))
            track.append(np.asarray(batch.column(col).flatten().flatten(), dtype=np.float64).reshape(-1, 2))
        elif parts[:2] == ["errors", "position_error_m"] and len(parts) == 3:
            col = next(n for n in names if n.endswith(":scalars"))
            errors.setdefault(parts[2], []).append((times, np.asarray(batch.column(col).flatten(), dtype=np.float64)))
        elif parts[0] in ("local", "map") and (parts[1:] in (["gnss", "outage"], ["scale"]) or (len(parts) == 3 and parts[2] == "live")):
            col = next(n for n in names if n.endswith(":strips") or n.endswith(":line_strings"))
            drawn.setdefault("/".join(parts), _Rows()).add(batch, col)
    if not states:
        raise InputError(f"{path}: not an ionav-viz replay recording (no /gnss/state)", "make one with 'ionav-viz replay DRIVE'")
    states.sort()
    spans = []
    for i, (t, label) in enumerate(states):
        if "outage" in label:
            nxt = states[i + 1][0] if i + 1 < len(states) else end_s
            spans.append((float(t), float(nxt), label))
    finite = {}  # per estimator, its error samples in time order (without the NaN line breaks)
    for name, parts_ in errors.items():
        t, v = np.concatenate([p[0] for p in parts_]), np.concatenate([p[1] for p in parts_])
        order = np.argsort(t, kind="stable")
        keep = order[np.isfinite(v[order])]
        finite[name] = (t[keep], v[keep])
    outages = []
    for start, end, label in spans:
        if not label.startswith("outage"):
            continue  # the log's own losses are labelled "real GNSS outage N"
        final = {}
        for name, (t, v) in finite.items():
            k = _last_in(t, start, end)
            final[name] = float(v[k]) if k is not None else float("nan")
        local = [rows.last_in(start, end) for key, rows in drawn.items() if key.startswith("local/")]
        geo = [rows.last_in(start, end) for key, rows in drawn.items() if key.startswith("map/")]
        ll = np.concatenate(geo) if geo else np.zeros((0, 2))
        outages.append(OutageInfo(len(outages) + 1, start, end, final, np.concatenate(local) if local else np.zeros((0, 2)),
                                  ll[:, 0], ll[:, 1]))
    ll = np.concatenate(track) if track else np.zeros((0, 2))
    return RecordingInfo(path, drive, end_s, spans, outages, ll[:, 0], ll[:, 1], estimators)


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


@dataclass
class Shot:
    """One image to render: a view at a time, framed on an outage or not."""

    view: str
    t_s: float
    label: str  # for the file name: 'worst', 'end', 'outage12', '0035.0s'
    outage: OutageInfo | None = None


def resolve_time(spec: str, info: RecordingInfo, worst_of: str = BASELINE) -> tuple[float, OutageInfo | None]:
    """``'35s'``, ``'worst'`` or ``'end'`` -> seconds on the ``time`` timeline, and the outage it
    frames (``'worst'``: the end of the outage with the largest final error of ``worst_of``)."""
    from ..core.durations import parse_duration_s

    key = spec.strip().lower()
    if key == "end":
        return info.end_s, None
    if key == "worst":
        worst = info.worst(worst_of)
        return worst.end_s, worst
    if key in ("0", "0s"):
        return 0.0, None
    t = parse_duration_s(spec, "time")
    if t > info.end_s + 1e-6:
        raise InputError(f"time {spec}: after the end of the recording ({info.end_s:.1f} s)", "choose a time within the drive, 'worst' or 'end'", param="times")
    return t, None


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rerun_executable() -> str:
    beside = Path(sys.executable).parent / "rerun"
    if beside.is_file():
        return str(beside)
    found = shutil.which("rerun")
    if found is None:
        raise RendererMissing("the 'rerun' viewer executable is not installed (it comes with rerun-sdk)")
    return found


class HeadlessViewer:
    """A private headless Rerun viewer process; use as a context manager (always shut down)."""

    #: Seconds to let the viewer draw after a change of blueprint and time, before the screenshot.
    settle_s = 0.4

    def __init__(self, width: int, height: int, timeout_s: float = 60.0) -> None:
        self.width, self.height, self.timeout_s = width, height, timeout_s
        self._dir = tempfile.TemporaryDirectory(prefix="ionav-viewer-")
        self.log_path = Path(self._dir.name) / "viewer.log"
        self.proc: subprocess.Popen | None = None
        self.client: Any = None
        self._old_handlers: dict[int, Any] = {}

    def __enter__(self) -> HeadlessViewer:
        from rerun.experimental import ViewerClient

        # SIGTERM and SIGHUP become an exception too (as Ctrl-C is), so __exit__ always runs.
        for sig in STOP_SIGNALS:
            with contextlib.suppress(ValueError):  # not the main thread
                self._old_handlers[sig] = signal.signal(sig, raise_terminated)
        try:
            self._start(ViewerClient)
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        return self

    def _start(self, client_cls) -> None:
        for _attempt in range(3):  # another process may grab the free port first
            port = free_port()
            with open(self.log_path, "ab") as log:
                self.proc = subprocess.Popen(
                    [_rerun_executable(), "--headless", "--port", str(port), "--window-size", f"{self.width}x{self.height}",
                     "--hide-welcome-screen", "--memory-limit", "25%"],
                    stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True,
                    # TMPDIR: the viewer's own scratch folders go into ours and are removed with it
                    env={**os.environ, "RERUN_APP_ONLY": "true", "RUST_LOG": os.environ.get("RUST_LOG", "warn"),
                         "TMPDIR": self._dir.name},
                )
            url = f"rerun+http://127.0.0.1:{port}/proxy"
            deadline = time.monotonic() + min(30.0, self.timeout_s)
            while time.monotonic() < deadline:
                if self.proc.poll() is not None:
                    break
                try:
                    self.client = client_cls.connect(url)
                    self.client.get_state()
                    return
                except Exception:
                    time.sleep(0.2)
            if self.proc.poll() is None:
                self._stop()
                raise RendererMissing(f"the headless Rerun viewer did not answer within {min(30.0, self.timeout_s):.0f} s")
            if "Address already in use" not in self._log_tail():
                self._raise_dead()
        self._raise_dead()

    def _log_tail(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")[-20000:]
        except OSError:
            return ""

    def _raise_dead(self) -> None:
        text = self._log_tail()
        lines = [line for line in text.splitlines() if "panicked" in line or "adapter" in line.lower() or "Error" in line]
        why = lines[0].strip() if lines else f"exit code {self.proc.returncode if self.proc else '?'}"
        raise RendererMissing(
            f"the headless Rerun viewer could not render ({why[:200]}); on a machine without a GPU install "
            "Mesa's software Vulkan driver: apt-get install mesa-vulkan-drivers"
        )

    def call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """A ViewerClient call; a dead viewer becomes :class:`RendererMissing`."""
        try:
            return getattr(self.client, method)(*args, **kwargs)
        except (KeyboardInterrupt, SystemExit):
            raise
        except Exception as exc:
            if self.proc is not None and self.proc.poll() is not None:
                self._raise_dead()
            raise RendererMissing(f"the headless Rerun viewer failed during {method}: {str(exc).splitlines()[0][:200]}") from None

    def open(self, path: Path) -> None:
        """Open a recording and wait until it is the active one."""
        self.call("close", "all")
        self.call("open", str(path.resolve()))
        deadline = time.monotonic() + self.timeout_s
        while self.call("get_state").active_recording is None:
            if time.monotonic() > deadline:
                raise RendererMissing(f"the viewer did not load {path} within {self.timeout_s:.0f} s")
            time.sleep(0.1)
        # every image starts from the recording's own layout (shots change titles, framing, maximised view)
        self.base_blueprint = self.call("get_blueprint").blueprint

    def shot(self, shot: Shot, info: RecordingInfo, out: Path) -> None:
        """Render ``shot`` (a view at a time, framed on its outage if any) and save it to ``out``."""
        frame = framing(info, shot.outage, (self.width, self.height), shot.view)
        bp = focus_blueprint(self.base_blueprint, shot.view, titles_for(info, shot, self.width), frame)
        self.call("set_blueprint", bp, of="recording")
        self.call("set_time", "time", duration=float(shot.t_s), play_state="paused")
        time.sleep(self.settle_s)  # let the viewer render a few frames at the new time
        from ..core.fileio import atomic_path

        with atomic_path(out, suffix=".tmp.png") as tmp:
            self.call("save_screenshot", str(tmp))
            if not tmp.is_file() or tmp.stat().st_size == 0:
                raise RendererMissing(f"the viewer wrote no screenshot for {out}")

    def _stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
                self.proc.wait(timeout=5)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                try:
                    os.killpg(self.proc.pid, signal.SIGKILL)
                    self.proc.wait(timeout=5)
                except (ProcessLookupError, subprocess.TimeoutExpired):
                    pass

    def __exit__(self, *exc: Any) -> None:
        self._stop()
        for sig, old in self._old_handlers.items():
            signal.signal(sig, old)
        self._old_handlers = {}
        self._dir.cleanup()


@dataclass
class Framing:
    """Where the map and local views look for one image: the whole drive, or one outage."""

    map_zoom: float | None = None
    local_bounds: tuple[float, float, float, float] | None = None  # x_min, x_max, y_min, y_max (m)
    map_entities: list[str] = field(default_factory=list)  # the map's contents when framed on an outage


def framing(info: RecordingInfo, outage: OutageInfo | None, size: tuple[int, int], view: str) -> Framing:
    """The whole drive (map zoom from the GNSS track), or ``outage``: its truth and estimated tracks
    with a margin, in the local view's bounds and on the map (only that outage's tracks and the
    GNSS track just around it, so the map centres on them)."""
    width, height = size
    # the map's side in pixels: the whole image maximised, else its tile of the review layout
    map_px = min(width, height) if view == "map" else min(COLUMN_FRACTION["map"] * width, 0.4 * height * 0.85)
    if outage is None:
        zoom = rerun_log.map_zoom(info.lat_deg, info.lon_deg, 0.8 * map_px) if len(info.lat_deg) else None
        return Framing(zoom)
    zoom = rerun_log.map_zoom(outage.lat_deg, outage.lon_deg, 0.6 * map_px) if len(outage.lat_deg) else None
    bounds = padded_bounds(outage.local_points, margin=0.12) if len(outage.local_points) else None
    entities = ["map/gnss/outage", "map/gnss/context", *(f"map/{name}/live" for name in info.estimators)]
    return Framing(zoom, bounds, entities)


def focus_blueprint(blueprint: dict[str, Any], view: str, titles: dict[str, str], frame: Framing | None = None) -> dict[str, Any]:
    """The recording's blueprint showing only ``view``, with view titles from ``titles`` (by
    origin) and the map and local views framed as ``frame`` says."""
    frame = frame or Framing()
    bp = {k: {a: dict(f) for a, f in v.items()} for k, v in blueprint.items()}
    views = {k: v["ViewBlueprint"] for k, v in bp.items() if "ViewBlueprint" in v}
    for key, vb in views.items():
        origin = vb.get("space_origin", "")
        if origin in titles:
            vb["display_name"] = titles[origin]
        if origin == "map" and frame.map_zoom is not None:
            bp[key + "/MapZoom"] = {"MapZoom": {"zoom": frame.map_zoom}}
        if origin == "map" and frame.map_entities:
            bp[key + "/ViewContents"] = {"ViewContents": {"query": [f"+ /{e}" for e in frame.map_entities]}}
        if origin == "local" and frame.local_bounds is not None and view in ("local", "map"):
            x0, x1, y0, y1 = frame.local_bounds
            bp[key + "/VisualBounds2D"] = {"VisualBounds2D": {"range": {"x_range": [x0, x1], "y_range": [y0, y1]}}}
            bp[key + "/ViewContents"] = {"ViewContents": {"query": rerun_log.LOCAL_FRAMED_CONTENTS}}
    if view == "all":
        return bp
    target = _ORIGINS[view]
    view_key = next((k for k, vb in views.items() if vb.get("space_origin") == target), None)
    if view_key is None:
        raise InputError(f"the recording has no {view} view", "replay it again with this version of ionav-viz")
    viewport = bp.setdefault("/viewport", {}).setdefault("ViewportBlueprint", {})
    if view in ("map", "local", "outage"):
        viewport["maximized"] = view_key.rsplit("/", 1)[-1]
    else:  # keep only the column of plots that holds the target view
        # the viewer writes container contents as "view/<id>" or "/view/<id>"
        ref = "view/" + view_key.rsplit("/", 1)[-1]
        column = next(k for k, v in bp.items() if ref in [c.lstrip("/") for c in v.get("ContainerBlueprint", {}).get("contents", [])])
        root_key = "/container/" + viewport["root_container"].rsplit("/", 1)[-1]
        root = bp[root_key]["ContainerBlueprint"]
        for other in root["contents"]:
            if "/" + other.lstrip("/") != column:
                _drop(bp, "/" + other.lstrip("/"))
        root["contents"] = [column.lstrip("/")]
        for shares in ("col_shares", "row_shares"):
            root.pop(shares, None)
    return bp


def _drop(bp: dict[str, Any], key: str) -> None:
    """Remove a container or view and everything under it from a blueprint dict."""
    for child in bp.get(key, {}).get("ContainerBlueprint", {}).get("contents", []):
        _drop(bp, "/" + child.lstrip("/"))
    for k in [k for k in bp if k == key or k.startswith(key + "/")]:
        del bp[k]


#: Pixels per character of a view title, and what the title bar's icons take (measured on renders).
TITLE_PX_PER_CHAR = 6.3
TITLE_ICONS_PX = 110
#: Widths of the review layout's columns (``recording.blueprint``'s column shares 4:3:3).
COLUMN_FRACTION = {"inspect": 0.4, "local": 0.2, "map": 0.2, "/": 0.3, "signals/displacement_m": 0.3, "errors/position_error_m": 0.3}


def _fit(variants: list[str], width_px: float) -> str:
    """The first (longest) title variant that fits ``width_px``, else the last."""
    budget = (width_px - TITLE_ICONS_PX) / TITLE_PX_PER_CHAR
    return next((v for v in variants if len(v) <= budget), variants[-1])


def titles_for(info: RecordingInfo, shot: Shot, width_px: int) -> dict[str, str]:
    """View titles that say drive, outage and time, and each estimator's final error on the framed
    outage; shortened to fit each view's width (the maximised view has the whole image)."""
    ests = sorted(info.estimators.items(), key=lambda kv: (kv[0] != BASELINE, kv[1][0]))  # as the plot legends
    legend = ", ".join(["GNSS green"] + [f"{short_label(label)} {color_word(rgb)}" for _, (label, rgb) in ests])
    o = shot.outage
    state = info.state_at(shot.t_s)
    when = f"t = {shot.t_s:.1f} s" + (f", {state}" if state else ", GNSS available")
    if o is not None:
        errs = [(short_label(label), name, o.final_error_m.get(name, float("nan"))) for name, (label, _rgb) in ests]
        long_err = ", ".join(f"{lab} ({color_word(info.estimators[n][1])}) {e:.1f} m" for lab, n, e in errs)
        mid_err = ", ".join(f"{lab} {e:.1f} m" for lab, _n, e in errs)
        short_err = ", ".join(f"{n} {e:.1f}" for _lab, n, e in errs)
        head = f"outage {o.number} ({o.span})"
        focus = [f"{head}, final error: {long_err}", f"{head}, final error: {mid_err}", f"{head}, final error (m): {short_err}",
                 f"#{o.number} {o.span}, final: {short_err} m", f"outage {o.number}, final (m): {short_err}"]
    else:
        focus = [when]
    full = width_px if shot.view != "all" else None
    def w(origin: str) -> float:
        return full or width_px * COLUMN_FRACTION.get(origin, 0.3)
    inspected = o or _outage_before(info, shot.t_s)
    inspect_head = f"outage {inspected.number} ({inspected.span})" if inspected else "no outage yet"
    titles = {
        "inspect": _fit([f"{info.drive}: {f}; m from the start fix, north up" for f in focus] + focus, w("inspect")) if o else
        _fit([f"{info.drive}: {inspect_head}, t = {shot.t_s:.1f} s; m from its start fix, north up",
              f"{inspect_head}, t = {shot.t_s:.1f} s; m from its start fix", inspect_head], w("inspect")),
        "map": _fit(([f"{info.drive}: map, {when} ({legend})"] if o is None else []) + [f"{info.drive}: map, {f}" for f in focus]
                    + ["Map" + (f", outage {o.number}" if o else "")], w("map")),
        "local": _fit([f"{info.drive}: local east-north (m), north up, {f}" for f in focus]
                      + [f"{info.drive}: east-north (m), {f}" for f in focus] + ["Drive: east-north (m)"], w("local")),
        "/": _fit([f"{info.drive}, {when}", f"{info.drive}, t = {shot.t_s:.1f} s", f"t = {shot.t_s:.1f} s"], w("/")),
        "signals/displacement_m": _fit([f"{info.drive}: displacement per second (m), {when}", "Displacement per second (m)"],
                                       w("signals/displacement_m")),
        "errors/position_error_m": _fit([f"{info.drive}: 2D position error (m), {when}", "2D position error (m)"],
                                        w("errors/position_error_m")),
    }
    return titles


def _outage_before(info: RecordingInfo, t_s: float) -> OutageInfo | None:
    """The outage the inspector shows at ``t_s``: the one under way, else the last one before."""
    started = [o for o in info.outages if o.start_s + rerun_log.OUTAGE_EPS_S <= t_s + 1e-9]
    return started[-1] if started else None


def parse_size(text: str) -> tuple[int, int]:
    """``'1600x900'`` -> (1600, 900)."""
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise InputError(f"image size {text!r}: expected WIDTHxHEIGHT, e.g. 1600x900", param="size") from None
    return check_size(w, h)


def check_size(width: int, height: int) -> tuple[int, int]:
    """An image size the viewer can render: 200 to 8192 pixels each way."""
    if not (200 <= width <= 8192 and 200 <= height <= 8192):
        raise InputError(f"image size {width}x{height}: width and height must be between 200 and 8192 pixels", param="size")
    return width, height


def output_paths(out: Path, stem: str, requests: list[tuple[str, str]], single_file_ok: bool) -> list[Path]:
    """Where each (view, time label) image goes: ``out`` itself for one image to a ``.png`` path,
    else ``<dir>/<stem>-<view>-<time>.png`` (``out`` a directory, or a ``.png`` whose stem is used)."""
    if out.suffix.lower() == ".png":
        if len(requests) == 1 and single_file_ok:
            return [out]
        directory, stem = out.parent, out.stem
    else:
        directory = out
    return [directory / f"{safe_stem(stem)}-{view}-{label}.png" for view, label in requests]


def safe_stem(name: str) -> str:
    """A file-name stem from text that comes from inside a file (a recording's drive name): only
    letters, digits, '.', '-' and '_', no leading dot, never a path."""
    cleaned = "".join(c if c.isascii() and (c.isalnum() or c in "._-") else "_" for c in name)
    cleaned = re.sub(r"\.{2,}", ".", cleaned).lstrip(".")
    return cleaned[:100] or "recording"


def render(recordings: list[Path], out: Path, times: list[str], views: list[str], size: tuple[int, int],
           timeout_s: float = 120.0, progress=None, outages: Sequence[int] = (), worst_of: str = BASELINE) -> list[Path]:
    """Render every (recording, time or outage, view) combination with one headless viewer; returns the PNGs.

    ``times``: ``'35s'``, ``'end'`` or ``'worst'`` (the outage with the largest final position error
    of ``worst_of``, framed); ``outages``: outage numbers, each framed and shown at its end.
    """
    for view in views:
        if view not in VIEWS:
            raise InputError(f"view {view!r} is unknown", f"choose from {', '.join(VIEWS)}", param="views")
    plans = []
    infos = [read_recording_info(p) for p in recordings]
    for info in infos:
        shots = []
        for spec in times:
            t, outage = resolve_time(spec, info, worst_of)
            key = spec.strip().lower()
            shots += [Shot(view, t, key if key in ("worst", "end") else f"{t:06.1f}s", outage) for view in views]
        for number in outages:
            o = info.outage(int(number))
            shots += [Shot(view, o.end_s, f"outage{o.number}", o) for view in views]
        paths = output_paths(out, info.drive, [(s.view, s.label) for s in shots], len(infos) == 1)
        plans.append((info, shots, paths))
    if out.suffix.lower() != ".png" or len(plans[0][2]) > 1 or len(infos) > 1:
        target_dir = out if out.suffix.lower() != ".png" else out.parent
        target_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with HeadlessViewer(*size, timeout_s=timeout_s) as viewer:
        for info, shots, paths in plans:
            viewer.open(info.path)
            for shot, path in zip(shots, paths):
                viewer.shot(shot, info, path)
                written.append(path)
                if progress:
                    progress(path)
    return written
