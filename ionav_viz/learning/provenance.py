"""What a trained IDNN model saw, and the checks that use it.

A model's ``metadata.json`` records, per training drive, the file's sha256 and size and the stretch
of the drive's own time it was trained on (``span_s``, after ``--span``), and for the whole model
what its inputs were (:func:`input_record`: the two channels, the 10 Hz grid, the IMU kind and the
drive's sample rate as read: IO-VNBD and KITTI files at their own rate; message logs are binned to
the 10 Hz grid as they are read, so a 100 Hz and a 10 Hz log both read as 10 Hz, and only their
kind, 6-axis, tells them from a 2-channel file). From those:

* :func:`check_inputs` refuses a drive whose IMU kind or sample rate is not the model's (a model
  fine-tuned on a 100 Hz phone, its samples averaged into the grid, is not a model of a 10 Hz
  two-channel logger); models without the record (the shipped one, older ones) are not checked;
* :func:`trained_outages` finds the outages that lie in data the model was trained on (the same
  file, by checksum, and overlapping time): their scores flatter the model.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.drive import Drive, measured_imu
from ..core.errors import InputError
from ..core.grid import GRID_RATE_HZ

#: What the IDNN's networks take: the longitudinal specific force and the yaw rate.
CHANNELS = ("accel_long_mps2", "yaw_rate_radps")
#: Sample rates closer than this (relative) are the same rate (a log's jitter, a rounding).
RATE_TOLERANCE = 0.1

_SHA_CACHE: dict[tuple[str, int, int], str] = {}


def imu_kind(drive: Drive) -> str:
    """``"6-axis"`` for a drive with the full IMU (message logs, KITTI), else ``"2-channel"``
    (IO-VNBD's longitudinal acceleration and yaw rate)."""
    return "6-axis" if measured_imu(drive) is not None else "2-channel"


def file_sha256(path: str | Path) -> str | None:
    """sha256 of a file (remembered per path, size and modification time), None for a folder or an
    unreadable path."""
    try:
        info = os.stat(path)
        if not os.path.isfile(path):
            return None
        key = (str(Path(path).resolve()), info.st_size, info.st_mtime_ns)
        if key not in _SHA_CACHE:
            digest = hashlib.sha256()
            with open(path, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    digest.update(block)
            _SHA_CACHE[key] = digest.hexdigest()
        return _SHA_CACHE[key]
    except OSError:
        return None


def drive_record(drive: Drive) -> dict[str, Any]:
    """What a model's metadata keeps of one training drive: its file, checksum and size, the time
    trained on (s on the drive's own clock), its IMU kind and rate."""
    size = os.path.getsize(drive.source) if drive.source and os.path.isfile(drive.source) else None
    return {"name": drive.name, "file": Path(drive.source).name, "sha256": file_sha256(drive.source),
            "size_bytes": size, "span_s": [float(drive.t_s[0]), float(drive.t_s[-1])], "imu_kind": imu_kind(drive),
            "imu_rate_hz": float(drive.rate_hz)}


def input_record(drives: Sequence[Drive]) -> dict[str, Any]:
    """The inputs of a model trained on ``drives``: they must share one IMU kind and sample rate
    (else an :class:`InputError`: one model per IMU)."""
    kinds = {imu_kind(d) for d in drives}
    rates = sorted({float(d.rate_hz) for d in drives})
    if len(kinds) > 1 or (rates and rates[-1] > rates[0] * (1 + RATE_TOLERANCE)):
        listed = ", ".join(f"{d.name} ({imu_kind(d)}, {d.rate_hz:g} Hz)" for d in drives)
        raise InputError(f"the training drives mix IMUs: {listed}", "train one model per IMU kind and sample rate",
                         param="drives")
    return {"channels": list(CHANNELS), "grid_rate_hz": GRID_RATE_HZ, "imu_kind": kinds.pop(), "imu_rate_hz": rates[0]}


def check_inputs(metadata: dict[str, Any], drive: Drive, model: str = "the model") -> None:
    """Refuse ``drive`` when the model's recorded inputs (:func:`input_record`) are not the drive's:
    another grid rate, a channel the drive lacks, another IMU kind or sample rate."""
    record = metadata.get("input")
    if not isinstance(record, dict):
        return  # the shipped model and older ones: trained across IMUs, or not recorded
    where = f"{drive.source or drive.name}"
    hint = ("evaluate it on drives of the IMU it was trained on, or fine-tune the shipped model on this one "
            "(train --from-model shipped)")
    grid = record.get("grid_rate_hz")
    if grid != GRID_RATE_HZ:
        raise InputError(f"{model} takes {grid} Hz inputs and this version puts drives on a {GRID_RATE_HZ:g} Hz grid",
                         "retrain it", param="model")
    missing = [c for c in record.get("channels", []) if c not in drive.columns]
    if missing:
        raise InputError(f"{where}: has no {', '.join(missing)}, an input of {model}", hint, param="model")
    kind, rate = record.get("imu_kind"), record.get("imu_rate_hz")
    if kind != imu_kind(drive):
        raise InputError(f"{where}: a {imu_kind(drive)} IMU, and {model} was trained on a {kind} IMU", hint,
                         param="model")
    if isinstance(rate, (int, float)) and rate > 0 and abs(drive.rate_hz - rate) > RATE_TOLERANCE * rate:
        raise InputError(f"{where}: samples at {drive.rate_hz:g} Hz, and {model} was trained on {rate:g} Hz samples",
                         hint, param="model")


def seen_drives(metadata: dict[str, Any]) -> list[dict[str, Any]]:
    """Every training drive record of a model's metadata: its own, and its parent's (fine-tuning)."""
    out = []
    for part in (metadata.get("training"), metadata.get("parent")):
        if isinstance(part, dict) and isinstance(part.get("drives"), list):
            out += [r for r in part["drives"] if isinstance(r, dict)]
    return out


def trained_outages(metadata: dict[str, Any], drive: Drive, intervals_s: np.ndarray) -> list[int]:
    """Which outages (``intervals_s``: (n, 2) start and end on the drive's own clock, the window
    before the outage included) lie in data the model was trained on: the same file (sha256; for
    records without a size, only files of the same name are hashed) and a time overlap of more than
    a sample. A record without ``span_s`` was trained on the whole drive."""
    drives = seen_drives(metadata)
    if not drives or not drive.source or not os.path.isfile(drive.source):
        return []
    try:
        size = os.stat(drive.source).st_size
    except OSError:
        return []
    name = Path(drive.source).name
    candidates = [r for r in drives if isinstance(r, dict) and isinstance(r.get("sha256"), str)
                  and (r.get("size_bytes") == size if isinstance(r.get("size_bytes"), int) else r.get("file") == name)]
    if not candidates or (sha := file_sha256(drive.source)) is None:
        return []
    spans = []
    for r in candidates:
        if r["sha256"] != sha:
            continue
        span = r.get("span_s")
        spans.append((float(span[0]), float(span[1])) if isinstance(span, list) and
                     len(span) == 2 else (-np.inf, np.inf))
    if not spans:
        return []
    intervals = np.asarray(intervals_s, dtype=np.float64).reshape(-1, 2)
    margin = 0.5 / GRID_RATE_HZ  # touching ends (train 0-330 s, test from 330 s) is no overlap
    hit = np.zeros(len(intervals), dtype=bool)
    for lo, hi in spans:
        hit |= (intervals[:, 0] < hi - margin) & (intervals[:, 1] > lo + margin)
    return [int(i) for i in np.flatnonzero(hit)]
