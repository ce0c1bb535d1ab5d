import math

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.analysis.metrics import aeps, cae, crse, final_error_pct, summarise


def test_hand_computed_metrics():
    err = np.array([1.0, -2.0, 3.0, -0.5])
    assert crse(err) == pytest.approx(6.5)  # 1 + 2 + 3 + 0.5
    assert cae(err) == pytest.approx(1.5)  # 1 - 2 + 3 - 0.5
    assert aeps(err) == pytest.approx(6.5 / 4)


def test_metrics_per_row_of_a_batch():
    err = np.array([[1.0, 1.0], [-3.0, 1.0]])
    np.testing.assert_allclose(crse(err), [2.0, 4.0])
    np.testing.assert_allclose(cae(err), [2.0, -2.0])
    np.testing.assert_allclose(aeps(err), [1.0, 2.0])


def test_summary_uses_population_std_like_the_paper():
    s = summarise(np.array([1.0, 2.0, 3.0, 4.0]))
    assert s == pytest.approx({"max": 4.0, "min": 1.0, "mean": 2.5, "std": math.sqrt(1.25)})


def test_summary_of_nothing_is_nan():
    assert all(math.isnan(v) for v in summarise(np.zeros(0)).values())


def test_final_error_as_a_percentage_of_distance_driven():
    # 2 m off after 100 m is 2 %; 1 m off after 5 m is undefined (a car nearly standing)
    pct = final_error_pct(np.array([2.0, 1.0, 0.5]), np.array([100.0, 5.0, 10.0]))
    assert pct[0] == pytest.approx(2.0) and math.isnan(pct[1]) and pct[2] == pytest.approx(5.0)
    # the summary is over the outages where it is defined
    assert summarise(pct) == pytest.approx({"max": 5.0, "min": 2.0, "mean": 3.5, "std": 1.5})
    assert all(math.isnan(v) for v in summarise(np.array([np.nan])).values())


def test_an_outages_tracks_end_where_its_final_error_says_and_a_wrong_number_is_refused():
    """``EvaluationReport.outage_tracks`` (the figures' worst outage): every line starts on the local
    plane about the truth at the outage's start, and the estimate's last point lies the outage's
    final position error from the truth's (computed here from the two end points)."""
    rep = iv.evaluate("hard-brake", 10.0, estimators=["ins"])
    seqs = rep.to_dict()["sequences"]
    name = seqs[0]["drive"]
    for number in (1, len(seqs)):
        tracks = rep.outage_tracks(name, number)
        truth, est = tracks["truth"], tracks["ins"]
        assert truth["east_m"][0] == 0.0 and truth["north_m"][0] == 0.0 and len(truth["east_m"]) == 11
        end_m = np.hypot(est["east_m"][-1] - truth["east_m"][-1], est["north_m"][-1] - truth["north_m"][-1])
        assert end_m == pytest.approx(seqs[number - 1]["ins"]["final_position_error_m"], abs=0.01)
    for bad in (0, len(seqs) + 1):
        with pytest.raises(iv.InputError, match=f"no outage {bad}"):
            rep.outage_tracks(name, bad)
    with pytest.raises(iv.InputError, match="no evaluated drive"):
        rep.outage_tracks("elsewhere", 1)


def test_improvement_interval_of_a_constant_ratio_is_that_ratio():
    # a candidate at 0.3 times the baseline on every outage: every resample's improvement is 70 %
    from ionav_viz.analysis.evaluate import improvement_ci95_pct

    base = np.array([4.0, 9.0, 1.5, 20.0, 7.0])
    lo, hi = improvement_ci95_pct(base, 0.3 * base)
    assert lo == pytest.approx(70.0) and hi == pytest.approx(70.0)


def test_improvement_interval_matches_normal_theory_on_many_outages():
    # baseline 10 m on every outage, candidate N(6, 2) m: improvement 100 (1 - mean / 10), whose
    # standard error is 100 * sd / (10 sqrt(n)); the 95 % interval is about +-1.96 of it
    from ionav_viz.analysis.evaluate import improvement_ci95_pct

    n = 400
    cand = np.random.default_rng(7).normal(6.0, 2.0, n)
    lo, hi = improvement_ci95_pct(np.full(n, 10.0), cand)
    centre = 100.0 * (1.0 - cand.mean() / 10.0)
    half = 1.96 * 100.0 * cand.std(ddof=1) / (10.0 * np.sqrt(n))
    assert lo == pytest.approx(centre - half, abs=0.15 * half)
    assert hi == pytest.approx(centre + half, abs=0.15 * half)


def test_improvement_interval_leaves_out_outages_either_misses_and_needs_two():
    from ionav_viz.analysis.evaluate import improvement_ci95_pct

    lo, hi = improvement_ci95_pct(np.array([10.0, np.nan, 10.0]), np.array([5.0, 1.0, 5.0]))
    assert (lo, hi) == pytest.approx((50.0, 50.0))
    assert np.isnan(improvement_ci95_pct(np.array([10.0, np.nan]), np.array([5.0, 1.0]))).all()


def test_improvement_interval_of_a_large_fleet_is_the_normal_approximation_of_the_bootstrap():
    # above BOOTSTRAP_MAX_OUTAGES the delta method stands in for the bootstrap: the two agree
    from ionav_viz.analysis.evaluate import BOOTSTRAP_MAX_OUTAGES, improvement_ci95_pct, paired_bootstrap_means

    rng = np.random.default_rng(1)
    n = BOOTSTRAP_MAX_OUTAGES + 1
    base = rng.gamma(2.0, 5.0, n)
    cand = 0.5 * base + rng.gamma(2.0, 2.0, n)
    mb, mc = paired_bootstrap_means(base, cand)
    boot = np.percentile(100.0 * (mb - mc) / mb, [2.5, 97.5])
    np.testing.assert_allclose(improvement_ci95_pct(base, cand), boot, atol=0.15)


def test_a_fleets_improvement_interval_resamples_whole_drives():
    # ten drives or more: the drives are resampled, not their outages. An independent bootstrap
    # written here (its own generator: the percentiles agree within their sampling noise)
    from ionav_viz.analysis.evaluate import FEW_DRIVES, clustered_improvement_ci95_pct

    rng = np.random.default_rng(3)
    base = [rng.uniform(5.0, 15.0, 4) for _ in range(FEW_DRIVES + 2)]
    cand = [b * rng.uniform(0.2, 0.8) for b in base]  # one ratio per drive: no spread inside a drive
    lo, hi = clustered_improvement_ci95_pct(base, cand)
    sb, sc = np.array([b.sum() for b in base]), np.array([c.sum() for c in cand])
    draws = np.random.default_rng(99).integers(0, len(sb), (20000, len(sb)))
    mine = np.percentile(100.0 * (1.0 - sc[draws].sum(axis=1) / sb[draws].sum(axis=1)), [2.5, 97.5])
    assert (lo, hi) == pytest.approx(tuple(mine), abs=1.0)
    assert hi - lo > 10.0  # the drives' ratios differ: wide, though every drive's outages agree exactly


def test_with_few_drives_a_fleets_interval_spans_at_least_the_outages():
    # drive A: the candidate halves the baseline, drive B: no gain. Drawing two drives with
    # replacement: AA 50 % (p 1/4), AB or BA 25 % (p 1/2), BB 0 % (p 1/4), so the drives' 2.5 and
    # 97.5 percentiles are 0 and 50; with two drives the interval spans the outages' as well
    from ionav_viz.analysis.evaluate import clustered_improvement_ci95_pct, improvement_ci95_pct

    base, cand = [np.array([4.0, 6.0]), np.array([3.0, 7.0])], [np.array([1.0, 4.0]), np.array([3.0, 7.0])]
    lo_o, hi_o = improvement_ci95_pct(np.concatenate(base), np.concatenate(cand))
    assert clustered_improvement_ci95_pct(base, cand) == pytest.approx((min(0.0, lo_o), max(50.0, hi_o)))
    # two drives with the same ratio (90 %) but outages that vary: not a zero-width interval (a review found it)
    base, cand = [np.array([1.0, 9.0]), np.array([10.0])], [np.array([0.9, 0.1]), np.array([1.0])]
    lo, hi = clustered_improvement_ci95_pct(base, cand)
    assert (lo, hi) == pytest.approx(improvement_ci95_pct(np.array([1.0, 9.0, 10.0]), np.array([0.9, 0.1, 1.0]))) and hi - lo > 50.0
    # one drive scored (the other's outages all NaN): its outages are resampled
    lo, hi = clustered_improvement_ci95_pct([np.array([10.0, 10.0, 10.0]), np.array([np.nan])], [np.array([5.0, 5.0, 5.0]), np.array([1.0])])
    assert (lo, hi) == pytest.approx((50.0, 50.0))
