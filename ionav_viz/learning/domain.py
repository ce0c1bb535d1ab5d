"""What an IDNN model was trained on (the domain of its inputs), and how far a drive's lie outside it.

A model's ``metadata.json`` keeps a summary of its training inputs (:class:`Domain`, written by
``train``; JSON, never a pickle):

* the bias-corrected longitudinal acceleration and yaw rate of every training sample and the
  GNSS speed, as quantiles of their sizes (:data:`QUANTILES`: up to which value 50 %, 90 %, ...
  and all of the samples lie);
* each training drive's sample noise (accelerometer and gyro: the spread of the samples' second
  differences, robust, over the whole drive: what the networks see of the sensor's noise and the
  car's vibration), as the range over the drives;
* the IMUs' own sample rates and sample kinds (``2-channel``, or ``6-axis`` with ``averaged`` or
  ``single`` readings; :func:`~ionav_viz.learning.provenance.imu_kind`).

A fine-tuned model's domain is its parent's and its own drives' together. A drive is
:func:`outside` the domain where its 99.5 % acceleration, yaw rate or speed exceeds the training's
by more than :data:`TOLERANCE`, where its noise lies more than that beyond the training drives'
range, or where its rate or sample kind is not one trained on (``IDNN: yaw rate up to 1.2 rad/s,
trained up to 0.6 rad/s; sample rate 40 Hz, trained on 10 Hz``). The estimator warns of it and
widens its learned uncertainty by :func:`sigma_scale`: a factor growing with how far each
outage's inputs go beyond what the networks ever saw.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.drive import Drive
from ..nav.bias import SensorBias
from .provenance import RATE_TOLERANCE, imu_kind

#: The quantiles of the sizes of the training samples kept per feature.
QUANTILES = (0.5, 0.9, 0.99, 0.995, 0.999, 1.0)
#: A drive's value at this quantile is compared with the training's at the same quantile (the warning).
CHECK_QUANTILE = 0.995
#: What the networks saw: a sample beyond the training's value at this quantile is extrapolated (the widening).
SEEN_QUANTILE = 0.999
#: How far beyond the training's value (relative) a drive's may lie before it is said to be outside.
TOLERANCE = 0.2
#: The sampled features: name -> (words, unit, digits).
SAMPLED = {"accel_mps2": ("acceleration", "m/s²", 2), "yaw_rate_radps": ("yaw rate", "rad/s", 2),
           "speed_mps": ("speed", "m/s", 1)}
#: The noise features: name -> (words, unit, digits).
NOISE = {"accel_noise_mps2": ("accelerometer noise", "m/s²", 3), "gyro_noise_radps": ("gyro noise", "rad/s", 4)}
#: A sample rate or sample kind not trained on counts this much in :func:`sigma_scale` (the inputs'
#: noise, measured, says the rest of what a rate or kind changes).
CATEGORY_DISTANCE = 0.25


def kind_of(drive: Drive) -> str:
    """The drive's sample kind: its IMU kind (``2-channel``, ``6-axis``), with ``, averaged`` or
    ``, single`` where the samples' nature is known (read or given, not assumed: a CSV does not say)."""
    kind = imu_kind(drive)
    known = drive.imu is not None and drive.imu.sample_kind_source != "assumed"
    return f"{kind}, {drive.imu.sample_kind}" if known else kind


def kind_trained(kind: str, kinds: Sequence[str]) -> bool:
    """Whether the sample kind ``kind`` (:func:`kind_of`) is one of ``kinds``: the same IMU kind, and
    the same nature of samples where both say it."""
    imu, _, nature = kind.partition(", ")
    for trained in kinds:
        t_imu, _, t_nature = trained.partition(", ")
        if t_imu == imu and (not nature or not t_nature or nature == t_nature):
            return True
    return False


def rate_of(drive: Drive) -> float:
    """The IMU's own sample rate (Hz): a log's as logged (before the reader's 10 Hz grid), else the drive's."""
    return float(drive.imu.native_rate_hz) if drive.imu is not None else float(drive.rate_hz)


def noise_of(samples: np.ndarray) -> float:
    """The noise of a series of samples: the robust spread (1.4826 x MAD) of its second
    differences over sqrt(6), which is the samples' standard deviation for white noise and leaves
    out what changes smoothly (NaN for fewer than 10 samples)."""
    x = np.asarray(samples, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) < 10:
        return math.nan
    d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def sampled_values(drive: Drive, bias: SensorBias) -> dict[str, np.ndarray]:
    """The sizes of the drive's samples of each :data:`SAMPLED` feature: bias-corrected acceleration
    and yaw rate, GNSS speed."""
    cols = drive.columns
    return {"accel_mps2": np.abs(cols["accel_long_mps2"] - bias.accel_mps2),
            "yaw_rate_radps": np.abs(cols["yaw_rate_radps"] - bias.gyro_radps), "speed_mps": np.abs(cols["speed_mps"])}


def drive_noise(drive: Drive) -> dict[str, float]:
    """Each :data:`NOISE` feature of the drive (:func:`noise_of` its samples)."""
    return {"accel_noise_mps2": noise_of(drive.columns["accel_long_mps2"]),
            "gyro_noise_radps": noise_of(drive.columns["yaw_rate_radps"])}


def _quantiles(values: np.ndarray) -> list[float]:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return [float(q) for q in np.quantile(v, QUANTILES)] if len(v) else [math.nan] * len(QUANTILES)


@dataclass(frozen=True)
class Domain:
    """A model's training inputs (see the module docstring).

    ``quantiles``: per :data:`SAMPLED` feature, its value at each of :data:`QUANTILES`;
    ``noise``: per :data:`NOISE` feature, the (least, largest) over the training drives;
    ``rates_hz`` and ``kinds``: the sample rates and kinds trained on; ``n_drives``: how many
    drives (a fine-tuned model's parent's included); ``note``: how the summary was made."""

    quantiles: dict[str, list[float]]
    noise: dict[str, tuple[float, float]]
    rates_hz: tuple[float, ...]
    kinds: tuple[str, ...]
    n_drives: int
    note: str = ""

    def value(self, feature: str, quantile: float) -> float:
        return self.quantiles[feature][QUANTILES.index(quantile)]

    def to_dict(self) -> dict[str, Any]:
        return {"quantiles_of": list(QUANTILES), "quantiles": {k: list(v) for k, v in self.quantiles.items()},
                "noise": {k: list(v) for k, v in self.noise.items()}, "rates_hz": list(self.rates_hz),
                "kinds": list(self.kinds), "n_drives": self.n_drives, "note": self.note}

    @classmethod
    def from_dict(cls, d: Any) -> Domain:
        """From metadata; a ValueError names what is wrong."""
        if not isinstance(d, dict):
            raise ValueError("domain: not an object")
        if d.get("quantiles_of") != list(QUANTILES):
            raise ValueError(f"domain.quantiles_of: {d.get('quantiles_of')!r}, expected {list(QUANTILES)}")

        def number(x: Any, where: str) -> float:
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x < 0:
                raise ValueError(f"domain.{where}: {x!r} is not a finite number >= 0")
            return float(x)

        quantiles = {}
        for name in SAMPLED:
            q = d.get("quantiles", {}).get(name) if isinstance(d.get("quantiles"), dict) else None
            if not isinstance(q, list) or len(q) != len(QUANTILES):
                raise ValueError(f"domain.quantiles.{name}: expected {len(QUANTILES)} numbers")
            quantiles[name] = [number(x, f"quantiles.{name}") for x in q]
            if any(b < a for a, b in zip(quantiles[name], quantiles[name][1:])):
                raise ValueError(f"domain.quantiles.{name}: not increasing")
        noise = {}
        for name in NOISE:
            r = d.get("noise", {}).get(name) if isinstance(d.get("noise"), dict) else None
            if not isinstance(r, list) or len(r) != 2:
                raise ValueError(f"domain.noise.{name}: expected [least, largest]")
            lo, hi = (number(x, f"noise.{name}") for x in r)
            if hi < lo:
                raise ValueError(f"domain.noise.{name}: [{lo}, {hi}] is not a range")
            noise[name] = (lo, hi)
        rates, kinds = d.get("rates_hz"), d.get("kinds")
        if not isinstance(rates, list) or not rates or any(number(r, "rates_hz") <= 0 for r in rates):
            raise ValueError("domain.rates_hz: expected a list of rates (Hz) above 0")
        if not isinstance(kinds, list) or not kinds or not all(isinstance(k, str) for k in kinds):
            raise ValueError("domain.kinds: expected a list of sample kinds")
        n = d.get("n_drives")
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"domain.n_drives: {n!r} is not a count")
        return cls(quantiles, noise, tuple(float(r) for r in rates), tuple(kinds), n, str(d.get("note", "")))


def domain_of(drives: Sequence[tuple[Drive, SensorBias]], parent: Domain | None = None, note: str = "") -> Domain:
    """The :class:`Domain` of training on ``drives`` (each with its sensor biases), joined with a
    fine-tuned model's ``parent``'s: the larger of each quantile (the parent's networks saw its
    inputs and still answer for them), the noise ranges and the rates and kinds together."""
    pooled = {name: np.concatenate([sampled_values(d, b)[name] for d, b in drives]) for name in SAMPLED}
    quantiles = {name: _quantiles(values) for name, values in pooled.items()}
    per_drive = [drive_noise(d) for d, _ in drives]
    noise = {}
    for name in NOISE:
        values = [n[name] for n in per_drive if math.isfinite(n[name])]
        noise[name] = (min(values), max(values)) if values else (math.nan, math.nan)
    rates = sorted({round(rate_of(d), 3) for d, _ in drives})
    kinds = sorted({kind_of(d) for d, _ in drives})
    n = len(drives)
    if parent is not None:
        quantiles = {k: [max(a, b) for a, b in zip(v, parent.quantiles[k])] for k, v in quantiles.items()}
        noise = {k: (min(v[0], parent.noise[k][0]), max(v[1], parent.noise[k][1])) for k, v in noise.items()}
        rates = sorted({*rates, *parent.rates_hz})
        kinds = sorted({*kinds, *parent.kinds})
        n += parent.n_drives
    return Domain(quantiles, noise, tuple(rates), tuple(kinds), n, note)


def _fmt(value: float, digits: int) -> str:
    return f"{value:.{digits}f}"


@dataclass(frozen=True)
class Outside:
    """One way a drive's inputs lie outside a model's domain: ``feature``, ``text`` (what the drive
    has against what was trained on), ``distance`` (how far: relative beyond the training's value,
    the log of the noise's ratio, or :data:`CATEGORY_DISTANCE` for a rate or kind) and whether it
    ``widens`` the uncertainty (:func:`sigma_scale`; not samples quieter than any trained on)."""

    feature: str
    text: str
    distance: float
    widens: bool = True


def outside(domain: Domain, drive: Drive, bias: SensorBias) -> list[Outside]:
    """How the drive's inputs lie outside ``domain`` (empty: inside), each feature once."""
    found = []
    values = sampled_values(drive, bias)
    for name, (words, unit, digits) in SAMPLED.items():
        v = values[name][np.isfinite(values[name])]
        if not len(v):
            continue
        mine, trained = float(np.quantile(v, CHECK_QUANTILE)), domain.value(name, CHECK_QUANTILE)
        if mine > trained * (1.0 + TOLERANCE):
            found.append(Outside(name,
                                 f"{words} up to {_fmt(mine, digits)} {unit}, trained up to "
                                 f"{_fmt(trained, digits)} {unit}", mine / trained - 1.0 if trained > 0 else 1.0))
    for name, value in drive_noise(drive).items():
        words, unit, digits = NOISE[name]
        lo, hi = domain.noise[name]
        if not (math.isfinite(value) and math.isfinite(lo) and math.isfinite(hi)):
            continue
        text = f"{words} {_fmt(value, digits)} {unit}, trained {_fmt(lo, digits)}-{_fmt(hi, digits)} {unit}"
        if value > hi * (1.0 + TOLERANCE):
            found.append(Outside(name, text, math.log(value / hi)))
        elif value < lo / (1.0 + TOLERANCE):
            found.append(Outside(name, text, math.log(lo / value) if value > 0 else 1.0, widens=False))
    rate = rate_of(drive)
    if not any(abs(rate - r) <= RATE_TOLERANCE * r for r in domain.rates_hz):
        trained = " and ".join(f"{r:g}" for r in domain.rates_hz)
        found.append(Outside("rate_hz", f"sample rate {rate:g} Hz, trained on {trained} Hz", CATEGORY_DISTANCE))
    kind = kind_of(drive)
    if not kind_trained(kind, domain.kinds):
        found.append(Outside("kind", f"{kind} samples, trained on {' and '.join(domain.kinds)}", CATEGORY_DISTANCE))
    return found


def sigma_scale(domain: Domain, drive_outside: Sequence[Outside], accel_mps2: np.ndarray, gyro_radps: np.ndarray,
                speed_mps: np.ndarray) -> np.ndarray:
    """Per outage, the factor on the learned position sigma (>= 1; the covariance takes its square):
    ``1 + d``, ``d`` the drive's noise (noisier than trained), rate and kind distances
    (:func:`outside`) and, per outage, how far its inputs go beyond what the networks saw
    (:data:`SEEN_QUANTILE` of the training's): the mean over its samples of
    ``max(0, |x| / seen - 1)`` for the bias-corrected acceleration and yaw rate (``accel_mps2``,
    ``gyro_radps``: ``(n_outages, ...)``) and the predicted speed (``speed_mps``,
    ``(n_outages, n_windows)``). 1 for an outage inside the domain."""
    base = sum(o.distance for o in drive_outside if o.feature not in SAMPLED and o.widens)
    d = np.full(len(accel_mps2), float(base))
    if not len(d):
        return d
    for name, x in (("accel_mps2", accel_mps2), ("yaw_rate_radps", gyro_radps), ("speed_mps", speed_mps)):
        seen = domain.value(name, SEEN_QUANTILE)
        x = np.abs(np.asarray(x, dtype=float)).reshape(len(d), -1)
        if seen > 0 and x.size:
            d += np.mean(np.maximum(x / seen - 1.0, 0.0), axis=1)
    return 1.0 + d
