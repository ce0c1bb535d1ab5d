"""The IDNN's uncertainty on held-out drives: how often the final position error of an outage lies
inside the estimate's 95 % ellipse, and the mean NEES (normalised estimation error squared; 2 for
a consistent 2D covariance), at each outage length.

    python benchmarks/idnn_uncertainty.py [--model DIR] [--minutes 10] [--seed-base 800] [--lengths 10,30]
    python benchmarks/idnn_uncertainty.py --bundled      # the bundled test drives instead

Drives: the held-out fleet of ``benchmarks/results_table.py`` (one per scenario, seed ``--seed-base``
+ scenario index; ``ionav-viz simulate SCENARIO --fleet held-out --seed SEED --duration 10m -o FILE``),
outages tiled after the default warm-up, as ``ionav-viz evaluate`` places them; the final error is
measured against the GNSS fix at the outage's end, in the local east/north frame.
"""

from __future__ import annotations

import argparse
import logging
import tempfile
from pathlib import Path

import numpy as np
from _cli import add_debug, check_model, lengths_s, run
from results_table import held_out_drives

import ionav_viz as iv
from ionav_viz.core.geo import wgs84
from ionav_viz.dataset.samples import SAMPLES, sample_path
from ionav_viz.learning.idnn import IdnnEstimator
from ionav_viz.learning.training import CHI2_2_95


def final_nees(result) -> np.ndarray:
    """NEES of each outage's final position error under the IDNN's covariance."""
    sol = result.estimates["idnn"]
    last = result.starts + result.n_windows - 1
    w = result.windows
    az, _, dist = wgs84().inv(w.lon1_deg[last], w.lat1_deg[last], sol.track.lon_deg[:, -1], sol.track.lat_deg[:, -1])
    az = np.deg2rad(np.asarray(az))
    err = np.stack([dist * np.sin(az), dist * np.cos(az)], axis=-1)
    return np.einsum("na,nab,nb->n", err, np.linalg.inv(sol.pos_cov_m2[:, -1]), err)


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--model", default=None, help="model directory (default: the shipped model)")
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seed-base", type=int, default=800)
    parser.add_argument("--lengths", default="10,30")
    parser.add_argument("--bundled", action="store_true", help="the bundled test drives (the training fleet's car) instead")
    args = parser.parse_args()
    check_model(args.model)
    logging.disable(logging.WARNING)
    lengths = [int(x) for x in lengths_s(args.lengths)]
    with tempfile.TemporaryDirectory() as tmp:
        if args.bundled:
            drives = {s.scenario: sample_path(s) for s in SAMPLES if s.role == "test"}
            print(f"bundled test drives: {len(drives)}")
        else:
            drives = held_out_drives(Path(tmp), args.minutes, args.seed_base)
            print(f"held-out drives: {len(drives)} of {args.minutes:g} min, seeds {args.seed_base}-{args.seed_base + len(drives) - 1}")
        print("outage_s  outages  inside_95%  mean_NEES  median_NEES")
        for length in lengths:
            q = []
            for path in drives.values():
                est = IdnnEstimator(args.model)
                result = iv.evaluate(str(path), outage_s=length, estimators=[est])
                q.extend(final_nees(res) for res in result.results)
            q = np.concatenate(q)
            print(f"{length:>8}  {len(q):>7}  {100 * np.mean(q <= CHI2_2_95):>9.1f}%  {np.mean(q):>9.2f}  {np.median(q):>11.2f}")


if __name__ == "__main__":
    run(main)
