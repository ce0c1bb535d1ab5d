"""One typed experiment (issue 61, point 1): ``iv.evaluate`` and ``iv.replay`` take an
``iv.Experiment`` or today's arguments, the variants (several lengths, by event, a fleet, a
scenario) are its fields, the old names warn for one release and return what they returned, and
no public function of the API takes more than 8 parameters."""

from __future__ import annotations

import inspect
import json
from dataclasses import replace

import pytest

import ionav_viz as iv

CHEAP = iv.RunOptions(estimators=["ins"])


def _fleet_dict(report) -> dict:
    """A fleet report without its wall times (the one part that differs between two runs)."""
    doc = report.to_dict()
    doc.pop("timing")
    return doc


def test_an_experiment_is_what_todays_arguments_make():
    exp = iv.Experiment("roundabout", 10.0, iv.Every(60.0), run=CHEAP)
    assert exp.drives == ("roundabout",) and exp.lengths_s is None
    assert iv.evaluate(exp).to_json() == iv.evaluate("roundabout", 10.0, iv.Every(60.0), ["ins"]).to_json()
    several = iv.evaluate(replace(exp, outage_s=[30, 10]))
    assert list(several) == [10.0, 30.0] and several[10.0].to_json() == iv.evaluate(exp).to_json()


@pytest.mark.parametrize(("fields", "param"), [
    ({"drives": None}, "drives"), ({"drives": ["roundabout", 5]}, "drives"), ({"drives": []}, None),
    ({"outage_s": 10.5}, "outage_s"), ({"outage_s": []}, "outage_s"), ({"placement": 5}, "placement"),
    ({"run": "x"}, "run"), ({"read": "x"}, "read"), ({"truth": ""}, "truth"), ({"engine": 2}, "engine"),
    ({"by_event": ["no-such-event"]}, "placement"), ({"by_event": True, "placement": iv.Every(30.0)}, "by_event"),
    ({"outage_s": [10, 30], "by_event": True}, "outage_s"), ({"outage_s": [10, 30], "engine": iv.Engine(1)}, "outage_s"),
    ({"runs": ["Vta"]}, "runs"), ({"scenario": "no-such"}, "scenario"), ({"external": {"x": "x.csv"}}, "external"),
    ({"plan": "p.outages.json", "placement": iv.Every(30.0)}, "plan"),
])
def test_an_experiment_refuses_a_bad_field_naming_it(fields, param):
    with pytest.raises(iv.InputError) as err:
        iv.Experiment(**{"drives": "roundabout", **fields})
    assert err.value.param == param and "\n" not in err.value.message


def test_an_experiment_and_its_fields_again_are_refused_and_a_misspelt_keyword_is_a_type_error():
    with pytest.raises(iv.InputError) as err:
        iv.evaluate(iv.Experiment("roundabout"), 30.0)
    assert err.value.param == "outage_s"
    with pytest.raises(TypeError, match="'outage'"):
        iv.evaluate("roundabout", outage=30.0)


def test_replay_takes_one_drive_without_an_engine(tmp_path):
    with pytest.raises(iv.InputError) as err:
        iv.replay(["roundabout", "hard-brake"], 10.0, output=tmp_path / "x.rrd")
    assert err.value.param == "drives" and list(tmp_path.iterdir()) == []


def test_the_deprecated_mcap_keyword_still_works_and_warns():
    with pytest.warns(DeprecationWarning, match="mcap= is deprecated"):
        old = iv.evaluate("roundabout", 10.0, estimators=["ins"], mcap=iv.LogOptions())
    assert old.to_json() == iv.evaluate("roundabout", 10.0, estimators=["ins"]).to_json()


def test_evaluate_lengths_warns_and_returns_the_same():
    with pytest.warns(DeprecationWarning, match=r"evaluate_lengths is deprecated: use evaluate\(") as said:
        old = iv.evaluate_lengths("roundabout", [10, 30], run=CHEAP)
    assert said[0].filename == __file__  # the caller's line, not the wrapper's
    new = iv.evaluate("roundabout", [10, 30], run=CHEAP)
    assert {k: r.to_json() for k, r in old.items()} == {k: r.to_json() for k, r in new.items()}


def test_evaluate_by_event_warns_and_returns_the_same():
    with pytest.warns(DeprecationWarning, match="evaluate_by_event is deprecated"):
        old = iv.evaluate_by_event(["hard-brake"], 10.0, ["hard-brake", "quick-accel"], ["ins"])
    new = iv.evaluate("hard-brake", 10.0, run=CHEAP, by_event=["hard-brake", "quick-accel"])
    assert {k: r.to_json() for k, r in old.items()} == {k: r.to_json() for k, r in new.items()}
    assert old.events == new.events


def test_evaluate_fleet_warns_and_returns_the_same():
    with pytest.warns(DeprecationWarning, match="evaluate_fleet is deprecated"):
        old = iv.evaluate_fleet(["roundabout", "hard-brake"], 10.0, estimators=["ins"], workers=1)
    new = iv.evaluate(["roundabout", "hard-brake"], 10.0, run=CHEAP, engine=iv.Engine(1))
    assert json.dumps(_fleet_dict(old)) == json.dumps(_fleet_dict(new))


def test_replay_fleet_warns_and_returns_the_same(tmp_path):
    with pytest.warns(DeprecationWarning, match="replay_fleet is deprecated"):
        old = iv.replay_fleet(["roundabout"], tmp_path / "old", 10.0, estimators=["ins"], workers=1)
    new = iv.replay(["roundabout"], 10.0, run=CHEAP, output=tmp_path / "new", engine=iv.Engine(1))
    assert [r["recording"] for r in old.drive_rows()] == [str(tmp_path / "old" / "roundabout.rrd")]
    assert [r["recording"] for r in new.drive_rows()] == [str(tmp_path / "new" / "roundabout.rrd")]
    assert old.to_dict()["sequences"] == new.to_dict()["sequences"]


def test_replay_lengths_warns_and_returns_the_same(tmp_path):
    with pytest.warns(DeprecationWarning, match="replay_lengths is deprecated"):
        old = iv.replay_lengths("roundabout", [10, 30], output=tmp_path / "old.rrd", run=CHEAP)
    new = iv.replay("roundabout", [10, 30], output=tmp_path / "new.rrd", run=CHEAP)
    assert [r.path.name for r in old] == ["old-10s.rrd", "old-30s.rrd"]
    assert [r.path.name for r in new] == ["new-10s.rrd", "new-30s.rrd"]
    assert [r.report.to_json() for r in old] == [r.report.to_json() for r in new]


def test_replay_scenario_warns_and_returns_the_same(tmp_path):
    (tmp_path / "old").mkdir()
    (tmp_path / "new").mkdir()
    with pytest.warns(DeprecationWarning, match="replay_scenario is deprecated"):
        old = iv.replay_scenario("roundabout", tmp_path / "old", run=CHEAP)
    new = iv.replay(iv.Experiment(scenario="roundabout", run=CHEAP), output=tmp_path / "new")
    assert [p.name for p in old] == [p.name for p in new] == ["roundabout-V-sim-roundabout.rrd"]
    assert [p.parent for p in old] == [tmp_path / "old"]


def test_train_and_cross_validate_keep_from_model_and_device_with_a_warning(tmp_path):
    """Both moved into iv.TrainingOptions; given as keywords they still work, said deprecated.
    (An unknown device is refused before any drive is read, either way.)"""
    with pytest.warns(DeprecationWarning, match=r"device= is deprecated: pass TrainingOptions"), \
            pytest.raises(iv.InputError) as err:
        iv.train(tmp_path / "m", ["roundabout"], device="tpu")
    assert err.value.param == "device"
    with pytest.raises(iv.InputError) as err:
        iv.cross_validate(["roundabout", "motorway"], 2, config=iv.TrainingOptions(device="tpu"))
    assert err.value.param == "device"
    with pytest.raises(iv.InputError) as err:
        iv.train(tmp_path / "m", ["roundabout"], iv.TrainingOptions(), from_model="shipped")
    assert err.value.param == "from_model"
    assert list(tmp_path.iterdir()) == []


def test_no_public_function_of_the_api_takes_more_than_8_parameters():
    import ionav_viz.api as api

    over = {}
    for name in api.__all__:
        value = getattr(api, name)
        if inspect.isfunction(value):
            n = len(inspect.signature(value).parameters)
            if n > 8:
                over[name] = n
    assert over == {}
