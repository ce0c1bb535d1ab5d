"""Measure what a log's IMU is, the same way on real and simulated logs (issue 41: the simulator
must predict real consumer IMUs). Give your local copies of the logs; nothing is downloaded.

Per log: the IMU's native rate and what the reader makes of its samples, the gyro's and the
accelerometer's noise standing and driving (successive-sample spread, as SENSORS.md's table), the
gyro's Allan deviation at 1 s standing (where 20 s of standstill allow it), the holder's wobble
(pitch and roll rates' spread while driving), the gyro's vertical scale against the GNSS course,
how much the forward accelerometer's offset from the GNSS acceleration wanders within 10 s (what an
outage's dead reckoning must carry: road grade, a holder tilting with the car's acceleration, bias
wander), the stamps' jitter and gaps,
the clock offset against the receiver, how late the receiver's speed is against the IMU
(:mod:`ionav_viz.core.gnss_lag`), the receiver's losses (its cold start and its gaps) and the mount::

    python benchmarks/imu_character.py LOG.mcap... [--truth-topic /truth/fix] [--gnss-topic T] [--max-sigma-m 13] [--json OUT] [--debug]
    python benchmarks/imu_character.py --simulated 300   # the simulator's phone and mems grades, 5 min each

A log that is missing or cannot be read, or a ``--json`` that cannot be written, stops it before
any measurement: one line naming the file, exit code 2 (``--debug``: the traceback).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from _cli import add_debug, check_logs, output_file, run

import ionav_viz as iv
from ionav_viz.core.fileio import atomic_write_bytes
from ionav_viz.core.gnss_quality import GnssLimits
from ionav_viz.core.runs import true_runs
from ionav_viz.nav.stillness import drive_still
from ionav_viz.sources.imu.clock import estimate_clock_offset


def _spread(d: np.ndarray) -> float:
    """Robust 1-sigma per sample of successive differences ``d``: 1.4826 MAD / sqrt(2)."""
    if len(d) < 10:
        return math.nan
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


def allan_1s(x: np.ndarray, rate_hz: float) -> float:
    """The Allan deviation at 1 s of samples ``x`` (one stretch of at least 5 s)."""
    n = int(round(rate_hz))
    m = len(x) // n
    if m < 5:
        return math.nan
    means = x[: m * n].reshape(m, n).mean(axis=1)
    return float(math.sqrt(0.5 * np.mean(np.diff(means) ** 2)))


def gyro_course_scale(drive, window_s: float = 10.0) -> float:
    """The gyro's vertical scale against the GNSS course: over 10 s stretches at speed, the turn the
    gyro integrates against the course's change, fitted through the origin on the stretches that
    turn (integrals over seconds: the course's noise hardly counts, where a rate's would bias it)."""
    t, speed = drive.t_s, drive.speed_mps
    course = np.unwrap(np.deg2rad(drive.heading_deg))
    turn = np.concatenate([[0.0], np.cumsum(0.5 * (drive.columns["gyro_z_radps"][1:] + drive.columns["gyro_z_radps"][:-1]) * np.diff(t))])
    edges = np.arange(t[0], t[-1] - window_s, window_s)
    i0, i1 = np.searchsorted(t, edges), np.searchsorted(t, edges + window_s)
    fast = np.array([speed[a:b].min() > 5.0 if b > a else False for a, b in zip(i0, i1)])
    g, c = (turn[i1] - turn[i0])[fast], -(course[i1] - course[i0])[fast]  # course is clockwise
    use = np.abs(c) > np.deg2rad(20.0)
    if use.sum() < 3:
        return math.nan
    return float((g[use] * c[use]).sum() / (c[use] * c[use]).sum())


def accel_gain(drive, smooth_s: float = 1.0) -> float:
    """The forward accelerometer against the GNSS speed's rate of change while driving (above
    3 m/s): the slope of a straight-line fit (with an offset: mount pitch, road grade, bias), both
    smoothed over ``smooth_s``. A rigid mount reads 1 (times its scale error); a holder tilting
    ``k`` rad nose-up per m/s^2 of forward acceleration adds gravity's share, ``1 + g k``. Noise in
    the GNSS acceleration pulls the slope below 1 (on the real logs 0.16-0.78 with correlations
    0.3-0.85): in the JSON only, it does not resolve a holder's tilt on these logs."""
    n = max(1, int(round(smooth_s * drive.rate_hz)))
    kernel = np.ones(n) / n
    t = drive.t_s
    speed = np.convolve(drive.speed_mps, kernel, mode="same")
    a_gnss = np.gradient(speed, t)
    a_imu = np.convolve(drive.columns["accel_x_mps2"], kernel, mode="same")
    use = (drive.speed_mps > 3.0) & np.isfinite(a_gnss) & np.isfinite(a_imu)
    use[:n] = use[-n:] = False
    if use.sum() < 100 or np.std(a_gnss[use]) < 0.1:
        return math.nan
    return float(np.polyfit(a_gnss[use], a_imu[use], 1)[0])


def accel_wander(drive, window_s: float = 10.0) -> float:
    """How much the forward accelerometer's offset from the GNSS acceleration changes within
    ``window_s`` while driving (m/s^2, robust 1 sigma): both averaged over ``window_s``, the
    difference of their means ``window_s`` apart. A constant offset (mount pitch, bias) a filter
    estimates before an outage does not count; road grade changing, a holder tilting with the car's
    acceleration and bias wander do: the error a 10 s outage's forward integration carries."""
    n = max(2, int(round(window_s * drive.rate_hz)))
    kernel = np.ones(n) / n
    speed = np.convolve(drive.speed_mps, kernel, mode="same")
    residual = np.convolve(drive.columns["accel_x_mps2"], kernel, mode="same") - np.gradient(speed, drive.t_s)
    use = drive.speed_mps > 3.0
    use[:n] = use[-n:] = False
    d = (residual[n:] - residual[:-n])[use[n:] & use[:-n]]
    d = d[np.isfinite(d)]
    if len(d) < 2 * n:
        return math.nan
    return float(1.4826 * np.median(np.abs(d - np.median(d))))


def receiver_gaps(drive, min_s: float = 2.0) -> dict:
    """The receiver's losses: stretches of at least ``min_s`` s without a fix the reader trusts
    (``receiver_fault``, or ``gnss_fault`` where the receiver is also the truth). The one at the
    start (a cold start, before the first trusted fix) is kept apart: its length (s); the others
    per 10 minutes of the drive after it, and their median and longest (s)."""
    t = drive.t_s
    fault = drive.receiver_fault if drive.receiver_fault is not None else drive.gnss_fault
    bad = np.asarray(fault) != 0
    starts, ends = true_runs(bad)
    lengths = t[np.minimum(ends, len(t) - 1)] - t[starts]
    cold = float(lengths[0]) if len(starts) and starts[0] == 0 else 0.0
    later = lengths[(starts > 0) & (lengths >= min_s)]
    after_s = float(t[-1] - t[0]) - cold
    return {"cold_start_s": round(cold, 1), "gaps_per_10min": float(len(later) / after_s * 600.0) if after_s > 0 else math.nan,
            "gap_median_s": float(np.median(later)) if len(later) else math.nan, "gap_max_s": float(later.max()) if len(later) else math.nan}


def stamp_jitter(path: Path | None, topic: str = "/imu/data") -> tuple[float, float, float]:
    """The IMU's native sample periods from an MCAP's message times: the median period (s), the
    spread between the 1st and 99th percentile periods (ms) and the share of periods over 1.5 times
    the median (gaps: lost or doubled samples). NaNs when the log is not an MCAP."""
    if path is None or Path(path).suffix.lower() != ".mcap":
        return math.nan, math.nan, math.nan
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        stamps = np.array([m.log_time for _, _, m in make_reader(f).iter_messages(topics=[topic])], dtype=np.int64)
    if len(stamps) < 3:
        return math.nan, math.nan, math.nan
    dt = np.diff(stamps) / 1e9
    med = float(np.median(dt))
    p1, p99 = np.percentile(dt, [1, 99])
    return med, float((p99 - p1) * 1e3), float(np.mean(dt > 1.5 * med))


def measure(drive, path: Path | None = None) -> dict:
    imu = drive.imu
    still = drive_still(drive)
    both = still[1:] & still[:-1]
    moving = (drive.speed_mps[1:] > 3.0) & (drive.speed_mps[:-1] > 3.0)
    gz, ax = drive.columns["gyro_z_radps"], drive.columns["accel_x_mps2"]
    out = {
        "log": drive.name,
        "native_rate_hz": imu.native_rate_hz if imu else drive.rate_hz,
        "samples": (f"averaged ({imu.readings_per_sample:.0f} per sample)" if imu.sample_kind_source == "reader"
                    else f"{imu.sample_kind} ({imu.sample_kind_source})") if imu else "?",
        "duration_s": round(drive.duration_s, 1),
        "standing_s": round(float(still.sum()) / drive.rate_hz, 1),
        "gyro_standing_dps": math.degrees(_spread(np.diff(gz)[both])),
        "gyro_driving_dps": math.degrees(_spread(np.diff(gz)[moving])),
        "accel_standing_mps2": _spread(np.diff(ax)[both]),
        "accel_driving_mps2": _spread(np.diff(ax)[moving]),
        "wobble_dps": imu.wobble_dps if imu else math.nan,
        # the same spread (pitch and roll rates, successive samples) standing
        "wobble_standing_dps": math.degrees(0.5 * (_spread(np.diff(drive.columns["gyro_x_radps"])[both])
                                                   + _spread(np.diff(drive.columns["gyro_y_radps"])[both]))),
        "gyro_course_scale": gyro_course_scale(drive),
        "accel_gain": accel_gain(drive),
        "accel_wander_mps2": accel_wander(drive),
    }
    out["period_s"], out["jitter_ms"], out["gaps"] = stamp_jitter(path)
    out |= receiver_gaps(drive)
    # Allan deviation at 1 s over the longest standing stretch
    starts, ends = true_runs(still)
    if len(starts):
        i = int(np.argmax(ends - starts))
        out["gyro_allan_1s_dps"] = math.degrees(allan_1s(gz[starts[i]:ends[i]], drive.rate_hz))
    clock = estimate_clock_offset(drive.t_s, gz, drive.speed_mps, drive.heading_deg)
    out["clock_offset_s"] = round(clock.offset_s, 3) if clock.resolved else None
    out["clock_note"] = f"{clock.offset_s:+.3f} ± {clock.sigma_s:.3f} s" if clock.resolved else clock.reason
    out["mount_deg"] = imu.mount_deg if imu else None
    # what the reader found (core.gnss_lag, on the whole log)
    out["speed_lag_s"] = round(imu.speed_lag_s, 2) if imu and imu.speed_lag_note[:1].isdigit() else None
    out["speed_lag_note"] = imu.speed_lag_note if imu else "–"
    return out


def row(m: dict) -> str:
    def f(key: str, fmt: str = "{:.2f}") -> str:
        v = m.get(key)
        return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else fmt.format(v)
    return (f"| {m['log']} | {f('native_rate_hz', '{:g}')} Hz, {m['samples']} | {f('duration_s', '{:.0f}')} s ({f('standing_s', '{:.0f}')} s standing) | "
            f"{f('gyro_standing_dps')} / {f('gyro_driving_dps')} | {f('accel_standing_mps2')} / {f('accel_driving_mps2')} | "
            f"{f('gyro_allan_1s_dps', '{:.3f}')} | {f('wobble_standing_dps')} / {f('wobble_dps', '{:.1f}')} | {f('gyro_course_scale', '{:.3f}')} | {f('accel_wander_mps2')} | "
            f"{f('jitter_ms', '{:.3f}')} ms, {f('gaps', '{:.2%}')} | {m['clock_note']} | {m['speed_lag_note']} | "
            f"{f('cold_start_s', '{:.0f}')} s; {f('gaps_per_10min', '{:.1f}')} per 10 min, median {f('gap_median_s', '{:.0f}')} s, longest {f('gap_max_s', '{:.0f}')} s |")


HEADER = ("| log | IMU | length | gyro noise standing / driving (deg/s per sample) | accel noise standing / driving (m/s² per sample) | "
          "gyro Allan dev. at 1 s standing (deg/s) | holder wobble standing / driving (deg/s) | gyro z / GNSS course | accel x offset wander in 10 s (m/s²) | "
          "period spread p1-p99, gaps | clock offset | receiver speed behind the IMU (correlation) | "
          "receiver without a trusted fix: cold start; gaps of 2 s or more after it |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|")


#: The simulated logs ``--simulated`` measures: (grade, scenario, seed); the seeds of
#: benchmarks/results_table.py's sets (hard-brake: its stands are long enough for an Allan deviation).
SIMULATED = (("phone", "roundabout", 900), ("phone", "sharp-cornering", 901), ("phone", "hard-brake", 902),
             ("dash", "motorway", 930), ("mems", "roundabout", 910))


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("logs", nargs="*", type=Path)
    parser.add_argument("--truth-topic")
    parser.add_argument("--gnss-topic")
    parser.add_argument("--simulated", type=float, metavar="SECONDS", help="also measure the simulator's phone and mems logs of this length")
    parser.add_argument("--max-sigma-m", type=float, help="trust fixes reporting up to this accuracy (m; a phone's 6-8 m need 13), as real_imu_logs.py")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    check_logs(args.logs)
    output_file(args.json, "--json", inputs=args.logs)
    results = []
    limits = GnssLimits() if args.max_sigma_m is None else replace(GnssLimits(), max_sigma_m=args.max_sigma_m)
    read = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", truth_topic=args.truth_topic, gnss_topic=args.gnss_topic, vehicle_speed_topic="none"),
                          gnss_limits=limits)
    drives = [(iv.load_drive(str(p), read), p) for p in args.logs]  # every log read before the table starts
    print(HEADER)
    with tempfile.TemporaryDirectory() as tmp:
        if args.simulated:
            from ionav_viz.sim.imu import IMU_GRADES, SIM_TRUTH_TOPIC, write_imu_log

            sim_read = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none"))
            for grade, scenario, seed in (s for s in SIMULATED if s[0] in IMU_GRADES):
                path = write_imu_log(Path(tmp) / f"sim-{grade}-{scenario}.mcap", scenario, seed, args.simulated, grade)
                drives.append((iv.load_drive(str(path), sim_read), path))
        for drive, path in drives:
            m = measure(drive, path)
            results.append(m)
            print(row(m), flush=True)
    if args.json:
        atomic_write_bytes(args.json, json.dumps(results, indent=1, default=float).encode())


if __name__ == "__main__":
    run(main)
