"""ROS 2 MCAP (outaged log) -> KF-GINS input files and config. Uses only mcap / mcap_ros2 / numpy.

    python mcap_to_kfgins.py cut.mcap OUTDIR [--imu-topic /imu/data_raw] [--gnss-topic /gps/fix] [--vel-topic /gps/vel]

Writes OUTDIR/imu.txt, OUTDIR/gnss.txt, OUTDIR/kf-gins.yaml, OUTDIR/time_offset.json.

Conventions:
- times: header stamps (UNIX s) minus OFFSET = the UTC midnight before the first IMU stamp, because
  KF-GINS refuses end times > 604800 s (it expects GPS seconds of week). kfgins_to_csv.py adds it back.
- IMU: sensor_msgs/Imu in REP 103 FLU (x forward, y left, z up) -> KF-GINS FRD: (x, -y, -z).
  Increments over (t[i-1], t[i]]: trapezoid of the two rate samples times dt (dt = stamp difference;
  the first sample uses 1/rate).
- GNSS: NavSatFix lat/lon/alt; position_covariance is ENU (ROS), so std N = sqrt(c[4]),
  E = sqrt(c[0]), D = sqrt(c[8]).
- Initial state: position = first fix; velocity and heading from the first /gps/vel (ENU -> NED);
  roll = pitch = 0.
- IMU white noise (ARW, VRW) from the Imu messages' own covariances: sigma * sqrt(1/rate).
"""

from __future__ import annotations

import argparse
import json
import math
import os

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("log")
    ap.add_argument("outdir")
    ap.add_argument("--imu-topic", default="/imu/data_raw")
    ap.add_argument("--gnss-topic", default="/gps/fix")
    ap.add_argument("--vel-topic", default="/gps/vel")
    ap.add_argument("--head-std-deg", type=float, default=2.0)
    # IMU error model; defaults: ARW/VRW from the Imu messages' covariances, the rest KF-GINS's config/ MEMS example
    ap.add_argument("--arw", type=float, help="deg/sqrt(h)")
    ap.add_argument("--vrw", type=float, help="m/s/sqrt(h)")
    ap.add_argument("--gbstd", type=float, default=50.0, help="deg/h")
    ap.add_argument("--abstd", type=float, default=250.0, help="mGal")
    ap.add_argument("--gsstd", type=float, default=1000.0, help="ppm")
    ap.add_argument("--asstd", type=float, default=1000.0, help="ppm")
    ap.add_argument("--corrtime", type=float, default=1.0, help="h")
    ap.add_argument("--static-gyro-bias", action="store_true",
                    help="initial gyro bias = mean gyro over the first stationary stretch (GNSS speed < 0.1 m/s)")
    args = ap.parse_args()
    os.makedirs(args.outdir, exist_ok=True)

    imu, fixes, vels = [], [], []
    gyr_var, acc_var = [], []
    with open(args.log, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, ch, _, m in reader.iter_decoded_messages(topics=[args.imu_topic, args.gnss_topic, args.vel_topic]):
            t = stamp(m)
            if ch.topic == args.imu_topic:
                w, a = m.angular_velocity, m.linear_acceleration
                imu.append((t, w.x, w.y, w.z, a.x, a.y, a.z))
                if len(gyr_var) < 1000:
                    gyr_var.append(m.angular_velocity_covariance[0])
                    acc_var.append(m.linear_acceleration_covariance[0])
            elif ch.topic == args.gnss_topic:
                if m.status.status < 0:  # no fix
                    continue
                c = m.position_covariance
                fixes.append((t, m.latitude, m.longitude, m.altitude, math.sqrt(c[4]), math.sqrt(c[0]),
                              math.sqrt(c[8])))
            else:
                v = m.twist.linear
                vels.append((t, v.x, v.y, v.z))
    imu = np.array(sorted(imu))
    fixes = np.array(sorted(fixes))
    vels = np.array(sorted(vels))
    # drop duplicate IMU stamps, if any
    keep = np.concatenate([[True], np.diff(imu[:, 0]) > 0])
    imu = imu[keep]

    offset = math.floor(imu[0, 0] / 86400.0) * 86400.0
    t = imu[:, 0] - offset
    dt_nom = float(np.median(np.diff(t)))
    rate = int(round(1.0 / dt_nom))
    # FLU -> FRD
    gyro = imu[:, 1:4] * np.array([1.0, -1.0, -1.0])
    acc = imu[:, 4:7] * np.array([1.0, -1.0, -1.0])
    dt = np.diff(t, prepend=t[0] - 1.0 / rate)
    g_prev = np.vstack([gyro[:1], gyro[:-1]])
    a_prev = np.vstack([acc[:1], acc[:-1]])
    dtheta = 0.5 * (g_prev + gyro) * dt[:, None]
    dvel = 0.5 * (a_prev + acc) * dt[:, None]
    with open(os.path.join(args.outdir, "imu.txt"), "w") as f:
        for i in range(len(t)):
            f.write("{:.9f} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e}\n".format(t[i], *dtheta[i], *dvel[i]))
    with open(os.path.join(args.outdir, "gnss.txt"), "w") as f:
        for r in fixes:
            f.write("{:.9f} {:.11f} {:.11f} {:.4f} {:.4f} {:.4f} {:.4f}\n".format(r[0] - offset, *r[1:]))

    # initial state
    start = float(t[0])
    fix0 = fixes[0]
    v0 = vels[np.argmin(np.abs(vels[:, 0] - fix0[0]))]
    ve, vn, vu = v0[1:4]
    heading = math.degrees(math.atan2(ve, vn)) % 360.0
    gyr_sigma = math.sqrt(float(np.median(gyr_var))) if np.median(gyr_var) > 0 else 0.002
    acc_sigma = math.sqrt(float(np.median(acc_var))) if np.median(acc_var) > 0 else 0.05
    arw = gyr_sigma * math.sqrt(1.0 / rate) * 180.0 / math.pi * 60.0  # deg/sqrt(h)
    vrw = acc_sigma * math.sqrt(1.0 / rate) * 60.0  # m/s/sqrt(h)
    arw = args.arw if args.arw is not None else arw
    vrw = args.vrw if args.vrw is not None else vrw
    bg0 = [0.0, 0.0, 0.0]
    if args.static_gyro_bias:
        moving = vels[np.hypot(vels[:, 1], vels[:, 2]) >= 0.1, 0]
        still_end = float(moving[0]) if len(moving) else float(vels[-1, 0])
        still = (imu[:, 0] <= still_end)
        if still.sum() >= 50:
            bg0 = list(gyro[still].mean(axis=0) * 180.0 / math.pi * 3600.0)  # FRD, deg/h
        print(f"static stretch: {still.sum()} IMU samples up to {still_end - imu[0, 0]:.2f} s; "
              f"initial gyro bias {bg0} deg/h")
    cfg = f"""# generated by mcap_to_kfgins.py from {os.path.abspath(args.log)}
# times = UNIX header stamps - {offset:.1f}
imupath: "{os.path.abspath(os.path.join(args.outdir, 'imu.txt'))}"
gnsspath: "{os.path.abspath(os.path.join(args.outdir, 'gnss.txt'))}"
outputpath: "{os.path.abspath(args.outdir)}"
imudatalen: 7
imudatarate: {rate}
starttime: {start:.9f}
endtime: -1
initpos: [ {fix0[1]:.11f}, {fix0[2]:.11f}, {fix0[3]:.4f} ]
initvel: [ {vn:.6f}, {ve:.6f}, {-vu:.6f} ]
initatt: [ 0.0, 0.0, {heading:.6f} ]
initgyrbias: [ {bg0[0]:.3f}, {bg0[1]:.3f}, {bg0[2]:.3f} ]
initaccbias: [ 0, 0, 0 ]
initgyrscale: [ 0, 0, 0 ]
initaccscale: [ 0, 0, 0 ]
initposstd: [ {fix0[4]:.3f}, {fix0[5]:.3f}, {fix0[6]:.3f} ]
initvelstd: [ 0.1, 0.1, 0.1 ]
initattstd: [ 1.0, 1.0, {args.head_std_deg:.3f} ]
imunoise:
  arw: [{arw:.4f}, {arw:.4f}, {arw:.4f}]          # deg/sqrt(h)
  vrw: [{vrw:.4f}, {vrw:.4f}, {vrw:.4f}]          # m/s/sqrt(h)
  gbstd: [{args.gbstd}, {args.gbstd}, {args.gbstd}]        # deg/h
  abstd: [{args.abstd}, {args.abstd}, {args.abstd}]     # mGal
  gsstd: [{args.gsstd}, {args.gsstd}, {args.gsstd}]  # ppm
  asstd: [{args.asstd}, {args.asstd}, {args.asstd}]  # ppm
  corrtime: {args.corrtime}                    # h
antlever: [ 0.0, 0.0, 0.0 ]
"""
    with open(os.path.join(args.outdir, "kf-gins.yaml"), "w") as f:
        f.write(cfg)
    with open(os.path.join(args.outdir, "time_offset.json"), "w") as f:
        json.dump({"offset_s": offset, "first_imu_stamp_s": float(imu[0, 0]), "rate_hz": rate}, f, indent=1)
    print(f"IMU {len(t)} rows @ {rate} Hz, GNSS {len(fixes)} fixes, offset {offset:.1f} s, start {start:.6f}, "
          f"heading {heading:.2f} deg, v0 NED ({vn:.3f}, {ve:.3f}, {-vu:.3f}), arw {arw:.3f} deg/sqrt(h), "
          f"vrw {vrw:.3f} m/s/sqrt(h)")


if __name__ == "__main__":
    main()
