import json
import shutil

import pytest

from ionav_viz.core.errors import InputError
from ionav_viz.dataset.samples import samples_dir
from ionav_viz.sources.resolve import resolve_drive

from .conftest import one_line_error, run_cli

UNSYNC = "Unsynchronised V and S Dataset/Categorised IOVNB (V) Dataset/V Dataset"
SYNC = "Synchronised V abd S datasets/Categorised IOVNB Dataset"


@pytest.fixture()
def fake_root(tmp_path):
    """A tree with the dataset's real folder names; every file a copy of a small drive."""
    src = samples_dir() / "V-sim-motorway.csv"
    paths = [
        f"{UNSYNC}/Vw (Driver E)/Vw08/V-Vw8.csv",
        f"{SYNC}/Vw (Driver E)/Vw08/V-Vw8.csv",
        f"{SYNC}/../Synchronised V abd S datasets/Uncategorised IOVNB Dataset/V-Dataset/V-Vw8.csv",
        f"{UNSYNC}/Vta (Driver E)/Vta01a/V-Vta1a.csv",
        f"{UNSYNC}/Vta (Driver E)/Vta11/V-Vta11.csv",
        "Unsynchronised V and S Dataset/Uncategorised IOVNB (V and S) Dataset/V-Dataset/V-Vta11.csv",
        f"{SYNC}/Vta (Driver E)/Vta11/V-vta11.csv",
    ]
    for p in paths:
        target = (tmp_path / p).resolve()
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(src, target)
    return tmp_path


@pytest.mark.parametrize("spec", ["V-Vw8", "Vw8", "v-vw8.csv", "V-VW8"])
def test_run_names_resolve_to_the_unsynchronised_copy(fake_root, spec):
    path = resolve_drive(spec, fake_root)
    assert path.name == "V-Vw8.csv" and UNSYNC in str(path)


@pytest.mark.parametrize("spec", ["V-Vta1a", "Vta01a", "V-Vta01a", "vta1a"])
def test_zero_padding_is_tolerated(fake_root, spec):
    assert resolve_drive(spec, fake_root).name == "V-Vta1a.csv"


def test_case_of_file_name_does_not_matter(fake_root):
    path = resolve_drive("V-Vta11", fake_root)
    assert "Unsynchronised" in str(path) and "/Categorised" in str(path)


def test_plain_path_and_bundled_scenario(tmp_path):
    assert resolve_drive(str(samples_dir() / "V-sim-roundabout.csv"), None).name == "V-sim-roundabout.csv"
    assert resolve_drive("roundabout", None).name == "V-sim-roundabout.csv"
    assert resolve_drive("stationary", None).name == "V-sim-stationary.csv"


def test_paper_run_without_data_root_says_what_it_is():
    with pytest.raises(InputError) as err:
        resolve_drive("V-Vw8", None)
    assert "sharp-cornering test run" in str(err.value) and "--data-root" in str(err.value)


@pytest.mark.parametrize(("run", "stand_in"), [("V-Vw8", "sharp-cornering"), ("Vta11", "roundabout"), ("V-Vw12", "motorway"),
                                             ("V-Vw1", "stationary")])
def test_a_missing_paper_run_names_its_bundled_stand_in(tmp_path, run, stand_in):
    # issue 63: 'replay V-Vw8' without the run said how to fetch it, never that a bundled drive stands in for it
    (tmp_path / "data").mkdir()
    line = one_line_error(run_cli("replay", run, "-o", str(tmp_path / "x.rrd"), env={"IONAV_DATA": str(tmp_path / "data")}),
                          run, f"ionav-viz fetch {run}", f"its bundled stand-in is {stand_in} (simulated")
    assert "an IO-VNBD run of the real IO-VNBD" not in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]
    with pytest.raises(InputError, match="V-Vw9 is a run of the real IO-VNBD dataset") as err:  # no stand-in for a run the paper does not use
        resolve_drive("V-Vw9", None)
    assert "stand-in" not in str(err.value)


def test_unknown_name_suggests_close_matches(fake_root):
    with pytest.raises(InputError, match=r"did you mean.*V-Vw8"):
        resolve_drive("V-Vw88", fake_root)


def test_cli_uses_ionav_data(fake_root):
    proc = run_cli("evaluate", "Vw8", "--no-idnn", "--json", env={"IONAV_DATA": str(fake_root)})
    assert proc.returncode == 0, proc.stderr
    assert '"drive": "V-Vw8"' in proc.stdout


def test_a_run_whose_file_is_not_the_published_size_is_read_with_a_warning(fake_root, caplog):
    """The fake root's V-Vw8.csv is a copy of a bundled drive, not the published run: 'list' calls
    it a mismatch, and evaluate read it as V-Vw8 without a word (a tour found it). It is read, with a
    warning naming both sizes; the published size is taken as is."""
    import logging

    from ionav_viz.dataset.catalog import vehicle_runs
    from ionav_viz.sources.resolve import warn_if_not_published

    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        path = resolve_drive("V-Vw8", fake_root)
        warn_if_not_published("V-Vw8", path)  # as the reader does, once per drive it reads
    published = sorted({e.size_bytes for e in vehicle_runs()["vw8"]}) if "vw8" in vehicle_runs() else None
    assert published, sorted(vehicle_runs())[:5]
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and f"is {path.stat().st_size} bytes, not the size of the published run's file" in said[0], said
    assert "ionav-viz fetch V-Vw8" in said[0]
    path.write_bytes(b"x" * published[0])  # the published size: nothing said
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        warn_if_not_published("V-Vw8", resolve_drive("V-Vw8", fake_root))
    assert not caplog.records
    proc = run_cli("list", "--data-root", str(fake_root))
    assert proc.returncode == 0, proc.stderr
    assert "mismatch = the size or sha256 differs from the manifest's" in proc.stdout
    assert "missing = no V-*.csv of the run under the data root" in run_cli("list", "--all", "--data-root", str(fake_root)).stdout


def test_list_shows_the_bundled_drives_first_and_counts_the_missing_runs(fake_root):
    # issue 63: 'list' showed 90 IO-VNBD runs, all missing, and never the drives that come with the package
    from ionav_viz.api.datasets import list_runs

    runs = list_runs(fake_root)
    here = [r["name"] for r in runs if r["status"] != "missing"]
    proc = run_cli("list", "--data-root", str(fake_root))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("Bundled drives") and lines[1].split()[:4] == ["name", "stands", "in", "for"]
    rows = {ln.split()[0]: ln for ln in lines[2:lines.index("")]}
    assert list(rows)[:5] == ["motorway", "roundabout", "quick-accel", "hard-brake", "sharp-cornering"]
    assert "V-Vw6, V-Vw7, V-Vw8" in rows["sharp-cornering"] and rows["sharp-cornering"].endswith("simulated 10-min sharp-cornering test drive")
    assert "V-sim-motorway-tunnels" in rows and "V-Vw1" in rows["stationary"]
    assert sorted(here) == ["V-Vta11", "V-Vta1a", "V-Vw8"] and all(any(ln.startswith(f"{n} ") for ln in lines) for n in here)
    assert not any(ln.startswith("V-Vw12 ") for ln in lines)  # a missing run: counted, not listed
    assert f"{len(runs) - 3} missing (" in proc.stdout and "'ionav-viz list --all'" in proc.stdout
    assert max(len(ln) for ln in rows.values()) <= 120 and len(lines) < 30
    every = run_cli("list", "--all", "--data-root", str(fake_root)).stdout.splitlines()
    assert {ln.split()[0] for ln in every if ln.startswith("V-") and " missing " in ln} == {r["name"] for r in runs if r["status"] == "missing"}
    listing = json.loads(run_cli("list", "--json", "--data-root", str(fake_root)).stdout)
    assert len(listing["runs"]) == len(runs) and listing["bundled"][4]["stands_in_for"] == ["V-Vw6", "V-Vw7", "V-Vw8"]


def test_list_sees_a_run_where_evaluate_finds_it(tmp_path):
    """A data root laid out flat (V-Vw8.csv at its top, not at the manifest's path): evaluate read
    it as V-Vw8 while list said it was missing."""
    import json

    shutil.copy(samples_dir() / "V-sim-motorway.csv", tmp_path / "V-Vw8.csv")
    proc = run_cli("list", "--data-root", str(tmp_path), "--json")
    assert proc.returncode == 0, proc.stderr
    [row] = [r for r in json.loads(proc.stdout)["runs"] if r["name"] == "V-Vw8"]
    assert row["status"] == "mismatch" and row["local_path"] == str(tmp_path / "V-Vw8.csv")


def test_a_run_file_gone_since_the_root_was_indexed_is_not_found(tmp_path):
    """The data root's index is cached per process: a file deleted after it was indexed gave a raw
    FileNotFoundError, and list still showed it (a review found it)."""
    from ionav_viz.api.datasets import list_runs

    shutil.copy(samples_dir() / "V-sim-motorway.csv", tmp_path / "V-Vw8.csv")
    assert resolve_drive("V-Vw8", tmp_path) == tmp_path / "V-Vw8.csv"
    (tmp_path / "V-Vw8.csv").unlink()
    with pytest.raises(InputError, match="it is not under the data root"):
        resolve_drive("V-Vw8", tmp_path)
    [row] = [r for r in list_runs(tmp_path) if r["name"] == "V-Vw8"]
    assert row["status"] == "missing" and "local_path" not in row


def test_a_run_not_at_its_published_size_is_warned_once_per_run(fake_root, tmp_path):
    """The check ran in the resolver, which the output checks call too: 'evaluate V-Vw8 --export'
    and 'replay V-Vw8 -o' said it twice. The reader says it, once."""
    proc = run_cli("evaluate", "V-Vw8", "--estimators", "ins", "--export", str(tmp_path / "ex"), "-q", env={"IONAV_DATA": str(fake_root)})
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("not the size of the published run's file") == 1, proc.stderr
