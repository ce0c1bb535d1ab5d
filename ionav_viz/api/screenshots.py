"""Headless screenshots of recordings (``ionav-viz screenshot``)."""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.errors import InputError
from ..core.fileio import check_output_file, check_regular_input, refuse_output_onto_input
from ..viz.screenshot import Shots

if TYPE_CHECKING:
    from ..viz.viewer import HeadlessViewer

log = logging.getLogger("ionav_viz")


def screenshot(
    recordings: Sequence[str | Path] | str | Path,
    output: str | Path,
    shots: Shots | None = None,
    *,
    timeout_s: float = 120.0,
    progress: Callable[[Path], None] | None = None,
) -> list[Path]:
    """Render PNG screenshots of recordings with a private headless Rerun viewer.

    Args:
        recordings: ``.rrd`` files written by :func:`replay`; a fleet overview (``evaluate --fleet-rrd``)
            is one image of its own layout, whatever ``shots`` asks.
        output: a ``.png`` for one image, else a directory (or a ``.png`` whose stem prefixes the names).
        shots: which views at which times and outages, and the image size (default :class:`Shots`:
            the whole review layout at the end, 1600x900).
        timeout_s: longest wait for the viewer to start or load a recording.
        progress: called with each image's path as it is written.

    Returns:
        the written PNG paths. Needs a Vulkan renderer (Mesa's lavapipe on machines without a GPU).
    """
    from ..viz.screenshot import check_size

    paths = [Path(recordings)] if isinstance(recordings, (str, Path)) else [Path(r) for r in recordings]
    if not paths:
        raise InputError("no recording to render", "give at least one .rrd made by replay")
    for rec in paths:
        check_regular_input(rec, "recordings", hint="give a .rrd made by 'ionav-viz replay DRIVE'", missing_ok=True)
        if not rec.is_file():
            raise InputError(f"{rec}: no such recording", "make one with 'ionav-viz replay DRIVE'")
    refuse_output_onto_input(output, paths)
    if shots is not None and not isinstance(shots, Shots):
        raise InputError(f"shots={shots!r} is not a Shots", "give shots=iv.Shots(...), or leave it out", param="shots")
    shots = shots if shots is not None else Shots()
    width, height = check_size(*(int(x) for x in shots.size))
    out = Path(output)
    single = (out.suffix.lower() == ".png" and len(paths) == 1
              and (len(shots.times) + len(shots.outages)) * len(shots.views) == 1)
    if single:
        check_output_file(out)
    elif out.suffix.lower() != ".png" and out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory", "several images go into a directory: name one",
                         param="output")
    folder = out if out.suffix.lower() != ".png" else out.parent
    existing = next((p for p in [folder, *folder.parents] if p.exists()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{out}: cannot write in {existing} (permission denied)", "choose a writable output directory",
                         param="output")
    from ..viz.viewer import HeadlessViewer

    # the viewer starts first: the recordings are read, and the images planned, while it starts and its
    # start-up toasts fade (a bad recording or option is still said first, and stops it)
    with HeadlessViewer(width, height, timeout_s=timeout_s, wait=False) as viewer:
        return _render(paths, out, single, folder, shots, (width, height), timeout_s, progress, viewer)


def _render(paths: list[Path], out: Path, single: bool, folder: Path, shots: Shots, size: tuple[int, int],
            timeout_s: float, progress: Callable[[Path], None] | None, viewer: HeadlessViewer) -> list[Path]:
    """:func:`screenshot`'s images, by the started ``viewer``: fleet overviews, then replays."""
    from ..viz.fleet import screenshot_fleet
    from ..viz.recording_info import is_fleet_recording
    from ..viz.screenshot import render

    fleets = [p for p in paths if is_fleet_recording(p)]
    if fleets and (tuple(shots.times) != ("end",) or tuple(shots.views) != ("all",) or shots.outages):
        log.warning("%s: a fleet overview is one image of its own layout: the times, views and outage numbers asked do "
                    "not apply to it",
                    ", ".join(str(p) for p in fleets))
    written = []
    # a fleet overview (evaluate --fleet-rrd): one image of its own layout, whatever the times and views
    for rec in fleets:
        png = out if single or (out.suffix.lower() == ".png" and len(paths) == 1) else folder / f"{rec.stem}.png"
        if png is not out:
            png.parent.mkdir(parents=True, exist_ok=True)
        written.append(screenshot_fleet(rec, png, size, timeout_s, viewer=viewer))
        if progress:
            progress(png)
    paths = [p for p in paths if p not in fleets]
    if not paths:
        return written
    return written + render(paths, out, replace(shots, size=size), timeout_s=timeout_s, progress=progress,
                            viewer=viewer)
