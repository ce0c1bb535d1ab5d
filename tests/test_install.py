"""Behaving like a released package: outputs where the user is, models never clobbered, no first-run traps."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from ionav_viz import InputError, ToolFailure
from ionav_viz.learning.idnn import default_model_dir, load_model, save_model

from .conftest import HANG_S, REPO, run_cli


def test_replay_writes_into_recordings_in_the_current_directory(tmp_path):
    proc = run_cli("replay", "hard-brake", "--no-idnn", "--every", "100s", "-q", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(Path("recordings", "V-sim-hard-brake.rrd"))
    assert [p.relative_to(tmp_path).as_posix() for p in sorted(tmp_path.rglob("*"))] == ["recordings", "recordings/V-sim-hard-brake.rrd"]
    again = run_cli("replay", "hard-brake", "--no-idnn", "--every", "100s", "-q", cwd=tmp_path)  # the folder exists now
    assert again.returncode == 0 and len(list(tmp_path.rglob("*.rrd"))) == 1, again.stderr


def test_a_failed_replay_leaves_no_recordings_folder(tmp_path):
    """Bad input (before any work) and a write that fails part-way (a file size limit, as on a
    full disk) both leave the current directory as it was: no recordings/ made."""
    import resource
    import subprocess
    import sys

    proc = run_cli("replay", "hard-brake", "--no-idnn", "--at", "99999s", "-q", cwd=tmp_path)
    assert proc.returncode == 2 and list(tmp_path.iterdir()) == [], proc.stderr

    def small_files() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    full = subprocess.run([sys.executable, "-m", "ionav_viz.cli", "replay", "hard-brake", "--no-idnn", "-q"], cwd=tmp_path,
                          capture_output=True, text=True, preexec_fn=small_files, timeout=HANG_S,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert full.returncode == 1 and "write failed" in full.stderr, full.stderr
    assert list(tmp_path.iterdir()) == []


def test_shipped_model_lives_once_in_the_repository_models_folder():
    from ionav_viz.dataset.samples import package_data

    assert default_model_dir() == REPO / "models" / "idnn"  # an editable install reads the checkout's models/
    assert sorted(p.name for p in default_model_dir().iterdir()) == ["displacement.safetensors", "metadata.json", "uncertainty.safetensors",
                                                                    "yaw_rate.safetensors"]
    assert not package_data("models").exists()  # no second copy inside the package


def test_shipped_data_is_package_data():
    from ionav_viz.dataset.samples import SAMPLES, package_data, samples_dir

    assert samples_dir() == package_data("samples")
    assert all((samples_dir() / s.file).is_file() for s in SAMPLES)
    assert samples_dir().parts[-3:] == ("ionav_viz", "data", "samples")


@pytest.fixture()
def shipped_copy(tmp_path):
    target = tmp_path / "model"
    shutil.copytree(default_model_dir(), target)
    return target


def test_train_refuses_existing_or_shipped_directories_before_any_work(tmp_path, shipped_copy):
    proc = run_cli("train", "-o", str(shipped_copy), "--epochs-disp", "1", "--epochs-yaw", "1", "-q")
    assert proc.returncode == 2 and "exists already" in proc.stderr and "--force" in proc.stderr
    proc = run_cli("train", "-o", str(default_model_dir()), "--force", "-q")
    assert proc.returncode == 2 and "shipped IDNN model" in proc.stderr
    proc = run_cli("train", "-q")
    assert proc.returncode == 2 and "-o" in proc.stderr  # no default model directory to write over


def test_force_replaces_a_model_atomically(tmp_path, shipped_copy, monkeypatch):
    model = load_model(shipped_copy)
    with pytest.raises(InputError, match="exists already"):
        save_model(model, shipped_copy)
    before = {p.name: p.read_bytes() for p in shipped_copy.iterdir()}

    # a save that fails half-way (after the first weights file) leaves the old model as it was
    import ionav_viz.learning.idnn as idnn

    real_save = __import__("safetensors.torch", fromlist=["save"]).save
    calls = []

    def failing_save(state):
        calls.append(1)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real_save(state)

    monkeypatch.setattr("safetensors.torch.save", failing_save)
    with pytest.raises(ToolFailure, match=r"model: write failed \(No space left on device\); is the disk full\?"):
        idnn.save_model(model, shipped_copy, overwrite=True)
    assert {p.name: p.read_bytes() for p in shipped_copy.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"]  # no temporary directory left
    monkeypatch.setattr("safetensors.torch.save", real_save)

    idnn.save_model(model, shipped_copy, overwrite=True)
    assert {p.name: p.read_bytes() for p in shipped_copy.iterdir()} == before  # same model, same bytes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"]
    with pytest.raises(InputError, match="shipped IDNN model"):
        save_model(model, default_model_dir(), overwrite=True)


def test_a_stop_signal_at_any_step_of_a_forced_save_keeps_one_complete_model(tmp_path, shipped_copy, monkeypatch):
    """Round 3: SIGTERM right after the old model was renamed aside left no model at the target,
    deleted the new one and kept the old only as a hidden folder. Here a real SIGTERM arrives right
    after each file-system step of the save in turn (Terminated, as the command line raises it):
    the target is always one complete model, old or new, and nothing else is left."""
    import os
    import signal
    import tempfile

    import ionav_viz.learning.idnn as idnn
    from ionav_viz.core.signals import Terminated, raise_terminated

    old_meta = (shipped_copy / "metadata.json").read_bytes()
    model = load_model(shipped_copy)
    model.metadata["note"] = "the new model"
    steps = [(tempfile, "mkdtemp"), (Path, "write_bytes"), (Path, "write_text"), (Path, "chmod"), (Path, "rename"),
             (__import__("shutil"), "rmtree")]
    calls, stopped_after = [], []

    def after_step(owner, name):
        real = getattr(owner, name)

        def step(*args, **kwargs):
            out = real(*args, **kwargs)
            calls.append(name)
            if len(calls) == stop_at:
                stopped_after.append(name)
                os.kill(os.getpid(), signal.SIGTERM)
            return out
        return step

    previous = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        for owner, name in steps:
            monkeypatch.setattr(owner, name, after_step(owner, name))
        stop_at = 0
        while True:
            stop_at, calls[:] = stop_at + 1, []
            try:
                idnn.save_model(model, shipped_copy, overwrite=True)
            except Terminated:
                pass
            else:
                break
            monkeypatch.undo()
            meta = (shipped_copy / "metadata.json").read_bytes()
            assert meta == old_meta or b"the new model" in meta, f"after {stopped_after[-1]}"
            load_model(shipped_copy)  # complete: every weight file matches its checksum
            assert sorted(p.name for p in tmp_path.iterdir()) == ["model"], f"left behind after {stopped_after[-1]}"
            for owner, name in steps:
                monkeypatch.setattr(owner, name, after_step(owner, name))
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert {"mkdtemp", "write_bytes", "write_text", "chmod", "rename", "rmtree"} <= set(stopped_after), stopped_after
    assert b"the new model" in (shipped_copy / "metadata.json").read_bytes()


def test_weights_that_differ_from_the_recorded_checksum_are_refused(shipped_copy):
    weights = shipped_copy / "yaw_rate.safetensors"
    data = bytearray(weights.read_bytes())
    data[-1] ^= 0x01  # one weight's lowest bit: still a valid file of the right shapes
    weights.write_bytes(bytes(data))
    with pytest.raises(InputError, match="sha256 differs"):
        load_model(shipped_copy)
    meta = json.loads((shipped_copy / "metadata.json").read_text())
    del meta["weights_sha256"]
    (shipped_copy / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="no weights_sha256"):
        load_model(shipped_copy)


def test_debug_and_verbose_work_anywhere_on_the_command_line():
    plain = run_cli("evaluate", "roundabout", "--outage", "2.5s")
    assert plain.returncode == 2 and "Traceback" not in plain.stderr
    debug = run_cli("evaluate", "roundabout", "--outage", "2.5s", "--debug")
    assert debug.returncode != 0 and "Traceback" in debug.stderr
    verbose = run_cli("replay", "hard-brake", "--no-idnn", "--every", "100s", "-o", "/dev/null/x.rrd", "-v")
    assert verbose.returncode == 2  # the output directory is not a directory; stages before it were logged
    assert "read hard-brake: V-sim-hard-brake" in verbose.stderr and " s)" in verbose.stderr


def test_open_without_a_display_says_what_to_do_instead(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = tmp_path / "x.rrd"
    proc = run_cli("replay", "hard-brake", "--no-idnn", "--every", "100s", "-q", "-o", str(out), "--open", env={**env, "DISPLAY": ""})
    assert proc.returncode == 1, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "no display" in lines[0] and "--serve-web" in lines[0] and "ionav-viz screenshot" in lines[0]
    assert not out.exists()  # said before any work, not after a long replay


def test_scenario_says_which_drives_it_uses(tmp_path):
    empty_root = tmp_path / "IO-VNBD"
    empty_root.mkdir()
    proc = run_cli("evaluate", "--scenario", "roundabout", "--overview", "--no-idnn", "--data-root", str(empty_root),
                   env={"COLUMNS": "1000"})  # wide enough for the overview's one line per scenario (piped: 120 columns, transposed)
    assert proc.returncode == 0, proc.stderr
    assert "roundabout: the bundled synthetic test drives (the paper's runs are not all under" in proc.stderr
    assert proc.stdout.splitlines()[1].startswith("roundabout")


def test_every_package_is_in_the_wheel():
    """pyproject.toml lists the packages (models/ is mapped into ionav_viz.models): a new
    subpackage left out of the list would be missing from the wheel."""
    import tomllib

    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {".".join(p.parent.relative_to(REPO).parts) for p in (REPO / "ionav_viz").rglob("__init__.py")}
    assert on_disk | {"ionav_viz.models"} == listed


def test_train_leaves_nothing_in_the_temporary_directory(tmp_path):
    """Round 3: every train left an empty torchinductor_<user> folder in the temporary directory."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    # any training step makes the folder (torch's optimiser step): two minutes of one drive train as the 40 bundled drives do
    proc = run_cli("train", "roundabout", "--span", "0s:120s", "-o", str(tmp_path / "model"), "--epochs-disp", "1", "--epochs-yaw", "1", "-q",
                   env={"TMPDIR": str(scratch)})
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "model" / "metadata.json").is_file()
    assert list(scratch.iterdir()) == []
