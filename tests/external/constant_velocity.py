"""A filter outside ionav-viz (it imports none of it): constant velocity through GNSS gaps.

    python constant_velocity.py OUTAGED.mcap TRAJECTORY.csv

Reads a ROS 2 MCAP's ``/gps/fix`` and ``/gps/vel`` (east, north m/s) and its ``/imu/data``
stamps; writes ``time_s,lat_deg,lon_deg``: the fixes themselves where there are any, and inside a
gap in the fixes (longer than 0.5 s), at every IMU stamp, the last fix moved along the geodesic at
its course by its speed times the time since it. Stamps: the header stamps, UNIX seconds.
"""

from __future__ import annotations

import math
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from pyproj import Geod


def main(log: str, out: str) -> None:
    fixes, vel, imu = [], {}, []
    with open(log, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages(topics=["/gps/fix", "/gps/vel", "/imu/data"]):
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            if channel.topic == "/gps/fix" and msg.status.status >= 0:
                fixes.append((stamp, msg.latitude, msg.longitude))
            elif channel.topic == "/gps/vel":
                vel[round(stamp, 6)] = (msg.twist.linear.x, msg.twist.linear.y)
            elif channel.topic == "/imu/data":
                imu.append(stamp)
    fixes.sort()
    imu.sort()
    geod = Geod(ellps="WGS84")
    rows = []
    for (t0, lat0, lon0), (t1, _, _) in zip(fixes, fixes[1:] + [(math.inf, 0.0, 0.0)]):
        rows.append((t0, lat0, lon0))
        if t1 - t0 <= 0.5:
            continue
        east, north = vel[round(t0, 6)]
        speed, course = math.hypot(east, north), math.degrees(math.atan2(east, north))
        for t in (s for s in imu if t0 < s < t1):
            lon, lat, _ = geod.fwd(lon0, lat0, course, speed * (t - t0))
            rows.append((t, lat, lon))
    with open(out, "w") as f:
        f.write("time_s,lat_deg,lon_deg\n")
        f.writelines(f"{t:.9f},{lat:.12f},{lon:.12f}\n" for t, lat, lon in rows)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
