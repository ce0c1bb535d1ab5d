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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import InputError, ToolFailure
from ..core.signals import STOP_SIGNALS, raise_terminated
from ..nav.estimators import short_label
from . import recording as rerun_log
from .style import color_word

VIEWS = ("all", "map", "local", "signals", "errors")
_ORIGINS = {"map": "map", "local": "local", "signals": "signals/displacement_m", "errors": "errors/crse_m"}


class RendererMissing(ToolFailure):
    """The headless viewer could not start or render (no GPU and no software renderer)."""


@dataclass
class RecordingInfo:
    """What a screenshot needs to know about a recording, read from the ``.rrd`` itself."""

    path: Path
    drive: str
    end_s: float
    outages: list[tuple[float, float, str]]  # (start s, end s, label)
    worst_s: float | None  # end of the outage with the largest INS position error
    lat_deg: np.ndarray  # the GNSS track
    lon_deg: np.ndarray
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = field(default_factory=dict)  # name -> (label, colour)

    def outage_at(self, t_s: float) -> str | None:
        for start, end, label in self.outages:
            if start <= t_s <= end + 1e-6:
                return label
        return None


def read_recording_info(path: Path) -> RecordingInfo:
    """Drive name, length, outages and the worst INS outage of a ionav-viz recording."""
    from rerun.chunk import RrdReader

    try:
        reader = RrdReader(path)
        recordings = reader.recordings()
    except Exception as exc:  # the reader raises various errors for files that are not .rrd
        raise InputError(f"{path}: not a readable Rerun recording ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
                         "make one with 'ionav-viz replay DRIVE'") from None
    if not recordings:
        raise InputError(f"{path}: no recording inside", "make one with 'ionav-viz replay DRIVE'")
    drive, end_s, states, errors, track = path.stem, 0.0, [], [], []
    estimators: dict[str, tuple[str, tuple[int, int, int]]] = {}
    for chunk in reader.stream():
        entity = str(chunk.entity_path)
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if chunk.is_static and entity.startswith("/errors/position_error_m/"):
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
        times = batch.column("time").cast("int64").to_numpy() / 1e9
        if len(times):
            end_s = max(end_s, float(times.max()))
        if entity == "/gnss/state":
            col = next(n for n in names if n.endswith(":state"))
            states += list(zip(times, (v[0] for v in batch.column(col).to_pylist())))
        elif entity == "/map/gnss/position":
            col = next(n for n in names if n.endswith(":positions"))
            track += [p[0] for p in batch.column(col).to_pylist()]
        elif entity == "/errors/position_error_m/ins":
            col = next(n for n in names if n.endswith(":scalars"))
            errors += [(t, v[0]) for t, v in zip(times, batch.column(col).to_pylist()) if v and v[0] == v[0]]  # no NaN breaks
    if not states:
        raise InputError(f"{path}: not an ionav-viz replay recording (no /gnss/state)", "make one with 'ionav-viz replay DRIVE'")
    states.sort()
    outages = []
    for i, (t, label) in enumerate(states):
        if label.startswith("outage"):
            nxt = states[i + 1][0] if i + 1 < len(states) else end_s
            outages.append((float(t), float(nxt), label))
    worst = max(errors, key=lambda r: r[1])[0] if errors else None
    ll = np.asarray(track, dtype=np.float64).reshape(-1, 2)
    return RecordingInfo(path, drive, end_s, outages, float(worst) if worst is not None else None, ll[:, 0], ll[:, 1], estimators)


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


def resolve_time(spec: str, info: RecordingInfo) -> float:
    """``'35s'``, ``'worst'`` or ``'end'`` -> seconds on the ``time`` timeline."""
    from ..core.durations import parse_duration_s

    key = spec.strip().lower()
    if key == "end":
        return info.end_s
    if key == "worst":
        if info.worst_s is None:
            raise InputError(f"{info.path}: time 'worst' needs INS errors in the recording", "replay with outages first", param="times")
        return info.worst_s
    if key in ("0", "0s"):
        return 0.0
    t = parse_duration_s(spec, "time")
    if t > info.end_s + 1e-6:
        raise InputError(f"time {spec}: after the end of the recording ({info.end_s:.1f} s)", "choose a time within the drive, 'worst' or 'end'", param="times")
    return t


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

    def open(self, path: Path, track_lat_deg=(), track_lon_deg=()) -> None:
        """Open a recording and wait until it is the active one (the track sets the map zoom)."""
        self.track_lat_deg, self.track_lon_deg = np.asarray(track_lat_deg), np.asarray(track_lon_deg)
        self.call("close", "all")
        self.call("open", str(path.resolve()))
        deadline = time.monotonic() + self.timeout_s
        while self.call("get_state").active_recording is None:
            if time.monotonic() > deadline:
                raise RendererMissing(f"the viewer did not load {path} within {self.timeout_s:.0f} s")
            time.sleep(0.1)

    def shot(self, view: str, t_s: float, titles: dict[str, str], out: Path) -> None:
        """Render ``view`` at ``t_s`` with view titles rewritten by origin, and save it to ``out``."""
        base = self.call("get_blueprint")
        zoom = rerun_log.map_zoom(self.track_lat_deg, self.track_lon_deg, 0.8 * self.height) if len(self.track_lat_deg) else None
        bp = focus_blueprint(base.blueprint, view, titles, zoom)
        self.call("set_blueprint", bp, of="recording")
        self.call("set_time", "time", duration=float(t_s), play_state="paused")
        time.sleep(0.4)  # let the viewer render a few frames at the new time
        from ..core.fileio import atomic_path

        with atomic_path(out, suffix=".tmp.png") as tmp:
            self.call("save_screenshot", str(tmp))
            if not tmp.is_file() or tmp.stat().st_size == 0:
                raise RendererMissing(f"the viewer wrote no screenshot for {out}")
        self.call("set_blueprint", base.blueprint, of="recording")

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


def focus_blueprint(blueprint: dict[str, Any], view: str, titles: dict[str, str], map_zoom: float | None = None) -> dict[str, Any]:
    """The recording's blueprint showing only ``view``, with view titles from ``titles`` (by origin)."""
    bp = {k: {a: dict(f) for a, f in v.items()} for k, v in blueprint.items()}
    views = {k: v["ViewBlueprint"] for k, v in bp.items() if "ViewBlueprint" in v}
    for vb in views.values():
        origin = vb.get("space_origin", "")
        if origin in titles:
            vb["display_name"] = titles[origin]
    if view == "all":
        return bp
    target = _ORIGINS[view]
    view_key = next((k for k, vb in views.items() if vb.get("space_origin") == target), None)
    if view_key is None:
        raise InputError(f"the recording has no {view} view", "replay it again with this version of ionav-viz")
    viewport = bp.setdefault("/viewport", {}).setdefault("ViewportBlueprint", {})
    if view in ("map", "local"):
        viewport["maximized"] = view_key.rsplit("/", 1)[-1]
        if view == "map" and map_zoom is not None:
            bp[view_key + "/MapZoom"] = {"MapZoom": {"zoom": map_zoom}}
    else:  # keep only the column of plots that holds the target view
        ref = "view/" + view_key.rsplit("/", 1)[-1]
        column = next(k for k, v in bp.items() if ref in v.get("ContainerBlueprint", {}).get("contents", []))
        root_key = "/container/" + viewport["root_container"]
        root = bp[root_key]["ContainerBlueprint"]
        for other in root["contents"]:
            if "/" + other != column:
                _drop(bp, "/" + other)
        root["contents"] = [column.lstrip("/")]
        for shares in ("col_shares", "row_shares"):
            root.pop(shares, None)
    return bp


def _drop(bp: dict[str, Any], key: str) -> None:
    """Remove a container or view and everything under it from a blueprint dict."""
    for child in bp.get(key, {}).get("ContainerBlueprint", {}).get("contents", []):
        _drop(bp, "/" + child)
    for k in [k for k in bp if k == key or k.startswith(key + "/")]:
        del bp[k]


def titles_for(info: RecordingInfo, t_s: float) -> dict[str, str]:
    """View titles that say drive, outage and time."""
    outage = info.outage_at(t_s)
    when = f"t = {t_s:.1f} s" + (f", {outage}" if outage else ", GNSS available")
    legend = ", ".join(["GNSS green"] + [f"{short_label(label)} {color_word(rgb)}" for _, (label, rgb) in sorted(info.estimators.items(), key=lambda kv: kv[0] != "ins")])
    return {
        "map": f"{info.drive}: map, {when} ({legend})",
        "local": f"{info.drive}: local east-north (m), north up, {when}",
        "signals/displacement_m": f"{info.drive}: displacement per second (m), {when}",
        "errors/position_error_m": f"{info.drive}: 2D position error (m), {when}",
    }


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


def time_label(spec: str, t_s: float) -> str:
    key = spec.strip().lower()
    return key if key in ("worst", "end") else f"{t_s:06.1f}s"


def render(recordings: list[Path], out: Path, times: list[str], views: list[str], size: tuple[int, int],
           timeout_s: float = 120.0, progress=None) -> list[Path]:
    """Render every (recording, time, view) combination with one headless viewer; returns the PNGs."""
    for view in views:
        if view not in VIEWS:
            raise InputError(f"view {view!r} is unknown", f"choose from {', '.join(VIEWS)}", param="views")
    infos = [read_recording_info(p) for p in recordings]
    plans = []
    for info in infos:
        resolved = [(spec, resolve_time(spec, info)) for spec in times]
        requests = [(view, spec, t) for spec, t in resolved for view in views]
        paths = output_paths(out, info.drive, [(v, time_label(s, t)) for v, s, t in requests], len(infos) == 1)
        plans.append((info, requests, paths))
    if out.suffix.lower() != ".png" or len(plans[0][2]) > 1 or len(infos) > 1:
        target_dir = out if out.suffix.lower() != ".png" else out.parent
        target_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with HeadlessViewer(*size, timeout_s=timeout_s) as viewer:
        for info, requests, paths in plans:
            viewer.open(info.path, info.lat_deg, info.lon_deg)
            for (view, _spec, t), path in zip(requests, paths):
                viewer.shot(view, t, titles_for(info, t), path)
                written.append(path)
                if progress:
                    progress(path)
    return written
