import math

import numpy as np

from ionav_viz.core.drive import Drive
from ionav_viz.nav.windows import make_windows, segments

WGS84_A_M = 6378137.0


def _drive(t, lat, lon, heading, speed=None, accel=None, yaw=None):
    n = len(t)
    return Drive(
        "test", "memory", 10.0, 0.0,
        {
            "t_s": t, "lat_deg": lat, "lon_deg": lon,
            "speed_mps": np.full(n, 11.0) if speed is None else speed,
            "heading_deg": heading,
            "accel_long_mps2": np.zeros(n) if accel is None else accel,
            "yaw_rate_radps": np.zeros(n) if yaw is None else yaw,
        },
    )


def test_geodesic_displacement_along_the_equator():
    # 1e-4 degree of longitude per second along the equator: a * pi/180 * 1e-4 metres per second.
    t = np.arange(31) / 10.0
    d = _drive(t, np.zeros(31), 1e-4 * t, np.full(31, 90.0))
    w = make_windows(d)
    assert len(w) == 3
    expected_m = WGS84_A_M * math.pi / 180.0 * 1e-4  # 11.1319 m
    np.testing.assert_allclose(w.gnss_disp_m, expected_m, rtol=1e-9)


def test_gnss_yaw_rate_is_wrap_safe_and_counter_clockwise_positive():
    t = np.arange(21) / 10.0
    heading = np.mod(359.0 + 2.0 * t, 360.0)  # clockwise through north: a right turn
    d = _drive(t, np.zeros(21), 1e-4 * t, heading)
    w = make_windows(d)
    np.testing.assert_allclose(w.gnss_yaw_rate_radps, -math.radians(2.0), atol=1e-9)


def test_course_held_while_standing_still():
    t = np.arange(31) / 10.0
    speed = np.where(t < 1.5, 10.0, 0.0)
    heading = np.where(t < 1.5, 45.0, 200.0)  # a receiver's course jumps when standing
    d = _drive(t, np.zeros(31), np.zeros(31), heading, speed=speed)
    w = make_windows(d)
    np.testing.assert_allclose(w.gnss_yaw_rate_radps, 0.0)


def test_a_standing_receivers_speed_noise_does_not_give_the_drive_its_course():
    """A phone standing at the start reports 0.3-0.5 m/s of speed noise, and one fix of 1.4 m/s
    with a random course; the car then drives off east. The course before it moves is the course
    it drives off on (east), not the noise's, and no window turns."""
    t = np.arange(201) / 10.0
    speed = np.where(t < 10.0, 0.4, 5.0)
    heading = np.where(t < 10.0, 250.0, 90.0)
    speed[30:42], heading[30:42] = 1.4, 320.0  # the spike: 1.2 s above 1 m/s
    d = _drive(t, np.zeros(201), 1e-5 * np.maximum(t - 10.0, 0.0), heading, speed=speed)
    w = make_windows(d)
    np.testing.assert_allclose(w.heading0_deg, 90.0)
    np.testing.assert_allclose(w.gnss_yaw_rate_radps, 0.0, atol=1e-12)


def test_missing_sample_is_bridged_and_long_gap_splits():
    t = np.concatenate([np.arange(0, 2.05, 0.1), np.arange(10.0, 12.05, 0.1)])
    t = np.delete(t, 5)  # one 0.2 s period
    assert segments(t, 1.0) == [(0, 20), (20, 41)]
    n = len(t)
    d = _drive(t, np.zeros(n), 1e-4 * t, np.full(n, 90.0), accel=np.full(n, 0.5))
    w = make_windows(d)
    assert list(w.segment) == [0, 0, 1, 1]
    assert w.accel_mps2.shape == (4, 11)
    np.testing.assert_allclose(w.accel_mps2, 0.5)
    np.testing.assert_allclose(w.t0_s, [0.0, 1.0, 10.0, 11.0], atol=1e-9)


def test_the_speed_fitted_to_fixes_is_no_noisier_at_the_ends_of_the_record_or_of_a_gap():
    """1 Hz fixes of a car at a steady 10 m/s east, 1 m of white noise per axis, with no fixes from
    16 to 24 s (a tunnel). Mid-record, the local parabola through three fixes has a slope noise of
    sigma / sqrt(2) = 0.71 m/s; at the first fix, and at each side of the gap, a one-sided parabola
    through three fixes would have sqrt(9 + 16 + 1) / 2 sigma = 2.55 m/s, where one through seven
    has 0.68 m/s (the slope's entry of the inverse normal matrix of 1, t, t^2 / 2 at t = 0..6:
    0.4643, whose square root it is)."""
    from ionav_viz.sources.gnss_fixes import fit_fixes

    rng = np.random.default_rng(11)
    g_t = np.r_[np.arange(0.0, 16.0), np.arange(25.0, 41.0)]
    at = np.array([0.0, 8.0, 15.0, 25.0, 40.0])
    m_per_deg_lat, m_per_deg_lon = 111_250.0, 111_250.0 * math.cos(math.radians(52.0))
    errors = []
    for _ in range(400):
        east, north = 10.0 * g_t + rng.normal(0.0, 1.0, len(g_t)), rng.normal(0.0, 1.0, len(g_t))
        errors.append(fit_fixes(at, g_t, 52.0 + north / m_per_deg_lat, -1.5 + east / m_per_deg_lon).speed_mps - 10.0)
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    assert abs(rms[1] - 0.71) < 0.1, rms
    assert (np.abs(rms[[0, 2, 3, 4]] - 0.68) < 0.1).all(), rms
