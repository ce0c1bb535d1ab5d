"""gins's history arbiter (:func:`ionav_viz.nav.gins.arbitrate`): per outage, the propagation whose
pseudo-outages over the GNSS before it ended nearest the fixes, shrunk toward gins's own.

* A good IMU (the simulated roof MEMS): its 3D strapdown ends pseudo-outages metres from the fixes
  where a planar DR of a 10 Hz gyro and accelerometer ends tens of metres off (the INS DR's 15-30 %
  of the distance against gins's 1-4 % in docs/results.md), and holding roll and pitch throws away
  what a good gyro measures: the arbiter keeps the default on every outage and the output is the
  arbiter-free filter's, bit for bit.
* A log built to break the filter (single readings, a holder wobbling 2.5 times the phone grade's,
  a clock 0.3 s off that the user said is 0), braking hard for 10 min: on 30 s outages the
  reduced filter integrates the holder's tilt under braking into its speed, the planar DR's past
  pseudo-outages end nearer the fixes, and once enough of them lie behind an outage the arbiter
  takes the planar DR there. The outages before that keep gins's own, so gins ends nearer the INS
  DR than without the arbiter, not yet at or below it (issue 41 point 7, a strict xfail).
  What breaks it, each switched alone on this drive (30 s outages, gins without the arbiter vs the
  INS DR): the holder's tilt under acceleration (0.4 deg per m/s^2), and in it the tilt's settling
  (0.3 s): without the tilt 14.6 against 18.2 % (the clock still 0.3 s off); with it and the clock
  right 19.2 against 16.4 %; settling in 0.01 s 15.8 against 16.4 %; half the tilt 11.5 against
  17.2 %. Not the forward scale error the tilt makes: the accelerometer scaled by 0.93-1.07 ends
  worse (21.4-22.6 %); nor the snapshot of roll and pitch the outage starts from: held through
  the outage, 21.3 %.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.nav.gins import GinsEstimator
from ionav_viz.sim.imu import IMU_GRADES, SIM_TRUTH_TOPIC, write_imu_log

pytestmark = pytest.mark.xdist_group("consumer_imu")

LOG = iv.LogOptions(imu_mount="auto", truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none")


def _pct(rep, name: str) -> float:
    return rep.summary[name]["final_error_pct"]["mean"]


def test_on_a_good_imu_the_arbiter_keeps_gins_on_every_outage(tmp_path):
    path = write_imu_log(tmp_path / "mems.mcap", "roundabout", 5, 300.0, "mems")
    drive = iv.load_drive(path, iv.ReadOptions(log=LOG))
    for length in (10.0, 30.0):
        on, off = GinsEstimator(), GinsEstimator(arbiter=False)
        a = iv.evaluate([drive], length, estimators=[on]).to_dict()
        b = iv.evaluate([drive], length, estimators=[off]).to_dict()
        n = len(a["sequences"])
        assert on.describe()["arbiter"].startswith(f"3D on {n} outages;"), on.describe()["arbiter"]
        assert "arbiter" not in off.describe()
        ea = np.array([s["gins"]["final_position_error_m"] for s in a["sequences"]])
        eb = np.array([s["gins"]["final_position_error_m"] for s in b["sequences"]])
        np.testing.assert_array_equal(ea, eb)


@pytest.fixture(scope="module")
def loose_holder(tmp_path_factory):
    # the phone grade's receiver before its speed lag and its losses were measured: the drive this
    # arbiter was written on; with the lag (0.7 s) gins ends it at 19.3 % with the arbiter, 19.1 % without
    grade = replace(IMU_GRADES["phone"], holder_wobble_dps=4.0, clock_offset_s=0.3, gnss_speed_lag_s=0.0, gnss_losses_per_10min=0.0)
    path = write_imu_log(tmp_path_factory.mktemp("loose") / "loose.mcap", "hard-brake", 904, 600.0, grade)
    drive = iv.load_drive(path, iv.ReadOptions(log=replace(LOG, imu_time_offset="0")))
    on, off = GinsEstimator(), GinsEstimator(arbiter=False)
    rep_on = iv.evaluate([drive], 30.0, estimators=["ins", on])
    rep_off = iv.evaluate([drive], 30.0, estimators=[off])
    return rep_on, rep_off, on.describe()["arbiter"]


def test_on_a_log_built_to_break_the_filter_the_arbiter_takes_the_planar_dr_where_its_past_says_so(loose_holder):
    rep_on, rep_off, note = loose_holder
    ins, on, off = _pct(rep_on, "ins"), _pct(rep_on, "gins"), _pct(rep_off, "gins")
    assert off > ins  # without it the filter loses to the INS DR here
    assert "planar DR (the INS DR's propagation) on" in note, note
    assert on < off, (on, off)
    # the first outages have no past pseudo-outage of 30 s after the alignment: gins's own there
    first_on = rep_on.to_dict()["sequences"][0]["gins"]["final_position_error_m"]
    first_off = rep_off.to_dict()["sequences"][0]["gins"]["final_position_error_m"]
    assert first_on == first_off


def test_the_text_report_says_what_the_arbiter_chose_on_one_drive(loose_holder):
    rep_on, rep_off, note = loose_holder
    text = rep_on.to_text()
    assert f"GNSS/INS 3D arbiter: {note}" in text
    assert "planar DR (the INS DR's propagation) on" in text
    assert "GNSS/INS 3D arbiter:" not in rep_off.to_text()  # without the arbiter there is nothing to say


@pytest.mark.xfail(strict=True, reason="issue 41 point 7, open: the arbiter needs past pseudo-outages; the outages before "
                   "them keep gins's own, and gins ends this drive's 30 s outages at 19.6 % against the INS DR's 16.6 %")
def test_on_a_log_built_to_break_the_filter_gins_with_the_arbiter_ends_at_or_below_the_ins_dr(loose_holder):
    rep_on, _, _ = loose_holder
    assert _pct(rep_on, "gins") <= _pct(rep_on, "ins")


def test_a_long_outage_with_little_history_of_its_length_is_judged_on_the_10_s_pseudo_outages(tmp_path):
    """A 3-minute drive holds at most two 60 s pseudo-outages before any outage (too few to switch
    on under the prior), but a dozen of 10 s: the arbiter judges its 60 s outages on those and says
    so. Here (a holder phone going round, where gins's own propagation ends 10 s pseudo-outages
    nearer the fixes than the planar DR) they keep gins's own, bit for bit."""
    grade = replace(IMU_GRADES["phone"], holder_wobble_dps=4.0)
    drive = iv.load_drive(write_imu_log(tmp_path / "round.mcap", "roundabout", 905, 180.0, grade), iv.ReadOptions(log=LOG))
    on, off = GinsEstimator(), GinsEstimator(arbiter=False)
    a = iv.evaluate([drive], 60.0, estimators=[on]).to_dict()
    b = iv.evaluate([drive], 60.0, estimators=[off]).to_dict()
    n = len(a["sequences"])
    assert n >= 2
    assert f"{n} outages with fewer than 4 behind them judged on the 10 s ones" in on.describe()["arbiter"], on.describe()["arbiter"]
    assert on.describe()["arbiter"].startswith(f"reduced on {n} outages;")
    np.testing.assert_array_equal([s["gins"]["final_position_error_m"] for s in a["sequences"]],
                                  [s["gins"]["final_position_error_m"] for s in b["sequences"]])
