"""The IDNN knows when it is out of its depth: a model carries the domain of its training inputs, a
drive outside it is said to be (stderr, the JSON, the text and Markdown reports, the recording's
summary) and its uncertainty is widened there; a drive inside it is not."""

from __future__ import annotations

import dataclasses
import json
import shutil

import pytest

from ionav_viz.api.training import training_drives
from ionav_viz.learning.domain import Domain
from ionav_viz.learning.idnn import default_model_dir
from ionav_viz.learning.training import training_domain
from ionav_viz.nav.bias import resolve_bias
from ionav_viz.sources.load import ReadOptions, load_drives
from tests.conftest import REPO, run_cli
from tests.test_real_logs import summary_of

pytestmark = pytest.mark.xdist_group("idnn_domain")

IN_DOMAIN = REPO / "ionav_viz" / "data" / "samples" / "V-sim-roundabout.csv"  # a bundled test drive: like the training drives, not one
OUTSIDE = "IDNN: inputs outside what the shipped model was trained on"


@pytest.fixture(scope="module")
def phone_log(tmp_path_factory):
    """A simulated phone in a car: 6-axis single readings at 10 Hz, a noisy gyro (the shipped model saw 2-channel logs)."""
    path = tmp_path_factory.mktemp("phone") / "phone.mcap"
    proc = run_cli("simulate", "roundabout", "--imu", "phone", "--duration", "150s", "--seed", "3", "-o", str(path), "-q")
    assert proc.returncode == 0, proc.stderr
    return path


def _evaluate(drive, *extra: str):
    proc = run_cli("evaluate", str(drive), "--outage", "10s", "--estimators", "ins,idnn", *extra)
    assert proc.returncode == 0, proc.stderr
    return proc


def test_the_shipped_models_domain_is_its_training_drives_inputs():
    """Computed from the 40 bundled training drives it was trained on (the files and biases its
    metadata records), as train computes a new model's: reproducible, not hand-written."""
    meta = json.loads((default_model_dir() / "metadata.json").read_text())
    drives = [(d, resolve_bias(d, None)) for d in load_drives(training_drives(), ReadOptions())]
    assert [d.name for d, _ in drives] == [r["name"] for r in meta["training"]["drives"]]
    assert dataclasses.replace(Domain.from_dict(meta["domain"]), note="") == dataclasses.replace(training_domain(drives), note="")
    assert meta["domain"]["note"].startswith("the inputs of its 40 training drives")
    assert meta["domain"]["rates_hz"] == [10.0] and meta["domain"]["kinds"] == ["2-channel"] and meta["domain"]["n_drives"] == 40


def test_a_drive_outside_the_domain_is_said_to_be_everywhere_and_widens_the_uncertainty(phone_log, tmp_path):
    as_json = _evaluate(phone_log, "--truth-topic", "/truth/fix", "--json")
    line = next(x for x in as_json.stderr.splitlines() if OUTSIDE in x)
    assert "6-axis samples, trained on 2-channel" in line and "gyro noise" in line and "its uncertainty widened (sigma x" in line
    report = json.loads(as_json.stdout)
    assert any(OUTSIDE in w for w in report["warnings"])
    note = report["model"]["domain"]["phone"]
    assert "6-axis samples, trained on 2-channel" in note["outside"] and note["sigma_scale_max"] > 1.5
    for args in ((), ("--markdown",)):
        text = _evaluate(phone_log, "--truth-topic", "/truth/fix", *args).stdout
        assert "IDNN out of its training domain on phone: " in text and "sigma widened x" in text
    # the recording's summary says it too
    rrd = tmp_path / "phone.rrd"
    proc = run_cli("replay", str(phone_log), "--truth-topic", "/truth/fix", "--estimators", "ins,idnn", "-o", str(rrd), "-q")
    assert proc.returncode == 0, proc.stderr
    summary = summary_of(rrd)
    assert "IDNN out of its training domain** on phone" in summary and OUTSIDE in summary
    # the same networks without the domain record: no warning, and a narrower covariance (a larger ANEES; the
    # history check widens both where the GNSS before an outage shows it, so the gap is largest early in the drive)
    bare = tmp_path / "bare"
    shutil.copytree(default_model_dir(), bare)
    meta = json.loads((bare / "metadata.json").read_text())
    del meta["domain"]
    (bare / "metadata.json").write_text(json.dumps(meta))
    without = _evaluate(phone_log, "--truth-topic", "/truth/fix", "--json", "--model", str(bare))
    assert "IDNN: inputs outside" not in without.stderr
    unwidened = json.loads(without.stdout)
    assert unwidened["summary"]["idnn"]["crse_m"] == report["summary"]["idnn"]["crse_m"]  # the estimates are the same
    assert unwidened["summary"]["idnn"]["consistency"]["anees"] > report["summary"]["idnn"]["consistency"]["anees"]


def test_a_drive_inside_the_domain_is_not_warned_about():
    proc = _evaluate(IN_DOMAIN, "--json")
    assert "IDNN: inputs outside" not in proc.stderr
    report = json.loads(proc.stdout)
    assert "domain" not in report["model"] and not any("outside what" in w for w in report["warnings"])
    assert "out of its training domain" not in _evaluate(IN_DOMAIN).stdout


def test_a_fine_tuned_model_knows_its_own_drives_and_its_parents(tmp_path):
    out = tmp_path / "m"
    proc = run_cli("train", str(IN_DOMAIN), "--span", "0s:120s", "--from-model", "shipped", "--epochs-disp", "1", "--epochs-yaw", "1",
                   "-q", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    domain = json.loads((out / "metadata.json").read_text())["domain"]
    shipped = json.loads((default_model_dir() / "metadata.json").read_text())["domain"]
    assert domain["n_drives"] == 41 and domain["note"] == "the inputs of its 1 training drive(s) and its parent's"
    assert all(a >= b for name in domain["quantiles"] for a, b in zip(domain["quantiles"][name], shipped["quantiles"][name]))


@pytest.mark.parametrize("damage", [lambda d: d.update(quantiles_of=[0.5]), lambda d: d["noise"].update(gyro_noise_radps=[1.0, 0.5]),
                                    lambda d: d.update(rates_hz=[]), lambda d: d["quantiles"]["speed_mps"].reverse()])
def test_a_damaged_domain_record_is_one_line(tmp_path, damage):
    bad = tmp_path / "bad"
    shutil.copytree(default_model_dir(), bad)
    meta = json.loads((bad / "metadata.json").read_text())
    damage(meta["domain"])
    (bad / "metadata.json").write_text(json.dumps(meta))
    proc = run_cli("evaluate", str(IN_DOMAIN), "--outage", "10s", "--estimators", "ins,idnn", "--model", str(bad))
    assert proc.returncode == 2 and proc.stderr.startswith("error: ") and "domain." in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_fine_tuned_on_the_first_half_of_an_out_of_domain_drive_its_ellipse_holds_80_to_99_percent_of_the_second(tmp_path):
    """Issue 62 point 3 on a simulated drive outside the shipped model's domain (a phone in a holder
    on a 10-minute drive of sharp corners: 6-axis single readings, a noisy gyro): fine-tuned on its
    first half (the parent's uncertainty kept), its 95 % ellipse holds 80-99 % of the second half's
    10 s outages' final errors (or all where an honest one would one time in four: 0.95^n >= 0.25)."""
    import ionav_viz as iv
    from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, write_imu_log

    path = write_imu_log(tmp_path / "phone.mcap", "sharp-cornering", 4, 600.0, "phone")
    log = iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none", imu_mount="auto")
    drive = iv.load_drive(str(path), iv.ReadOptions(log=log))
    shipped = iv.evaluate([drive], 10, estimators=["idnn"]).to_dict()
    assert "6-axis samples, trained on 2-channel" in shipped["model"]["domain"]["phone"]["outside"]
    config = iv.fine_tune_settings("shipped", epochs_disp=20, epochs_yaw=20)
    iv.train(tmp_path / "m", [drive], iv.TrainingOptions(config, "shipped"), read=iv.ReadOptions(log=log, span="0s:300s"))
    run = iv.RunOptions(model=str(tmp_path / "m"), strict=True, warm_up_s=301.0)
    report = iv.evaluate([drive], 10, estimators=["idnn"], run=run).to_dict()
    c = report["summary"]["idnn"]["consistency"]
    n = c["n_outages"]
    assert n >= 25 and (80.0 <= c["coverage_95"] <= 99.0 or (c["coverage_95"] == 100.0 and 0.95**n >= 0.25)), c
