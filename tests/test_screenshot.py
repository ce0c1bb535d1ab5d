"""Headless screenshots: real renders through the Rerun viewer (Mesa lavapipe on CPU-only machines)."""

import os
import subprocess
import sys
import time

import numpy as np
import pytest

from ionav_viz.nav.idnn import IdnnEstimator
from ionav_viz.nav.ins import InsEstimator
from ionav_viz.viz.style import GNSS_COLOR

from .conftest import REPO, run_cli

COLORS = {"gnss": GNSS_COLOR, "ins": InsEstimator.color, "idnn": IdnnEstimator.color}



@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("rec") / "sharp.rrd"
    proc = run_cli("replay", "sharp-cornering", "--outage", "10s", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    probe = run_cli("screenshot", str(out), "-o", str(out.with_suffix(".png")), "--size", "400x300")
    if probe.returncode == 1 and "mesa-vulkan-drivers" in probe.stderr and not os.environ.get("CI"):
        pytest.skip(f"no renderer on this machine: {probe.stderr.strip()}")
    assert probe.returncode == 0, probe.stderr
    return out


def _pixels_near(path, rgb, tol=45):
    from PIL import Image

    img = np.asarray(Image.open(path).convert("RGB")).astype(int)
    return int((np.abs(img - np.array(rgb)).max(axis=-1) <= tol).sum())


@pytest.mark.parametrize("view", ["map", "local"])
def test_png_has_the_size_and_every_estimator_colour(recording, tmp_path, view):
    from PIL import Image

    out = tmp_path / f"{view}.png"
    proc = run_cli("screenshot", str(recording), "-o", str(out), "--view", view, "--time", "worst", "--size", "1200x700")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    assert Image.open(out).size == (1200, 700)
    for name in ("gnss", "ins", "idnn"):
        assert _pixels_near(out, COLORS[name]) > 50, name


def test_several_times_and_views_make_one_png_each(recording, tmp_path):
    proc = run_cli("screenshot", str(recording), "-o", str(tmp_path / "shots"), "--view", "signals", "--view", "errors",
                   "--time", "35s", "--time", "end", "--size", "800x600")
    assert proc.returncode == 0, proc.stderr
    names = sorted(p.name for p in (tmp_path / "shots").iterdir())
    assert names == ["V-sim-sharp-cornering-errors-0035.0s.png", "V-sim-sharp-cornering-errors-end.png",
                     "V-sim-sharp-cornering-signals-0035.0s.png", "V-sim-sharp-cornering-signals-end.png"]


def _viewer_scratch():
    import tempfile
    from pathlib import Path

    return {p.name for p in Path(tempfile.gettempdir()).glob("rerun-data-*")} | {p.name for p in Path(tempfile.gettempdir()).glob("ionav-viewer-*")}


def test_two_runs_in_parallel(recording, tmp_path):
    scratch_before = _viewer_scratch()
    cmds = [[sys.executable, "-m", "ionav_viz.cli", "screenshot", str(recording), "-o", str(tmp_path / f"p{i}.png"),
             "--view", "local", "--size", "600x400"] for i in range(2)]
    procs = [subprocess.Popen(c, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for c in cmds]
    results = [p.communicate(timeout=180) for p in procs]
    assert all(p.returncode == 0 for p in procs), results
    assert (tmp_path / "p0.png").is_file() and (tmp_path / "p1.png").is_file()
    assert _viewer_scratch() <= scratch_before  # the viewers' scratch folders are gone too


def _viewer_processes():
    out = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
    return {line.split()[0] for line in out.splitlines() if "rerun" in line and "--headless" in line}


def test_missing_renderer_is_a_clear_error_and_leaves_no_viewer(recording, tmp_path):
    before = _viewer_processes()
    env = {"VK_ICD_FILENAMES": str(tmp_path / "none.json"), "LIBGL_ALWAYS_SOFTWARE": "0", "MESA_LOADER_DRIVER_OVERRIDE": "none",
           "GALLIUM_DRIVER": "none", "WGPU_BACKEND": "vulkan"}
    start = time.monotonic()
    proc = run_cli("screenshot", str(recording), "-o", str(tmp_path / "x.png"), "--size", "400x300", env=env, timeout=120)
    assert time.monotonic() - start < 90
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "mesa-vulkan-drivers" in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1  # one line; the viewer's own output stays out of the terminal
    assert not (tmp_path / "x.png").exists()
    time.sleep(0.5)
    assert _viewer_processes() <= before


def test_replay_with_screenshot_dir(tmp_path):
    proc = run_cli("replay", "motorway", "-o", str(tmp_path / "m.rrd"), "-q", "--no-idnn", "--screenshot", str(tmp_path / "shots"))
    if proc.returncode == 1 and "mesa" in proc.stderr and not os.environ.get("CI"):
        pytest.skip("no renderer on this machine")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "shots").iterdir()) == [
        f"V-sim-motorway-{v}-worst.png" for v in ("all", "errors", "local", "map", "signals")]


def test_bad_screenshot_inputs(tmp_path):
    rrd = tmp_path / "not.rrd"
    rrd.write_bytes(b"garbage")
    for args, message in [
        ([str(rrd), "-o", str(tmp_path / "x.png")], "not a readable Rerun recording"),
        ([str(tmp_path / "missing.rrd"), "-o", str(tmp_path / "x.png")], "no such recording"),
        ([str(rrd), "-o", str(tmp_path / "x.png"), "--size", "big"], "WIDTHxHEIGHT"),
    ]:
        proc = run_cli("screenshot", *args)
        assert proc.returncode == 2 and message in proc.stderr, (args, proc.stderr)
