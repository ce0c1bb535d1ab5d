"""Benchmark: the 3D GNSS/INS ``gins`` over a long simulated 6-axis drive.

    python benchmarks/bench_gins.py                 # a 1 h motorway drive, MEMS IMU
    python benchmarks/bench_gins.py --hours 3 --outage 30

Prints the IMU samples per second of the filter's pass over the drive with GNSS (everything the
estimator does before the outages: the boundaries, the stillness detector, the noise measurement
and the compiled filter) and of the whole estimate (the pass and every tiled outage run without
GNSS), on two forms of the same drive:

* the drive at the IMU's 100 Hz, as :mod:`ionav_viz.sim.imu` makes it;
* the drive as a message-log reader gives it: 10 Hz means of the IMU (every log reader bins
  to the 10 Hz grid), where each sample is an increment of 0.1 s.

Target on our 2-core machine: the pass at >= 1 million IMU samples/s. Timings are the best of
``--repeat`` runs after a first run that compiles (numba caches to ``__pycache__``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ionav_viz.core.drive import IMU_COLUMNS, Drive
from ionav_viz.core.grid import GRID_RATE_HZ, GRID_STEP_S
from ionav_viz.experiment.outages import tile
from ionav_viz.nav.bias import SensorBias
from ionav_viz.nav.gins import GinsEstimator
from ionav_viz.nav.protocol import EstimatorInputs
from ionav_viz.nav.windows import make_windows
from ionav_viz.sim.imu import imu_drive
from ionav_viz.sources.resample import ImuBins


def ten_hz(drive: Drive) -> Drive:
    """The drive as a log reader bins it: the reader's own 0.1 s means of the IMU
    (:class:`~ionav_viz.sources.resample.ImuBins`), the other columns taken at the nearest sample."""
    bins = ImuBins(GRID_STEP_S, False, lambda block: block)
    bins.add_block(np.column_stack([drive.t_s, *(drive.columns[c] for c in IMU_COLUMNS)]))
    t, means, _ = bins.means()
    nearest = np.clip(np.searchsorted(drive.t_s, t), 0, len(drive) - 1)
    columns = {name: values[nearest] for name, values in drive.columns.items() if name not in IMU_COLUMNS}
    columns |= dict(zip(IMU_COLUMNS, means.T, strict=True))
    columns |= {"t_s": t - t[0], "accel_long_mps2": means[:, 0], "yaw_rate_radps": means[:, 5]}
    return Drive(drive.name, drive.source, GRID_RATE_HZ, drive.start_time_of_day_s, columns)


def best_of(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--outage", type=float, default=10.0, help="outage length (s), tiling the drive")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    raw = imu_drive("motorway", 1, 3600.0 * args.hours, "mems").drive.as_received()
    for label, drive in (("100 Hz (the IMU's rate)", raw), ("10 Hz (as log readers bin it)", ten_hz(raw))):
        windows = make_windows(drive)
        n = int(args.outage)
        inputs = EstimatorInputs(drive, windows, tile(windows, n), n, SensorBias.none())
        gins = GinsEstimator()
        gins.estimate(inputs)  # compiles on the first run of a machine
        t_pass = best_of(args.repeat, lambda gins=gins, drive=drive, windows=windows: gins.run(drive, windows))
        t_all = best_of(args.repeat, lambda gins=gins, inputs=inputs: gins.estimate(inputs))
        samples = len(drive)
        print(f"{label}: {samples:,} samples, {inputs.n_outages} outages of {n} s")
        print(f"  pass with GNSS      {t_pass:6.3f} s   {samples / t_pass / 1e6:5.2f} M samples/s")
        print(f"  pass + outages      {t_all:6.3f} s   {samples / t_all / 1e6:5.2f} M drive samples/s (the outages run over the drive again)")


if __name__ == "__main__":
    main()
