"""Results in the forms other tools read (``--export DIR``): a per-outage metrics table, tracks for
evo, and tracks for GIS tools.

Files written into ``DIR`` (each atomically, an existing one of the same name replaced; a drive's ``tum`` folder
replaced as a whole):

* ``outages.csv``: one row per outage and estimator, every metric, units in the column names.
* ``tum/<drive>/outage-NNN-<estimator>.tum`` and ``outage-NNN-truth.tum``: each outage's estimated
  track and the truth in evo's TUM format (``timestamp x y z qx qy qz qw``), one pose per second
  from the outage's start to its end. Timestamps are the source's own clock (UNIX seconds for
  message logs, the time of day for IO-VNBD; :meth:`~ionav_viz.core.drive.Drive.stamp_s`); x east and y
  north in metres on the azimuthal equidistant plane about the drive's first trustworthy GNSS fix (the local
  frame ``--external`` reads too), z 0; the orientation is the course (yaw about up, from east,
  counter-clockwise). ``evo_ape tum outage-001-truth.tum outage-001-ins.tum`` reads them as they are.
* ``real_outages.csv``, with ``--on gnss-outage``: one row per loss of the log's own GNSS and
  estimator, its span and the final error from the last good fix to the first after it.
* ``tracks.geojson`` (RFC 7946, WGS84 longitude/latitude): each drive's truth (a MultiLineString
  of its trustworthy fixes, broken where it has none: a receiver without a fix writes (0, 0) or
  freezes) and every outage's estimated tracks as LineStrings with their drive, outage, estimator
  and final error, the log's own losses' too (``kind`` ``real-outage``); each feature styled as
  simplestyle-spec 1.1 has it (``stroke``, ``stroke-width``, ``stroke-opacity``, ``marker-color``,
  ``title``), in the colours the recording draws them.
* ``tracks.gpx`` (GPX 1.1): the same tracks, one ``trk`` each (the truth's stretches as its
  ``trkseg`` s), for Google Earth, QGIS or a phone; each ``trkpt`` has its ``time`` in UTC (ISO 8601,
  ms) from the drive's clock (:func:`gpx_times`).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from ..core.drive import drive_labels
from ..core.errors import InputError
from ..core.fileio import write_failure
from ..core.geo import local_en_m
from ..core.json_out import dumps_json
from ..nav.kalman import CHI2_2_95
from .consistency import outage_nees
from .metrics import METRICS

#: The columns of ``outages.csv``: keys, then every metric (their names carry their units).
#: ``final_nees`` and ``final_inside_95``: for an estimator that gives a position covariance, its
#: final error's NEES (2 degrees of freedom) and whether it lies inside the 95 % ellipse (:mod:`.consistency`).
#: ``in_training``: 1 when the outage lies in data the IDNN's model (or its parent) was trained on
#: (same file by sha256, overlapping time), 0 when not, empty when no IDNN ran.
OUTAGE_COLUMNS = ("drive", "outage", "start_s", "end_s", "start_stamp_s", "estimator", "label", "gnss_distance_m",
                  *METRICS, "final_nees", "final_inside_95", "in_training")
#: The columns of ``real_outages.csv`` (``--on gnss-outage``): each loss of the log's own GNSS,
#: bridged from its last good fix (``gap_start_s``) and scored at the first good one after it
#: (``gap_end_s``); the estimators ran on the windows from ``outage_start_s`` for ``outage_s``.
REAL_OUTAGE_COLUMNS = ("drive", "outage", "gap_start_s", "gap_end_s", "gap_s", "outage_start_s", "outage_s", "span_m",
                       "estimator", "label", "final_position_error_m")


#: A clock whose first stamp is this far past 1970-01-01 (s) is UNIX time, dated: a time of day,
#: even run past midnight, never gets there.
DATED_AFTER_S = 2 * 86400.0


def export_results(results: list[Any], folder: str | Path, *, colors: dict[str, tuple[int, int, int]],
                   truth_color: tuple[int, int, int]) -> list[Path]:
    """Write the exports of ``results`` (:class:`~ionav_viz.analysis.evaluate.DriveResult` s of one
    report) into ``folder`` (made when missing, with its parents). Returns the files written.
    ``colors``: RGB per estimator name, ``truth_color`` the truth's, for the tracks' styles.

    Everything is written into a hidden folder inside ``folder`` first and moved in when complete,
    with stop signals held (each file renamed over its old version, each drive's ``tum/<drive>``
    swapped whole): a full disk or a signal part-way left ``outages.csv`` without the tracks, and a
    new export folder made but empty. Now ``folder`` is as it was, and a folder made here removed."""
    from ..core.fileio import check_output_folder, made_folders, staging_folder

    folder = check_output_folder(Path(folder), param="export")
    with made_folders(folder), staging_folder(folder / "export", folder,
                                              refused=lambda exc: _failure(folder, exc)) as stage:
        files, drives = _write_all(results, stage, folder, {**colors, None: truth_color})
        _move_in(stage, folder, files, drives)
    return [folder / f for f in files] + [folder / "tum" / d / f for d, names in drives.items() for f in names]


def _failure(target: Path, exc: OSError) -> Exception:
    return write_failure(target, exc) or InputError(f"{target}: cannot write the export "
                                                    f"({exc.strerror or type(exc).__name__})",
                                                    "choose a writable folder", param="export")


def _write_all(results: list[Any], stage: Path, folder: Path,
               colors: dict[Any, tuple[int, int, int]]) -> tuple[list[str], dict[str, list[str]]]:
    """Every export file of ``results`` into ``stage``: the top-level files' names, and each drive's TUM files."""
    drives: dict[str, list[str]] = {}
    features, gpx_tracks = [], []
    name = "outages.csv"
    labels = drive_labels([r.drive for r in results])  # two drives of one name (a/V-x.csv, b/V-x.csv): by their files
    try:
        (stage / name).write_bytes(_outages_csv(results, labels).encode())
        for res, label in zip(results, labels):
            if len(res.starts):
                name = f"tum/{_safe(label)}"
                (stage / name).mkdir(parents=True)
                drives[_safe(label)] = _tum_files(res, stage / name)
            f, g = _tracks(res, label, colors)
            features += f
            gpx_tracks += g
        real = any(res.bridged for res in results)
        if real:
            name = "real_outages.csv"
            (stage / name).write_bytes(_real_outages_csv(results, labels).encode())
        name = "tracks.geojson"
        (stage / name).write_bytes(dumps_json({"type": "FeatureCollection", "features": features},
                                              indent=None).encode())
        name = "tracks.gpx"
        (stage / name).write_bytes(_gpx(gpx_tracks).encode())
    except OSError as exc:
        raise _failure(folder / name, exc) from None
    return ["outages.csv", *(["real_outages.csv"] if real else []), "tracks.geojson", "tracks.gpx"], drives


def _move_in(stage: Path, folder: Path, files: list[str], drives: dict[str, list[str]]) -> None:
    """Move the staged files and each drive's ``tum/<drive>`` into ``folder``, with stop signals
    held (staged by ``open`` and ``mkdir``: the usual permissions already)."""
    import os

    from ..core.fileio import swap_in_directory
    from ..core.signals import hold_signals

    release = hold_signals()
    try:
        for name in files:
            if (folder / name).exists() and not (folder / name).is_file():
                raise InputError(f"{folder / name}: exists and is not a regular file",
                                 "ionav-viz only ever replaces regular files; choose another folder",
                                 param="export")
        if drives:
            (folder / "tum").mkdir(exist_ok=True)
        for name in files:
            os.replace(stage / name, folder / name)
        for drive in drives:
            swap_in_directory(stage / "tum" / drive, folder / "tum" / drive)
    except OSError as exc:
        raise _failure(folder, exc) from None
    finally:
        release()  # a signal that came during the moves acts now, with the export complete


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name) or "drive"


def _outages_csv(results: list[Any], labels: list[str]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(OUTAGE_COLUMNS)
    for res, label in zip(results, labels):
        distance = res.gnss_distance_m
        nees = {est.name: outage_nees(res, est.name) for est in res.estimators}
        trained = res.in_training
        for i, k in enumerate(res.starts):
            t0 = float(res.windows.t0_s[k])
            in_training = "" if trained is None else str(int(trained[i]))
            for est in res.estimators:
                m = res.metrics[est.name]
                final = nees[est.name][0][i, -1] if nees[est.name] is not None else math.nan
                inside = "" if not math.isfinite(final) else str(int(final <= CHI2_2_95))
                writer.writerow([label, i + 1, f"{t0:.3f}", f"{t0 + res.n_windows:.3f}",
                                 f"{float(res.drive.stamp_s(t0)):.6f}", est.name, est.label, f"{distance[i]:.4f}",
                                 *(_number(m[name][i]) for name in METRICS), _number(final), inside, in_training])
    return out.getvalue()


def _real_outages_csv(results: list[Any], labels: list[str]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(REAL_OUTAGE_COLUMNS)
    for res, label in zip(results, labels):
        labels = {est.name: est.label for est in res.estimators}
        for b in res.bridged:
            for name, err in b.final_error_m.items():
                writer.writerow([label, b.number, f"{b.gap_t0_s:.3f}", f"{b.gap_t1_s:.3f}", f"{b.gap_s:.3f}",
                                 f"{b.t0_s:.3f}", b.n_windows, f"{b.span_m:.4f}", name, labels.get(name, name),
                                 _number(err)])
    return out.getvalue()


def _number(x: float) -> str:
    return "" if not math.isfinite(float(x)) else repr(float(x))


def _boundaries(res: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per outage: stamps (s), truth latitude, longitude and course at the window boundaries."""
    w, starts, n = res.windows, np.asarray(res.starts, dtype=int), res.n_windows
    t = np.asarray(res.drive.stamp_s(w.t0_s[starts][:, None] + np.arange(n + 1)[None, :]), dtype=float)
    return (t, *w.boundary_fixes(starts, n))


def _tum(t: np.ndarray, east: np.ndarray, north: np.ndarray, course_deg: np.ndarray,
         origin: tuple[float, float]) -> str:
    yaw = np.radians(90.0 - course_deg)  # ENU yaw: from east, counter-clockwise
    rows = [f"# timestamp x y z qx qy qz qw  (x east, y north m about the drive's first trustworthy GNSS fix, "
            f"lat {origin[0]:.8f} lon {origin[1]:.8f} deg; ionav-viz)"]
    rows += [f"{ti:.6f} {x:.4f} {y:.4f} 0 0 0 {math.sin(a / 2):.9f} {math.cos(a / 2):.9f}"
             for ti, x, y, a in zip(t, east, north, yaw)]
    return "\n".join(rows) + "\n"


def _tum_files(res: Any, folder: Path) -> list[str]:
    """Write the TUM files of every outage into ``folder`` (plain writes: the caller swaps it in); their names."""
    received = res.drive.as_received()
    lat0, lon0 = received.local_origin_deg
    t, lat, lon, heading = _boundaries(res)
    # one projection per track set (a projection is set up per call: thousands of outages add up)
    local = {"truth": (*local_en_m(lat, lon, lat0, lon0), heading)}
    for est in res.estimators:
        track = res.estimates[est.name].track
        local[est.name] = (*local_en_m(track.lat_deg, track.lon_deg, lat0, lon0), track.heading_deg)
    out = []
    for i in range(len(res.starts)):
        for name, (east, north, course) in local.items():
            file = f"outage-{i + 1:03d}-{name}.tum"
            (folder / file).write_text(_tum(t[i], east[i], north[i], course[i], (lat0, lon0)))
            out.append(file)
    return out


#: One GPX ``trk``: its name, a description (or ""), and per segment the latitudes, longitudes and stamps (s).
GpxTrack = tuple[str, str, list[np.ndarray], list[np.ndarray], list[np.ndarray]]


def _tracks(res: Any, label: str,
            colors: dict[Any, tuple[int, int, int]]) -> tuple[list[dict[str, Any]], list[GpxTrack]]:
    """GeoJSON features and GPX tracks of one drive (named ``label``): its truth, and every outage's
    estimates; ``colors`` per estimator name, the truth's under None."""
    d = res.drive
    desc = "" if _dated(d) else UNDATED_DESC
    # the truth at about 1 Hz keeps the files small
    stretches = truth_stretches(d.gnss_ok, max(1, int(round(d.rate_hz))))
    features = [{"type": "Feature",
                 "geometry": {"type": "MultiLineString",
                              "coordinates": [_coords(d.lat_deg[k], d.lon_deg[k]) for k in stretches]},
                 "properties": {"drive": label, "kind": "truth",
                                **_style(f"{label} truth", colors[None], TRUTH_WIDTH_PX)}}]
    gpx = [(f"{label} truth", desc, [d.lat_deg[k] for k in stretches], [d.lon_deg[k] for k in stretches],
            [d.stamp_s(d.t_s[k]) for k in stretches])]
    for i, k in enumerate(res.starts):
        # the tracks are at the window boundaries
        stamps = d.stamp_s(res.windows.t0_s[k] + np.arange(res.n_windows + 1))
        for est in res.estimators:
            track = res.estimates[est.name].track
            final = float(res.metrics[est.name]["final_position_error_m"][i])
            title = (f"{label} outage {i + 1} {est.label}"
                     + (f", final error {final:.1f} m" if math.isfinite(final) else ""))
            features.append({"type": "Feature",
                             "geometry": {"type": "LineString",
                                          "coordinates": _coords(track.lat_deg[i], track.lon_deg[i])},
                             "properties": {"drive": label, "kind": "estimate", "outage": i + 1,
                                            "start_s": round(float(res.windows.t0_s[k]), 3),
                                            "estimator": est.name, "label": est.label,
                                            "final_position_error_m": final if math.isfinite(final) else None,
                                            **_style(title, colors[est.name], ESTIMATE_WIDTH_PX)}})
            gpx.append((f"{label} outage {i + 1} {est.label}", desc, [track.lat_deg[i]], [track.lon_deg[i]], [stamps]))
    for b in res.bridged:  # the log's own GNSS losses (--on gnss-outage)
        stamps = d.stamp_s(b.t0_s + np.arange(b.n_windows + 1))
        for est in res.estimators:
            track = b.tracks[est.name]
            final = float(b.final_error_m[est.name])
            title = (f"{label} real GNSS outage {b.number} {est.label}"
                     + (f", final error {final:.1f} m" if math.isfinite(final) else ""))
            features.append({"type": "Feature",
                             "geometry": {"type": "LineString",
                                          "coordinates": _coords(track.lat_deg[0], track.lon_deg[0])},
                             "properties": {"drive": label, "kind": "real-outage", "outage": b.number,
                                            "start_s": round(b.gap_t0_s, 3),
                                            "estimator": est.name, "label": est.label,
                                            "final_position_error_m": final if math.isfinite(final) else None,
                                            **_style(title, colors[est.name], ESTIMATE_WIDTH_PX)}})
            gpx.append((f"{label} real GNSS outage {b.number} {est.label}", desc, [track.lat_deg[0]],
                        [track.lon_deg[0]], [stamps]))
    return features, gpx


#: Line widths of the GeoJSON styles (px): the truth under the estimates, a little wider.
TRUTH_WIDTH_PX, ESTIMATE_WIDTH_PX = 4, 2
#: What a GPX track of a drive whose clock has no date says of its times (:func:`gpx_times`).
UNDATED_DESC = "times: the log's time of day (UTC) on 1970-01-01; the log carries no date"


def _style(title: str, rgb: tuple[int, int, int], width_px: int) -> dict[str, Any]:
    """A feature's simplestyle-spec 1.1 properties: its line and marker in ``rgb``, and its title."""
    color = "#{:02x}{:02x}{:02x}".format(*(int(c) for c in rgb))
    return {"title": title, "stroke": color, "stroke-width": width_px, "stroke-opacity": 1.0, "marker-color": color}


def _dated(drive: Any) -> bool:
    """Whether the drive's clock is UNIX time (message logs, KITTI), not a time of day (IO-VNBD)."""
    return drive.start_stamp_s is not None and float(drive.start_stamp_s) >= DATED_AFTER_S


def gpx_times(stamps_s: np.ndarray) -> list[str]:
    """GPX ``time`` values (UTC, ISO 8601 to the millisecond) of a drive's stamps
    (:meth:`~ionav_viz.core.drive.Drive.stamp_s`): UNIX seconds are their instant; a time of day (an IO-VNBD log carries
    no date) is that time on 1970-01-01 (past midnight, the 2nd), the date unknown, and the track's ``desc`` says so."""
    ms = np.round(np.asarray(stamps_s, dtype=float) * 1000.0).astype(np.int64).astype("datetime64[ms]")
    return [f"{t}Z" for t in np.datetime_as_string(ms, unit="ms")]


def truth_stretches(ok: np.ndarray, step: int) -> list[np.ndarray]:
    """The sample indices of the truth tracks: every ``step``-th trustworthy fix (``ok``), in
    stretches broken wherever an untrusted one lies between two (the last good fix of each
    stretch kept, so a stretch ends where the fixes stop)."""
    good = np.flatnonzero(ok)
    if not len(good):
        return []
    bad_before = np.cumsum(~np.asarray(ok, dtype=bool))[good]  # untrusted samples up to each good one
    cuts = np.flatnonzero(np.diff(bad_before)) + 1
    out = []
    for run in np.split(good, cuts):
        keep = run[::step]
        out.append(keep if keep[-1] == run[-1] else np.append(keep, run[-1]))
    return out


def _coords(lat: np.ndarray, lon: np.ndarray) -> list[list[float]]:
    return [[round(float(x), 8), round(float(y), 8)] for y, x in zip(lat, lon)]


def _gpx(tracks: list[GpxTrack]) -> str:
    """GPX 1.1 of ``tracks``: each ``(name, desc, lat, lon and stamps per segment)`` one ``trk``."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           '<gpx version="1.1" creator="ionav-viz" xmlns="http://www.topografix.com/GPX/1/1">']
    for name, desc, lats, lons, stamps in tracks:
        segments = "".join("<trkseg>" + "".join(f'<trkpt lat="{float(y):.8f}" '
                                                f'lon="{float(x):.8f}"><time>{t}</time></trkpt>'
                                                for y, x, t in zip(lat, lon, gpx_times(stamp))) + "</trkseg>"
                           for lat, lon, stamp in zip(lats, lons, stamps))
        out.append(f"<trk><name>{escape(name)}</name>" + (f"<desc>{escape(desc)}</desc>" if desc else "")
                   + f"{segments}</trk>")
    out.append("</gpx>")
    return "\n".join(out) + "\n"
