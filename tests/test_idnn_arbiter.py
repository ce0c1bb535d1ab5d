"""The IDNN's history arbiter (issue 62 point 2): per outage, a share of the INS DR's displacement
(none, half, all) where the drive's own pseudo-outages over the GNSS before it show the INS DR's
displacement nearer the truth than the network's, shrunk toward a prior that favours the network;
and the gyro's yaw rate where they show its heading nearer the truth's.

* The phone lying flat (``tests/data/real``): the shipped model's displacement CRSE is above the INS
  DR's there (13.75 against 11.55 m at 10 s without the arbiter); the pseudo-outages before most
  outages say so, and the arbiter takes half the INS DR's displacement there.
* The roof MEMS IMU: the network beats the INS DR by half; the arbiter keeps the network's
  displacement on every outage, bit for bit, and takes the 100 Hz gyro's yaw rate.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.gnss_quality import GnssLimits
from ionav_viz.learning.idnn import IdnnEstimator
from ionav_viz.nav.history_check import past_choice

CORPUS_DIR = Path(__file__).parent / "data" / "real"
CORPUS = json.loads((CORPUS_DIR / "corpus.json").read_text())


def test_an_alternative_is_taken_only_when_its_past_beats_the_prior():
    """Three pseudo-outages ending at windows 5, 10 and 15; the default erred 1 m on each, the
    alternative 0.2 m. Outages at windows 4 (none behind), 12 (two behind) and 20 (three):
    with the prior 'twice the default' the alternative scores (3 x 2 x 1 + 0.4) / 5 = 1.28 and
    (6 + 0.6) / 6 = 1.1, both above the default's 1; with the prior 'as good' (3 + 0.4) / 5 = 0.68
    and (3 + 0.6) / 6 = 0.6, below."""
    ends = np.array([10, 5, 15])  # in any order
    err = np.array([[1.0, 1.0, 1.0], [0.2, 0.2, 0.2]])
    starts = np.array([4, 12, 20])
    choice, sums, count = past_choice(ends, err, starts, np.array([1.0, 2.0]))
    assert choice.tolist() == [0, 0, 0]
    assert count.tolist() == [0, 2, 3]
    np.testing.assert_allclose(sums, [[0.0, 2.0, 3.0], [0.0, 0.4, 0.6]])
    choice, _, _ = past_choice(ends, err, starts, np.array([1.0, 1.0]))
    assert choice.tolist() == [0, 1, 1]


def load(log: str) -> iv.Drive:
    entry = CORPUS["logs"][log]
    options = iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", **dict(entry.get("log", {})))
    limits = (GnssLimits() if entry.get("max_sigma_m") is None
              else dataclasses.replace(GnssLimits(), max_sigma_m=entry["max_sigma_m"]))
    return iv.load_drive(str(CORPUS_DIR / entry["file"]), iv.ReadOptions(log=options, gnss_limits=limits))


def crse(report: iv.Report, name: str) -> np.ndarray:
    return np.array([s[name]["crse_m"] for s in report.to_dict()["sequences"]])


@pytest.fixture(scope="module")
def phone():
    drive = load("phone_flat_meszdav")
    on, off = IdnnEstimator(), IdnnEstimator(arbiter=False)
    with_arbiter = iv.evaluate([drive], 10, estimators=["ins", on])
    without = iv.evaluate([drive], 10, estimators=[off])
    return with_arbiter, without, on.describe()["arbiter"], (on.describe(), off.describe())


def test_on_the_phone_the_arbiter_takes_the_ins_drs_displacement_where_the_past_says_so(phone):
    with_arbiter, without, note, _ = phone
    ins, on, off = crse(with_arbiter, "ins"), crse(with_arbiter, "idnn"), crse(without, "idnn")
    assert off.mean() > ins.mean()  # the shipped model's network loses to the INS DR on this phone
    assert on.mean() < off.mean() - 0.5, (on.mean(), off.mean())
    # each outage is the network's, the INS DR's, or half of each; the note counts them
    kept = int(re.match(r"the network's displacement on (\d+) outage", note).group(1))
    halved = int(re.search(r"50 % of the INS DR's on (\d+) outage", note).group(1))
    taken = int(m.group(1)) if (m := re.search(r"100 % of the INS DR's on (\d+) outage", note)) else 0
    assert kept + halved + taken == len(on) and kept >= 1 and halved >= 1, note
    assert int(np.sum(on == ins)) >= taken, note  # the INS DR's own displacement where it is taken whole
    assert on[0] == off[0]  # the first outage has no pseudo-outage behind it: the network, as trained


def test_the_text_report_says_what_the_idnns_arbiter_chose(phone):
    with_arbiter, without, note, _ = phone
    assert f"IDNN arbiter: {note}" in with_arbiter.to_text()
    assert "IDNN arbiter:" not in without.to_text()
    assert [e["info"]["arbiter"] for e in with_arbiter.to_dict()["estimators"] if e["name"] == "idnn"] == [note]


def test_the_ellipse_is_judged_on_the_estimates_the_arbiter_gives_the_outages(phone):
    """The history check scales the covariance by the NEES on pseudo-outages over the GNSS: each run
    as an outage starting there would be, with the arbiter's choice from the ones before it. On the
    phone the arbiter's choices err less there than the network alone (above), so their NEES is lower
    and the scale narrower than without the arbiter, on the same 26 pseudo-outages; judged on the
    network's own estimates both would be equal."""
    import re

    with_arbiter, without = (d["uncertainty_scale"] for d in phone[3])
    pattern = r"x([\d.]+) median, .* per degree of freedom ([\d.]+) on (\d+) pseudo-outages"
    (scale_on, nees_on, k_on), (scale_off, nees_off, k_off) = (re.search(pattern, n).groups() for n in (with_arbiter, without))
    assert k_on == k_off == "26"
    assert float(nees_on) < 0.9 * float(nees_off) and float(scale_on) < float(scale_off), (with_arbiter, without)


def test_where_the_network_beats_the_ins_dr_the_arbiter_keeps_its_displacement_and_takes_the_truer_heading():
    """The roof MEMS IMU: the network's displacement on every outage, as trained (its inputs with the
    filter's road grade) on all but the few whose past pseudo-outages said otherwise; its yaw rate
    (trained on 10 Hz simulated drives) turns the heading further from the fixes' on the pseudo-outages
    than the 100 Hz gyro's, so the gyro's is taken there, and the final errors fall."""
    drive = load("roof_mems_rtk")
    on = IdnnEstimator()
    a = iv.evaluate([drive], 10, estimators=[on])
    b = iv.evaluate([drive], 10, estimators=[IdnnEstimator(arbiter=False)])
    n = len(a.to_dict()["sequences"])
    note = on.describe()["arbiter"]
    assert note.startswith(f"the network's displacement on {n} outages, ") and "% of the INS DR's" not in note, note
    flat = int(m.group(1)) if (m := re.search(r"without the filter's road grade on (\d+) outage", note)) else 0
    assert flat <= n // 10 and "the gyro's yaw rate on " in note, note
    assert int(np.sum(crse(a, "idnn") != crse(b, "idnn"))) == flat
    final = {k: np.array([s["idnn"]["final_position_error_m"] for s in r.to_dict()["sequences"]]) for k, r in (("a", a), ("b", b))}
    assert final["a"].mean() < final["b"].mean(), (final["a"].mean(), final["b"].mean())


def test_on_the_held_out_phone_the_inputs_leave_the_filters_grade_out_where_the_past_says_so():
    """The held-out phone: the GNSS-aided filter's road grade follows the phone's receiver speed
    (+1.1 m/s^2 after a stretch without usable fixes), and the network fed with it runs away; its past
    pseudo-outages say so, and most 30 s outages take the inputs without it. The roof's RTK-fed grade
    is kept (above)."""
    on = IdnnEstimator()
    iv.evaluate([load("phone_flat_meszdav_q2")], 30, estimators=["ins", on])
    note = on.describe()["arbiter"]
    flat = re.search(r"without the filter's road grade on (\d+) outages \(their past 10 s pseudo-outages' "
                     r"1 m \+ displacement CRSE ([\d.]+) % lower without it, geometric mean\)", note)
    assert flat and int(flat.group(1)) >= 4 and float(flat.group(2)) > 0, note


def worse_beyond_spread(baseline: np.ndarray, candidate: np.ndarray) -> bool:
    """Whether the candidate's mean is above the baseline's beyond the outages' spread: the 95 %
    interval of a paired bootstrap of the difference (outages where either is undefined left out)
    lies wholly above zero."""
    from ionav_viz.analysis.evaluate import paired_bootstrap_means

    both = np.isfinite(baseline) & np.isfinite(candidate)
    mb, mc = paired_bootstrap_means(baseline[both], candidate[both])
    return bool(np.percentile(mc - mb, 2.5) > 0)


#: Corpus logs and lengths where the shipped model is worse than the INS DR beyond the spread (none
#: since the arbiter chooses whether the inputs keep the filter's road grade; the held-out phone's
#: 10 and 30 s were, docs/real-imu-logs.md, "The held-out phone drive").
HELD_OUT_MISSES: dict[tuple[str, int], str] = {}


@pytest.mark.parametrize(("log", "length"), [
    pytest.param(log, length, marks=pytest.mark.xfail(strict=True, reason=HELD_OUT_MISSES[log, length]))
    if (log, length) in HELD_OUT_MISSES else (log, length)
    for log in sorted(CORPUS["logs"]) for length in (10, 30) if str(length) in CORPUS["logs"][log]["envelope"]])
def test_untuned_the_shipped_idnn_is_no_worse_than_the_ins_dr_on_each_corpus_log(log, length):
    """Issue 62 point 2 on the corpus: the shipped model, not fine-tuned, IMU only, on 10 and 30 s
    outages tiled over each log: neither its displacement CRSE nor its final error (% of the distance)
    above the INS DR's beyond the outages' spread. The phone's final error at 10 s was (+2.0 points,
    interval +0.6 to +3.7) while its network's yaw rate stood on every outage; its heading now comes
    from the gyro where the pseudo-outages before show the gyro's heading truer."""
    report = iv.evaluate([load(log)], length, estimators=["ins", "idnn"]).to_dict()
    for metric in ("crse_m", "final_error_pct"):
        ins, idnn = (np.array([s[name][metric] for s in report["sequences"]], dtype=float) for name in ("ins", "idnn"))
        assert not worse_beyond_spread(ins, idnn), (metric, round(float(np.nanmean(idnn)), 2), round(float(np.nanmean(ins)), 2))


def test_a_long_outage_with_little_history_of_its_length_is_judged_on_the_10_s_ones():
    drive = load("phone_flat_meszdav")
    on = IdnnEstimator()
    iv.evaluate([drive], 30, estimators=[on])
    assert "with fewer than 4 behind them judged on the 10 s ones" in on.describe()["arbiter"]


def test_the_recordings_details_say_what_the_idnns_arbiter_chose(phone, tmp_path):
    from tests.conftest import run_cli
    from tests.test_real_logs import summary_of

    entry = CORPUS["logs"]["phone_flat_meszdav"]
    rrd = tmp_path / "phone.rrd"
    proc = run_cli("replay", str(CORPUS_DIR / entry["file"]), "--outage", "10s", "--imu-mount", "auto",
                   "--gnss-limit", f"max_sigma_m={entry['max_sigma_m']}", "--estimators", "ins,idnn", "-o", str(rrd), "-q")
    assert proc.returncode == 0, proc.stderr
    _, _, note, _ = phone  # the same drive and outages through the API
    assert f"**IDNN arbiter**: {note}" in summary_of(rrd)
