"""How the GNSS-aided INS (``ekf``) compares with the paper's INS DR on the bundled test drives,
with the drives' vehicle speed left out (the filter on GNSS and IMU alone), for its noise values.

    python benchmarks/ekf_tuning.py [accel_offset_walk_mps2=0.1 gnss_speed_mps=0.05 ...]

Prints per scenario the mean displacement CRSE and final position error of both, and their ratio.
"""

from __future__ import annotations

import logging
import sys
from dataclasses import replace

import ionav_viz as iv
from ionav_viz.core.drive import Drive
from ionav_viz.nav.ekf import EkfEstimator, EkfNoise

SCENARIOS = ("motorway", "roundabout", "quick-accel", "hard-brake", "sharp-cornering")


def without_vehicle_speed(drive: Drive) -> Drive:
    cols = {k: v for k, v in drive.columns.items() if not k.startswith("wheel_speed") and k != "speed_can_mps"}
    out = Drive(drive.name, drive.source, drive.rate_hz, drive.start_time_of_day_s, cols)
    out.gnss_fault = drive.gnss_fault
    return out


def main(overrides: list[str]) -> None:
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    noise = replace(EkfNoise(), **{k: float(v) for k, v in (o.split("=") for o in overrides)})
    print(f"{'scenario':16s} {'INS CRSE':>9s} {'EKF CRSE':>9s} {'ratio':>6s} {'INS final':>10s} {'EKF final':>10s}")
    for scenario in SCENARIOS:
        drive = without_vehicle_speed(iv.load_drive(scenario))
        s = iv.evaluate([drive], 10.0, estimators=["ins", EkfEstimator(noise)]).to_dict()["summary"]
        a, b = s["ins"]["crse_m"]["mean"], s["ekf"]["crse_m"]["mean"]
        fa, fb = s["ins"]["final_position_error_m"]["mean"], s["ekf"]["final_position_error_m"]["mean"]
        print(f"{scenario:16s} {a:9.2f} {b:9.2f} {b / a:6.2f} {fa:10.2f} {fb:10.2f}")


if __name__ == "__main__":
    main(sys.argv[1:])
