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
import socket
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import InputError
from ..core.fileio import made_folders, safe_stem
from ..experiment.registry import BASELINE
from .blueprints import (
    MIN_Y_SPAN,
    PLOT_MARGIN_S,
    TOP_BAND_PX,
    VIEWS,
    KeyEntry,
    Shot,
    ShotLayout,
    focus_blueprint,
    framing,
    key_for,
    plot_range,
    plot_window,
    shot_rows,
    shown_views,
    titles_for,
)
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

__all__ = ["RendererMissing", "check_size", "draw_key", "parse_size", "render", "resolve_time"]

#: The viewer keeps a band this high above the views where its top panel (hidden in screenshots)
#: would be: the frameless window's title bar, which no blueprint setting removes. Screenshots draw
#: their colour key into it (:func:`draw_key`), so it names every line instead of staying empty.
KEY_BAND_PX = TOP_BAND_PX
#: The viewer's background, and the key's text colour.
BACKGROUND_RGB, KEY_TEXT_RGB = (13, 13, 13), (225, 225, 225)


def key_head(shot: Shot) -> str:
    """What the key's values are, before its entries: the framed outage's final errors (the
    filter-health view's key names its lines only)."""
    return f"{shot.outage.name}, final error:" if shot.outage is not None and shot.view != "health" else ""


def band_height(img) -> int:
    """The rows of the empty band above the views (:data:`KEY_BAND_PX`, measured on the image: the
    first row below the top edge that is not the band's background)."""
    import numpy as np

    rows = np.asarray(img.convert("RGB"))[:, 1:-1].astype(int)
    for r in range(1, min(len(rows), 3 * KEY_BAND_PX)):
        if np.abs(rows[r] - np.array(BACKGROUND_RGB)).max() > 6:
            return r if r >= 16 else KEY_BAND_PX
    return KEY_BAND_PX


def draw_key(png: Path, keys: Sequence[KeyEntry], head: str = "") -> None:
    """Draw the colour key of ``keys`` (a short line or a dot in each colour, and its name) into the
    band above the views of the screenshot ``png``: one line, the type made smaller (down to 10 px)
    until it fits the width, else two lines."""
    from PIL import Image, ImageDraw, ImageFont

    img = Image.open(png).convert("RGB")
    band = band_height(img)
    draw = ImageDraw.Draw(img)
    draw.rectangle([1, 1, img.width - 2, band - 1], fill=BACKGROUND_RGB)

    def space(font) -> float:
        # the default font's space is 2 px at 10-11 px ("INS DR52.5 m" in a 1024 px image), 3 px from 12 px up
        return max(font.getlength(" "), 3.0)

    def length(font, text: str) -> float:
        words = text.split(" ")
        return sum(font.getlength(w) for w in words) + space(font) * (len(words) - 1)

    def write(xy: tuple[float, float], text: str, font) -> None:
        x, y = xy
        for word in text.split(" "):
            draw.text((x, y), word, fill=KEY_TEXT_RGB, font=font)
            x += font.getlength(word) + space(font)

    def widths(font) -> list[float]:
        swatch = font.size * 1.4
        return [swatch + 5 + length(font, k.text) + font.size for k in keys]

    def place(font, items: list[KeyEntry], y: float, x: float) -> None:
        swatch = font.size * 1.4
        mid = y + font.size * 0.55
        for k in items:
            if k.mark == "dot":
                r = font.size * 0.32
                draw.ellipse([x + swatch / 2 - r, mid - r, x + swatch / 2 + r, mid + r], fill=k.rgb)
            elif k.mark == "ellipse":
                rx, ry = swatch / 2, font.size * 0.4
                draw.ellipse([x, mid - ry, x + 2 * rx, mid + ry], outline=k.rgb, width=max(1, round(font.size / 8)))
            else:
                draw.line([x, mid, x + swatch, mid], fill=k.rgb, width=max(2, round(font.size / 5)))
            write((x + swatch + 5, y), k.text, font)
            x += swatch + 5 + length(font, k.text) + font.size

    room = img.width - 20
    for size in (14, 13, 12, 11, 10):
        font = ImageFont.load_default(size=size)
        head_w = length(font, head) + font.size if head else 0.0
        if head_w + sum(widths(font)) <= room:
            y = (band - font.size) / 2 - 1
            if head:
                write((10, y), head, font)
            place(font, list(keys), y, 10 + head_w)
            break
    else:  # two lines, the head on the first
        font = ImageFont.load_default(size=min(11, max(8, (band - 6) // 2 - 2)))
        head_w = length(font, head) + font.size if head else 0.0
        w = widths(font)
        # what fits the first line
        split = max(1, max((i for i in range(len(keys) + 1) if head_w + sum(w[:i]) <= room), default=1))
        line_h = (band - 4) / 2
        if head:
            write((10, 2), head, font)
        place(font, list(keys[:split]), 2, 10 + head_w)
        place(font, list(keys[split:]), 2 + line_h, 10)
    img.save(png, format="PNG")


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
    try:
        t = parse_duration_s(spec, "time", allow_zero=True)
    except InputError as exc:  # named --time on the command line, with what else it takes
        raise InputError(exc.message, "give a time into the drive (35s, 500ms, 1m), 'worst' or 'end'",
                         param="times") from None
    if t > info.end_s + 1e-6:
        raise InputError(f"time {spec}: after the end of the recording ({info.end_s:.1f} s)",
                         "choose a time within the drive, 'worst' or 'end'", param="times")
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
        raise InputError(f"image size {width}x{height}: width and height must be between 200 and 8192 pixels",
                         param="size")
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


@dataclass(frozen=True)
class Shots:
    """What a screenshot renders of each recording: every view at every time and outage
    (:func:`render`; the API's :func:`ionav_viz.api.screenshots.screenshot`).

    Attributes:
        times: seconds (float), ``"35s"``, ``"worst"`` or ``"end"``. ``"worst"`` is the end of the
            outage with the largest final position error of ``worst_of`` (default the INS DR), and
            frames that outage.
        views: ``all``, ``outage`` (the outage inspector), ``map``, ``local``, ``signals``, ``errors``.
        size: image width and height in pixels.
        outages: outage numbers (1-based, as the replay lists them): each is shown at its end, framed.
        worst_of: the estimator whose final error picks ``"worst"``.
    """

    times: Sequence[str | float] = ("end",)
    views: Sequence[str] = ("all",)
    size: tuple[int, int] = (1600, 900)
    outages: Sequence[int] = ()
    worst_of: str = BASELINE


def render(recordings: list[Path], out: Path, shots: Shots, *, timeout_s: float = 120.0, progress=None,
           viewer: HeadlessViewer | None = None) -> list[Path]:
    """Render every (recording, time or outage, view) combination of ``shots`` with one headless
    viewer; returns the PNGs. ``viewer``: a started viewer of ``shots.size`` to render with (else one
    is started and shut down here). Bad input is said before a missing renderer, and leaves neither
    a folder nor a viewer behind.
    """
    size = (int(shots.size[0]), int(shots.size[1]))
    if viewer is None:
        # started first: the recordings are read while it starts and its toasts fade
        with HeadlessViewer(*size, timeout_s=timeout_s, wait=False) as own:
            return render(recordings, out, shots, timeout_s=timeout_s, progress=progress, viewer=own)
    times = [f"{t:g}s" if isinstance(t, (int, float)) else str(t) for t in shots.times]
    views, outages, worst_of = list(shots.views), [int(n) for n in shots.outages], shots.worst_of
    for view in views:
        if view not in VIEWS:
            raise InputError(f"view {view!r} is unknown", f"choose from {', '.join(VIEWS)}", param="views")
    plans = []
    infos = [read_recording_info(p) for p in recordings]
    for info in infos:
        if "health" in views and not info.health:
            raise InputError(f"{info.path}: no filter health to show (no estimator of this run reports one)",
                             "the GNSS-aided filters (ekf, gins) do; or choose another --view", param="views")
        planned = []
        for spec in times:
            t, outage = resolve_time(spec, info, worst_of)
            key = spec.strip().lower()
            planned += [Shot(view, t, key if key in ("worst", "end") else f"{t:06.1f}s", outage) for view in views]
        for number in outages:
            o = info.outage(number)
            planned += [Shot(view, o.end_s, f"{'real-' if o.real else ''}outage{o.number}", o) for view in views]
        paths = output_paths(out, info.drive, [(s.view, s.label) for s in planned], len(infos) == 1)
        plans.append((info, planned, paths))
    folder = None
    if out.suffix.lower() != ".png" or len(plans[0][2]) > 1 or len(infos) > 1:
        folder = out if out.suffix.lower() != ".png" else out.parent
    written: list[Path] = []
    with made_folders(folder):
        viewer.ready()
        tiles = map_tiles_reachable()  # once the viewer runs: a missing renderer is said first, alone
        if not tiles and any(v in ("map", "all") for v in views):
            log.warning("map tiles cannot load (%s is unreachable): screenshots draw the local east-north view in "
                        "the map's place", TILE_HOST)
        for info, planned, paths in plans:
            viewer.open(info.path)
            for shot, path in zip(planned, paths):
                frame = framing(info, shot.outage, size, shot.view)
                x0, x1 = plot_window(shot.t_s, info.end_s)
                extents = {o: plot_range(o, *e, pad=False) for o in MIN_Y_SPAN
                           if (e := info.y_extent(o, x0 - PLOT_MARGIN_S, x1 + PLOT_MARGIN_S)) is not None}
                try:
                    layout = focus_blueprint(
                        viewer.base_blueprint, shot.view, titles_for(info, shot, size[0]), frame,
                        ShotLayout(shot.t_s, info.end_s, tiles, size, extents, len(info.estimators), info.warned,
                                   shown_views(info)))
                except InputError as exc:
                    raise InputError(f"{info.path}: {exc.message}", exc.hint) from None
                keys, head = key_for(info, shot, shot_rows(size).accel), key_head(shot)
                viewer.show(layout, shot.t_s, path, finish=lambda png, keys=keys, head=head: draw_key(png, keys, head))
                written.append(path)
                if progress:
                    progress(path)
    return written
