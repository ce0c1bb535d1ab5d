"""Headless screenshots of ``.rrd`` recordings, for scenario reviews on machines without a display.

One private headless viewer (:mod:`ionav_viz.viz.viewer`) renders every requested image: for each
recording, read back what it holds (:mod:`ionav_viz.viz.recording_info`), then for each view at
each time or outage a change of blueprint, framing and titles (:mod:`ionav_viz.viz.blueprints`)
and a screenshot.

Views: ``all`` (the recording's review layout), ``outage`` (the inspector), ``map``, ``local``
(maximised single views), ``signals`` and ``errors`` (their columns of plots).
"""

from __future__ import annotations

import logging
import re
import socket
from collections.abc import Sequence
from pathlib import Path

from ..core.errors import InputError
from ..core.fileio import made_folders
from ..nav.registry import BASELINE
from .blueprints import VIEWS, Shot, focus_blueprint, framing, titles_for
from .recording_info import OutageInfo, RecordingInfo, read_recording_info
from .viewer import HeadlessViewer, RendererMissing

log = logging.getLogger("ionav_viz")

#: The map view's tile server (Rerun's default map style draws OpenStreetMap's tiles).
TILE_HOST, TILE_PORT = "tile.openstreetmap.org", 443


def map_tiles_reachable(host: str = TILE_HOST, port: int = TILE_PORT, timeout_s: float = 2.0) -> bool:
    """Whether the map's tile server accepts a connection (a TCP connect within ``timeout_s``):
    offline, the map view would be black, so screenshots draw the local metric view instead."""
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return True
    except OSError:
        return False

__all__ = ["RendererMissing", "check_size", "parse_size", "render", "resolve_time"]


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
    folder = None
    if out.suffix.lower() != ".png" or len(plans[0][2]) > 1 or len(infos) > 1:
        folder = out if out.suffix.lower() != ".png" else out.parent
    written: list[Path] = []
    with made_folders(folder), HeadlessViewer(*size, timeout_s=timeout_s) as viewer:
        tiles = map_tiles_reachable()  # once the viewer runs: a missing renderer is said first, alone
        if not tiles and any(v in ("map", "all") for v in views):
            log.warning("map tiles cannot load (%s is unreachable): screenshots draw the local east-north view in the map's place", TILE_HOST)
        for info, shots, paths in plans:
            viewer.open(info.path)
            for shot, path in zip(shots, paths):
                frame = framing(info, shot.outage, size, shot.view)
                try:
                    layout = focus_blueprint(viewer.base_blueprint, shot.view, titles_for(info, shot, size[0]), frame,
                                             t_s=shot.t_s, end_s=info.end_s, map_tiles=tiles)
                except InputError as exc:
                    raise InputError(f"{info.path}: {exc.message}", exc.hint) from None
                viewer.show(layout, shot.t_s, path)
                written.append(path)
                if progress:
                    progress(path)
    return written
