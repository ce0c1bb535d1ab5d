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


def _viewers_under(tmpdir):
    """Headless viewer processes started with a TMPDIR inside ``tmpdir`` (ours, not other tests')."""
    from pathlib import Path

    found = set()
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmd = (proc / "cmdline").read_bytes().split(b"\0")
            env = (proc / "environ").read_bytes().split(b"\0")
        except OSError:
            continue
        if any(b"rerun" in c for c in cmd[:1]) and b"--headless" in cmd and any(e.startswith(b"TMPDIR=" + str(tmpdir).encode()) for e in env):
            found.add(proc.name)
    return found


def test_two_runs_in_parallel(recording, tmp_path):
    private_tmp = tmp_path / "tmp"
    private_tmp.mkdir()
    cmds = [[sys.executable, "-m", "ionav_viz.cli", "screenshot", str(recording), "-o", str(tmp_path / f"p{i}.png"),
             "--view", "local", "--size", "600x400"] for i in range(2)]
    env = {**os.environ, "TMPDIR": str(private_tmp)}
    procs = [subprocess.Popen(c, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for c in cmds]
    results = [p.communicate(timeout=180) for p in procs]
    assert all(p.returncode == 0 for p in procs), results
    assert (tmp_path / "p0.png").is_file() and (tmp_path / "p1.png").is_file()
    assert list(private_tmp.iterdir()) == []  # the viewers' scratch folders are gone too
    assert _viewers_under(private_tmp) == set()


def test_missing_renderer_is_a_clear_error_and_leaves_no_viewer(recording, tmp_path):
    private_tmp = tmp_path / "tmp"
    private_tmp.mkdir()
    env = {"TMPDIR": str(private_tmp), "VK_ICD_FILENAMES": str(tmp_path / "none.json"), "LIBGL_ALWAYS_SOFTWARE": "0", "MESA_LOADER_DRIVER_OVERRIDE": "none",
           "GALLIUM_DRIVER": "none", "WGPU_BACKEND": "vulkan"}
    start = time.monotonic()
    proc = run_cli("screenshot", str(recording), "-o", str(tmp_path / "x.png"), "--size", "400x300", env=env, timeout=120)
    assert time.monotonic() - start < 90
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "mesa-vulkan-drivers" in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1  # one line; the viewer's own output stays out of the terminal
    assert not (tmp_path / "x.png").exists()
    assert _viewers_under(private_tmp) == set()  # the viewer is stopped before the command returns
    assert list(private_tmp.iterdir()) == []


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
