"""Headless screenshots: real renders through the Rerun viewer (Mesa lavapipe on CPU-only machines)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from ionav_viz.learning.idnn import IdnnEstimator
from ionav_viz.nav.ekf import EkfEstimator
from ionav_viz.nav.ins import InsEstimator
from ionav_viz.nav.odometry import OdometryEstimator
from ionav_viz.viz.style import GNSS_COLOR

from .conftest import HANG_S, REPO, run_cli

# the module's generated fixtures are built once, on one worker (pytest-xdist's --dist loadgroup)
pytestmark = pytest.mark.xdist_group("screenshot")

COLORS = {"gnss": GNSS_COLOR, "ins": InsEstimator.color, "idnn": IdnnEstimator.color, "odo": OdometryEstimator.color,
          "ekf": EkfEstimator.color}
TITLE_BAR_PX = 62  # the viewer's top bar and the view's title (text down to y = 58)



@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("rec") / "sharp.rrd"
    proc = run_cli("replay", "sharp-cornering", "--outage", "10s", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    return out


def _no_renderer(proc) -> bool:
    """Whether ``proc`` failed for want of a renderer, on a machine other than CI's (which has one)."""
    return proc.returncode == 1 and "mesa-vulkan-drivers" in proc.stderr and not os.environ.get("CI")


#: The images of the recording the tests below look at: per size, the views, times and outage numbers
#: that one ``screenshot`` command renders (one PNG each, named <drive>-<view>-<time>.png), for every
#: test that looks at that size. A viewer costs seconds to start (its start-up toasts must fade first),
#: an image a fraction of one.
BATCHES = {
    "800x450": (("local",), ("worst", "291s", "0ms"), ("3", "7")),
    "800x600": (("map", "local", "signals", "errors"), ("35s", "end"), ()),
    "1200x700": (("map", "local"), ("worst",), ()),
    "1280x720": (("all", "signals", "errors"), ("end", "worst"), ()),
    "1600x900": (("all", "signals", "errors"), ("end", "worst", "305s"), ()),
    "1024x576": (("all", "signals", "errors", "health"), ("end", "worst"), ()),
}


class Shots:
    """The images of ``batches`` (as :data:`BATCHES`) of ``recording`` (of the drive ``drive``), each
    size's rendered by one command when a test first asks."""

    def __init__(self, recording, root, batches=BATCHES, drive="V-sim-sharp-cornering"):
        self.recording, self.root, self.batches, self.drive, self.procs = recording, root, batches, drive, {}

    def folder(self, size: str):
        """The folder of ``size``'s images (skips the test where nothing renders)."""
        if size not in self.procs:
            views, times, numbers = self.batches[size]
            args = [a for v in views for a in ("--view", v)] + [a for t in times for a in ("--time", t)]
            args += [a for n in numbers for a in ("--outage-number", n)]
            self.procs[size] = run_cli("screenshot", str(self.recording), "-o", str(self.root / size), "--size", size,
                                       *args)
        proc = self.procs[size]
        if _no_renderer(proc):
            pytest.skip(f"no renderer on this machine: {proc.stderr.strip()}")
        assert proc.returncode == 0, proc.stderr
        return self.root / size

    def __call__(self, size: str, view: str, label: str):
        """The image of ``view`` at ``label`` (``worst``, ``end``, ``0035.0s``, ``outage3``) and ``size``."""
        png = self.folder(size) / f"{self.drive}-{view}-{label}.png"
        assert png.is_file(), sorted(p.name for p in png.parent.iterdir())
        return png


@pytest.fixture(scope="module")
def shots(recording, tmp_path_factory):
    return Shots(recording, tmp_path_factory.mktemp("shots"))


@pytest.fixture
def renderer(shots):
    """For a test that needs the viewer to render: skipped where nothing renders (outside CI)."""
    shots.folder("800x450")


def _image(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def _pixels_near(path, rgb, tol=45):
    return int((np.abs(_image(path) - np.array(rgb)).max(axis=-1) <= tol).sum())


def _extent_of(path, rgb, tol=30):
    """(width, height) in pixels of the box around the pixels of colour ``rgb`` below the title bar."""
    img = _image(path)[TITLE_BAR_PX:-40]  # not the title bar, not the time panel
    ys, xs = np.nonzero(np.abs(img - np.array(rgb)).max(axis=-1) <= tol)
    return (int(np.ptp(xs)), int(np.ptp(ys))) if len(xs) else (0, 0)


def test_worst_outage_local_view_frames_that_outage(shots):
    """Framed: the outage's own GNSS track (full green; the rest of the drive is drawn faint) spans a
    large part of the image, where the whole-drive view shows it a few pixels long; every
    estimator's colour is there (in the key at least: a track can lie under another one's)."""
    framed, whole = shots("800x450", "local", "worst"), shots("800x450", "local", "0291.0s")
    w, h = _extent_of(framed, GNSS_COLOR)
    assert w > 0.5 * 800 or h > 0.5 * (450 - TITLE_BAR_PX - 40), (w, h)
    w_whole, h_whole = _extent_of(whole, GNSS_COLOR)  # the same time (the worst outage's end), not framed
    assert max(w_whole, h_whole) < 0.25 * max(w, h), ((w, h), (w_whole, h_whole))
    for name, rgb in COLORS.items():
        assert _pixels_near(framed, rgb, tol=30) > 15, name


def _static_points(path, entity):
    from rerun.chunk import RrdReader

    for chunk in RrdReader(path).stream():
        if chunk.is_static and str(chunk.entity_path) == entity:
            batch = chunk.to_record_batch()
            col = next(n for n in batch.schema.names if n.endswith(":positions") or n.endswith(":lat_lon"))
            return len(batch.column(col).to_pylist()[0])
    return 0


def test_no_label_text_on_the_map_or_the_local_view_by_default(recording, shots):
    """Events and outage starts carry names, but only in hover text. A label is drawn in its marker's
    colour: with labels turned on, the event colour covered 8,548 pixels of this local view (the bound
    is 3,770); by default it stays within the markers. No white text over the tracks either (the local view's scale bar,
    in a bottom corner the track leaves free, the right one on this drive, is grey)."""
    from ionav_viz.viz.style import EVENT_COLOR, SCALE_COLOR

    n_events = _static_points(recording, "/local/events")
    assert n_events > 20
    marker_px = np.pi * 5.0**2  # a 3.5-point radius marker, antialiased edge included
    for view in ("map", "local"):
        # not the titles, nor the time panel and map attribution
        img = _image(shots("800x600", view, "end"))[TITLE_BAR_PX:-45]
        yellow = int((np.abs(img - np.array(EVENT_COLOR)).max(axis=-1) <= 60).sum())
        assert yellow < 1.2 * n_events * marker_px, (view, yellow, n_events)
        white = img.min(axis=-1) >= 200
        corner = np.zeros_like(white)
        corner[-int(0.25 * white.shape[0]):, : int(0.3 * white.shape[1])] = True
        corner[-int(0.25 * white.shape[0]):, -int(0.3 * white.shape[1]):] = True
        assert int(white[~corner].sum()) < 10, view
        if view == "local":  # the scale bar (grey: white was lost on the viewer's light theme) and its label
            assert int((np.abs(img[corner] - np.array(SCALE_COLOR)).max(axis=-1) <= 12).sum()) > 20


def test_outage_numbers_and_worst_of(recording, shots, tmp_path):
    # one image each, named by its number (all the names: test_several_times_views_and_outage_numbers_make_one_png_each)
    for number in (3, 7):
        assert shots("800x450", "local", f"outage{number}").is_file()
    for args, message in [(["--outage-number", "999"], "no outage 999 (the recording has 57)"),
                          (["--outage", "10s"], "to frame outage N give --outage-number N"),
                          (["--time", "worst", "--worst-of", "nope"], "choose one of")]:
        proc = run_cli("screenshot", str(recording), "-o", str(tmp_path / "x.png"), *args)
        assert proc.returncode == 2 and message in proc.stderr and proc.stderr.count("\n") == 1, (args, proc.stderr)
    # --outage is a length on every command; a bare number there keeps its old meaning, said as deprecated
    old = run_cli("screenshot", str(recording), "-o", str(tmp_path / "y.png"), "--outage", "999")
    assert old.returncode == 2 and "no outage 999" in old.stderr, old.stderr
    assert "warning: --outage 999: outage numbers are --outage-number now" in old.stderr, old.stderr


def test_a_time_that_is_no_duration_names_time(recording, shots, tmp_path):
    """--time -5s said "time '-5s' is not a duration (hint: use e.g. 10s, 500ms, 1m)": no option, and
    not that worst and end are times too; 0ms was refused while 0s was taken."""
    for bad in ("-5s", "ten"):
        proc = run_cli("screenshot", str(recording), "-o", str(tmp_path / "x.png"), "--time", bad)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert proc.stderr.startswith(f"error: --time: time '{bad}' is not a duration") and "'worst' or 'end'" in proc.stderr, proc.stderr
    assert not (tmp_path / "x.png").exists()
    assert shots("800x450", "local", "0000.0s").is_file()  # --time 0ms


def test_worst_of_picks_the_outage_with_the_largest_final_error_of_that_estimator(recording):
    """Against the final errors read back from the recording's error series, independently."""
    from ionav_viz.viz.recording_info import read_recording_info

    from .test_replay import read_rrd

    rows, _ = read_rrd(recording)
    info = read_recording_info(recording)
    for est in ("ins", "idnn"):
        series = [(t, v[0]) for t, v in rows[f"/errors/position_error_m/{est}"] if v[0] == v[0]]
        finals = [max((r for r in series if o.start_s < r[0] <= o.end_s + 1e-6), key=lambda r: r[0])[1] for o in info.outages]
        assert info.worst(est).number == int(np.argmax(finals)) + 1


@pytest.mark.parametrize("size", [(1600, 900), (1280, 720)])
def test_review_layout_titles_fit_their_views(recording, size):
    """Every title of the 'all' layout, at the worst outage, fits its column's width (at the title
    font's measured width per character)."""
    from ionav_viz.viz.blueprints import TITLE_ICONS_PX, TITLE_PX_PER_CHAR, Shot, column_fraction, titles_for
    from ionav_viz.viz.recording_info import read_recording_info

    info = read_recording_info(recording)
    worst = info.worst()
    titles = titles_for(info, Shot("all", worst.end_s, "worst", worst), size[0])
    assert f"outage {worst.number}" in titles["inspect"] or f"#{worst.number}" in titles["inspect"]
    # each final error in the inspector's title, or (a narrow column) in the image's key, the title saying so
    from ionav_viz.viz.blueprints import key_for

    key = " ".join(k.text for k in key_for(info, Shot("all", worst.end_s, "worst", worst)))
    shown = titles["inspect"] if "key" not in titles["inspect"] else key
    assert all(f"{worst.final_error_m[e]:.1f}" in shown for e in COLORS if e != "gnss"), (titles["inspect"], key)
    assert all(f"{label} " in shown for label, _rgb in info.estimators.values())  # by their labels
    for origin, title in titles.items():
        assert len(title) * TITLE_PX_PER_CHAR + TITLE_ICONS_PX <= size[0] * column_fraction(origin), (origin, title)


@pytest.mark.parametrize("view", ["map", "local"])
def test_png_has_the_size_and_every_estimator_colour(shots, view):
    from PIL import Image

    out = shots("1200x700", view, "worst")
    assert Image.open(out).size == (1200, 700)
    for name in ("gnss", "ins", "idnn"):
        assert _pixels_near(out, COLORS[name]) > 50, name


def test_several_times_views_and_outage_numbers_make_one_png_each(shots):
    """One PNG per view and time (--view map --view local --view signals --view errors --time 35s --time
    end), and per view and outage number; the command prints the path of each."""
    folder = shots.folder("800x600")
    names = sorted(p.name for p in folder.iterdir())
    assert names == sorted(f"V-sim-sharp-cornering-{view}-{time}.png" for view in ("map", "local", "signals", "errors")
                           for time in ("0035.0s", "end"))
    assert sorted(shots.procs["800x600"].stdout.splitlines()) == sorted(str(folder / name) for name in names)
    # --view local --time worst --time 291s --time 0ms --outage-number 3 --outage-number 7
    names = sorted(p.name for p in shots.folder("800x450").iterdir())
    assert names == ["V-sim-sharp-cornering-local-0000.0s.png", "V-sim-sharp-cornering-local-0291.0s.png",
                     "V-sim-sharp-cornering-local-outage3.png", "V-sim-sharp-cornering-local-outage7.png",
                     "V-sim-sharp-cornering-local-worst.png"]


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


def test_two_runs_in_parallel(recording, renderer, tmp_path):
    private_tmp = tmp_path / "tmp"
    private_tmp.mkdir()
    cmds = [[sys.executable, "-m", "ionav_viz.cli", "screenshot", str(recording), "-o", str(tmp_path / f"p{i}.png"),
             "--view", "local", "--size", "600x400"] for i in range(2)]
    env = {**os.environ, "TMPDIR": str(private_tmp)}
    procs = [subprocess.Popen(c, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for c in cmds]
    results = [p.communicate(timeout=HANG_S) for p in procs]
    assert all(p.returncode == 0 for p in procs), results
    assert (tmp_path / "p0.png").is_file() and (tmp_path / "p1.png").is_file()
    assert list(private_tmp.iterdir()) == []  # the viewers' scratch folders are gone too
    assert _viewers_under(private_tmp) == set()


def _no_renderer_env(tmp_path):
    """Environment variables under which the viewer finds no renderer."""
    return {"VK_ICD_FILENAMES": str(tmp_path / "none.json"), "LIBGL_ALWAYS_SOFTWARE": "0", "MESA_LOADER_DRIVER_OVERRIDE": "none",
            "GALLIUM_DRIVER": "none", "WGPU_BACKEND": "vulkan"}


def _viewer_children():
    """Headless viewer processes started by this process."""
    from pathlib import Path

    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and f"PPid:\t{os.getpid()}\n" in (proc / "status").read_text() and b"--headless" in (proc / "cmdline").read_bytes():
                found.append(proc.name)
        except OSError:
            continue
    return found


def test_missing_renderer_is_a_clear_error_and_leaves_no_viewer(recording, tmp_path):
    private_tmp = tmp_path / "tmp"
    private_tmp.mkdir()
    env = {"TMPDIR": str(private_tmp), **_no_renderer_env(tmp_path)}
    proc = run_cli("screenshot", str(recording), "-o", str(tmp_path / "x.png"), "--size", "400x300", env=env, timeout=HANG_S)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "mesa-vulkan-drivers" in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1  # one line; the viewer's own output stays out of the terminal
    assert not (tmp_path / "x.png").exists()
    assert _viewers_under(private_tmp) == set()  # the viewer is stopped before the command returns
    assert list(private_tmp.iterdir()) == []


def test_a_viewer_entered_has_answered(tmp_path, monkeypatch):
    """``with HeadlessViewer(...) as viewer:`` (tests/test_live.py, a fleet overview's image) enters
    with a viewer that answers, or raises RendererMissing there, before its body (a screenshot
    enters at once with wait=False, and reads its recordings while the viewer starts)."""
    from ionav_viz.viz.viewer import HeadlessViewer, RendererMissing

    for name, value in _no_renderer_env(tmp_path).items():
        monkeypatch.setenv(name, value)
    body = []
    with pytest.raises(RendererMissing, match="mesa-vulkan-drivers"), HeadlessViewer(400, 300):
        body.append("entered")
    assert body == [] and _viewer_children() == []


def test_a_starting_viewer_is_watched_without_the_rerun_package():
    """Entering a viewer with wait=False starts its process and watches for its first answer without
    importing the rerun package, which takes about a second (a starting viewer answers in less): in a
    fresh 'ionav-viz screenshot' the toasts' wait counts from the viewer's answer, not from that import."""
    code = ("import sys\nfrom ionav_viz.viz.viewer import HeadlessViewer\n"
            "with HeadlessViewer(400, 300, wait=False):\n    print('rerun' in sys.modules)\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=HANG_S)
    assert proc.returncode == 0 and proc.stdout.split() == ["False"], proc.stdout + proc.stderr


def test_the_recording_is_read_while_the_viewer_starts_and_bad_input_is_said_first(recording, tmp_path, monkeypatch):
    """The viewer is started first and the recording read while it starts and its start-up toasts
    fade (it was read before, the viewer's wait coming after). A bad option found in reading it
    is still said, not a missing renderer, and stops the viewer: no viewer and no file left."""
    import ionav_viz as iv
    import ionav_viz.viz.screenshot as screenshot
    from ionav_viz.core.errors import InputError
    from ionav_viz.viz.viewer import HeadlessViewer

    # the order, not a count of processes at reading time: a viewer process that is slow to show
    # its command line on a loaded machine must not fail the test
    real, real_enter, events = screenshot.read_recording_info, HeadlessViewer.__enter__, []

    def enter(viewer):
        started = real_enter(viewer)
        events.append("viewer started" if viewer.proc is not None else "no viewer")
        return started

    def read(path):
        events.append("read")
        return real(path)

    monkeypatch.setattr(HeadlessViewer, "__enter__", enter)
    monkeypatch.setattr(screenshot, "read_recording_info", read)
    out = tmp_path / "out"
    for env in ({}, _no_renderer_env(tmp_path)):
        with monkeypatch.context() as m:
            for name, value in env.items():
                m.setenv(name, value)
            with pytest.raises(InputError, match="no outage 999"):
                iv.screenshot(recording, out / "x.png", iv.Shots(views=["local"], outages=[999]))
        assert _viewer_children() == [] and not out.exists()
    assert events[:2] == ["viewer started", "read"], events


def test_replay_with_screenshot_dir(tmp_path):
    proc = run_cli("replay", "motorway", "-o", str(tmp_path / "m.rrd"), "-q", "--no-idnn", "--screenshot", str(tmp_path / "shots"))
    if proc.returncode == 1 and "mesa" in proc.stderr and not os.environ.get("CI"):
        pytest.skip("no renderer on this machine")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "shots").iterdir()) == [
        f"V-sim-motorway-{v}-worst.png" for v in ("all", "errors", "health", "local", "map", "outage", "signals")]


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


# --- round 3: crafted and damaged recordings ----------------------------------------------------

def test_a_recording_with_an_entity_of_another_type(tmp_path):
    """Round 3: /gnss/state logged as another type gave a StopIteration traceback."""
    import rerun as rr

    path = tmp_path / "crafted.rrd"
    rec = rr.RecordingStream("ionav-viz", recording_id="crafted")
    rec.save(path)
    rec.set_time("time", duration=1.0)
    rec.log("/gnss/state", rr.Points2D([[0, 0]]))
    rec.flush()
    rec.disconnect()
    proc = run_cli("screenshot", str(path), "-o", str(tmp_path / "x.png"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert f"{path}: /gnss/state holds no state (it is logged as another type)" in proc.stderr


def test_a_truncated_recording_is_one_line(recording, tmp_path):
    """Round 3: a truncated .rrd printed a raw two-line RerunWarning before the error."""
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(recording.read_bytes()[: recording.stat().st_size // 2])
    proc = run_cli("screenshot", str(cut), "-o", str(tmp_path / "x.png"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert f"{cut}: not a readable Rerun recording" in proc.stderr and "RerunWarning" not in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.rrd"]


def test_a_missing_view_names_the_recording_and_leaves_no_folders(recording, renderer, tmp_path):
    """Round 3: '-o new/deep/ --view local' on a recording without that view exited 2 but left the
    folders it made, and the message did not name the file."""
    import rerun as rr
    import rerun.blueprint as rrb
    from rerun.chunk import RrdReader

    path = tmp_path / "noview.rrd"
    rec = rr.RecordingStream("ionav-viz", recording_id="V-sim-sharp-cornering-10s")
    rec.save(path)
    rec.send_chunks(list(RrdReader(recording).stream()))  # the data, without the recording's own layout
    rec.send_blueprint(rrb.Blueprint(rrb.TextDocumentView(origin="/summary")))  # the review layout without its views
    rec.flush()
    rec.disconnect()
    proc = run_cli("screenshot", str(path), "-o", str(tmp_path / "new" / "deep") + "/", "--view", "local", "--size", "400x300")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert f"{path}: the recording has no local view" in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["noview.rrd"]


@pytest.mark.parametrize("size", ["1600x900", "1280x720", "1024x576"])
def test_clean_review_images_with_the_whole_summary(shots, size):
    """Issue 31.1: only the views: no menu, badges or timeline (the top rows are background, the
    orange of the 'Software rasterizer' and 'Docker' badges is nowhere), and the summary tab ends
    above the image's bottom edge (its last line drawn, nothing cut) in the review layout; issue
    46.1: at 1024x576 too, and its table ends left of the image's right edge."""
    img = _image(shots(size, "all", "end"))
    h, w, _ = img.shape
    # above the views the colour key (issue 46.1), not the top panel: its green truth swatch, no badge
    assert (np.abs(img[1:30] - np.array(GNSS_COLOR)).max(axis=-1) <= 40).sum() > 15, "no colour key above the views"
    badge_orange = (np.abs(img - np.array([255, 140, 40])).max(axis=-1) <= 40) & (img[..., 0] > 200) & (img[..., 2] < 90)
    assert badge_orange[: h // 10].sum() == 0
    # the summary sits at the bottom of the right-hand column: its last line ends above the rows
    # where the view clips its text (a cut line runs into them), and nothing reaches the right edge
    from ionav_viz.viz.blueprints import TITLE_BAR_PX, shot_rows

    top = int(h - shot_rows((w, h), 4).errors[-1]) + TITLE_BAR_PX + 4  # below the summary's title bar (its icons)
    text = img[top:, int(0.72 * w): w - 3].max(axis=-1) > 80
    text_rows = np.nonzero(text.any(axis=1))[0] + top
    assert text_rows.max() <= h - 18, f"the summary runs into the bottom edge (text down to row {text_rows.max()} of {h})"
    assert not text[:, -12:].any(), "the summary's table runs into the right edge"
    assert len(np.nonzero(np.ptp(img[int(0.6 * h):, int(0.72 * w):], axis=(1, 2)) > 60)[0]) > 40  # a summary of several lines


def test_time_plots_end_at_the_drive_end_and_the_map_gives_way_offline():
    """Issue 31.1: the time plots of a shot show a minute inside the drive (--time end: ending at
    its end), and without map tiles the map view is left out of the layout, the local view taking
    its place (and a --view map shot draws the local view)."""
    from ionav_viz.viz import entities as ent
    from ionav_viz.viz.blueprints import ShotLayout, focus_blueprint, plot_window

    # the start at a whole 10 s: a tick just before it was labelled at the plot's left edge, cut ("m" of "+6m")
    assert plot_window(341.8, 341.8) == (280.0, 341.8) and plot_window(10.0, 341.8) == (0.0, 60.0)
    assert plot_window(100.0, 341.8) == (70.0, 130.0) and plot_window(5.0, 30.0) == (0.0, 30.0)
    bp = {
        "/viewport": {"ViewportBlueprint": {"root_container": "/container/root"}},
        "/container/root": {"ContainerBlueprint": {"container_kind": "Horizontal", "contents": ["/container/tracks", "/view/ts"],
                                                   "col_shares": [1, 1]}},
        "/container/tracks": {"ContainerBlueprint": {"container_kind": "Horizontal", "contents": ["/view/local", "/view/map"],
                                                     "col_shares": [1, 1]}},
        "/view/local": {"ViewBlueprint": {"class_identifier": "2D", "space_origin": ent.LOCAL}},
        "/view/map": {"ViewBlueprint": {"class_identifier": "Map", "space_origin": ent.MAP}},
        "/view/ts": {"ViewBlueprint": {"class_identifier": "TimeSeries", "space_origin": ent.DISPLACEMENTS}},
    }
    online = focus_blueprint(bp, "all", {}, layout=ShotLayout(t_s=341.8, end_s=341.8))
    view_range = online["/view/ts/TimeAxis"]["TimeAxis"]["view_range"]
    assert view_range["end"] == {"Absolute": 345_800_000_000}  # + room for the last label
    assert 277_000_000_000 < view_range["start"]["Absolute"] < 280_000_000_000  # and the first
    assert "/view/map" in online and all(online[p] == {k: {**v, "state": "Hidden"}} for p, (k, v) in
                                         {"/top_panel": ("PanelBlueprint", {}), "/time_panel": ("TimePanelBlueprint", {})}.items())
    offline = focus_blueprint(bp, "all", {}, layout=ShotLayout(map_tiles=False))
    assert "/view/map" not in offline and offline["/container/tracks"]["ContainerBlueprint"]["contents"] == ["/view/local"]
    maximised = focus_blueprint(bp, "map", {}, layout=ShotLayout(map_tiles=False))["/viewport"]["ViewportBlueprint"]["maximized"]
    assert maximised == "local"


# --- issue 46.1: every view reads on its own --------------------------------------------------

def _label_runs(img, y0, y1, x1=24, bright=100, rows_of_text=(6, 14)):
    """Tick labels left of a plot between rows y0 and y1: runs of rows with light text in x < x1,
    as tall as a line of text (labels 20-30 px apart are drawn faded, at about 120 of 255)."""
    rows = np.nonzero(img[y0:y1, :x1].max(axis=(1, 2)) > bright)[0]
    runs = []
    for r in rows:
        if runs and r - runs[-1][1] <= 1:
            runs[-1][1] = r
        else:
            runs.append([r, r])
    return [r for r in runs if rows_of_text[0] <= r[1] - r[0] + 1 <= rows_of_text[1]]


def _plot_rows(size, shares, k):
    """Rows (top, bottom) of the drawing area of the k-th row of a column of ``shares`` (pixels,
    :func:`shot_rows`) in a screenshot of ``size`` (below the key band; without the title bar and
    the time labels)."""
    from ionav_viz.viz.blueprints import TIME_LABELS_PX, TITLE_BAR_PX, TOP_BAND_PX

    views_px = size[1] - TOP_BAND_PX
    top = TOP_BAND_PX + views_px * sum(shares[:k]) / sum(shares)
    bottom = TOP_BAND_PX + views_px * sum(shares[: k + 1]) / sum(shares)
    return int(top + TITLE_BAR_PX), int(bottom - TIME_LABELS_PX)


def _no_legend(img, y0, y1):
    """No legend box in the plot between rows y0 and y1: no bright text inside it (the time cursor,
    a bright vertical line, aside)."""
    area = img[y0:y1, 40:]
    text = (area.min(axis=-1) >= 185) & (np.ptp(area, axis=-1) <= 12)
    grey = (area.min(axis=-1) >= 140) & (np.ptp(area, axis=-1) <= 12)
    for c in np.nonzero(grey.mean(axis=0) > 0.3)[0]:  # the time cursor (a grey line) and its bright head
        text[:, max(c - 8, 0): c + 9] = False
    return int(text.sum())


def test_views_read_on_their_own(shots):
    """At 1600x900: the colour key in the band above the views names the truth and every
    estimator in their colours (the band is not empty), no legend box over the curves, and every
    time plot of the signals and errors columns has at least three labelled y ticks (a yaw rate
    and an acceleration that showed a single '0'). At 1024x576 the key still fits, with every
    colour, above the whole layout."""
    from ionav_viz.viz.blueprints import TOP_BAND_PX, shot_rows

    signals, errors = (_image(shots("1600x900", v, "end")) for v in ("signals", "errors"))
    small = shots("1024x576", "all", "worst")
    for img, drawn in ((signals, COLORS), (errors, {k: v for k, v in COLORS.items() if k != "gnss"}), (_image(small), COLORS)):
        band = img[1:TOP_BAND_PX]
        for name, rgb in drawn.items():
            assert (np.abs(band - np.array(rgb)).max(axis=-1) <= 40).sum() > 15, f"{name} missing from the key"
        assert (band.min(axis=-1) > 180).sum() > 200  # the names, as text
    assert (np.abs(errors[1:TOP_BAND_PX] - np.array(GNSS_COLOR)).max(axis=-1) <= 40).sum() == 0  # the errors draw no truth line
    rows = shot_rows((1600, 900), 4)
    assert rows.yaw_crse  # three error plots at 1600x900
    for img, shares, plots in ((signals, rows.signals, (1, 2, 3)), (errors, rows.errors, (0, 1, 2))):
        for k in plots:
            y0, y1 = _plot_rows((1600, 900), shares, k)
            labels = _label_runs(img, y0, y1)
            assert len(labels) >= 3, (k, labels)
            assert _no_legend(img, y0, y1) < 25, k


@pytest.mark.parametrize("size", ["1280x720", "1024x576"])
@pytest.mark.parametrize("time", ["end", "worst"])
def test_small_images_label_every_plot(shots, size, time):
    """Issue 46.1 at 1280x720 and 1024x576: every time plot of the signals and errors columns has
    at least three labelled y ticks (the acceleration, and at 1024 the error plots, showed a single
    '0'); a small image leaves out the orientation-rate CRSE rather than draw it too low for them,
    and at 1024x576 the acceleration and the CRSE and CAE too (three labels had the displacement's
    0-30 m under ticks of 100, in the plot's bottom fifth, and the errors' 0-52 m): the displacement
    and the yaw rate each take half the column, the position error all the errors column's plots."""
    from ionav_viz.viz.blueprints import shot_rows
    from ionav_viz.viz.screenshot import parse_size

    w, h = parse_size(size)
    rows = shot_rows((w, h), 4)
    assert not rows.yaw_crse and rows.accel == rows.crse == (size == "1280x720")
    assert len(rows.signals) == (4 if rows.accel else 3) and len(rows.errors) == (3 if rows.crse else 2)
    for view, shares, plots in (("signals", rows.signals, range(1, len(rows.signals))),
                                ("errors", rows.errors, range(len(rows.errors) - 1))):
        img = _image(shots(size, view, time))
        assert img.shape[:2] == (h, w)
        for k in plots:
            y0, y1 = _plot_rows((w, h), shares, k)
            labels = _label_runs(img, y0, y1)
            assert len(labels) >= 3, (view, k, labels)
            assert _no_legend(img, y0, y1) < 25, (view, k)


def _text_at_edge(img, x: int) -> np.ndarray:
    """Rows (below the key band) with light text in pixel column ``x``, a view's first: a label cut at
    its left edge (horizontal lines, the state timeline's axis, aside)."""
    from ionav_viz.viz.blueprints import TOP_BAND_PX

    light = img[TOP_BAND_PX:, x : x + 40].min(axis=-1) > 60  # the faded labels too (about 80), not the grid (55)
    rule = light[:, 1:].all(axis=1)
    return np.nonzero(light[:, 0] & ~rule)[0] + TOP_BAND_PX


def test_the_first_time_label_is_whole(shots):
    """Issue 63: the time plots began at their first tick, whose label is centred on it: a view as
    wide as the image (signals, errors, filter health) drew it across the image's left edge ("4m
    40s" of "+4m 40s"). They now start a little before it, but not so much that the label of the
    tick before it is drawn at the view's edge ("0s" of "+4m 30s", in the review layout's columns):
    no text at the left edge of any of those views, at 1024x576 and at the review layout's 1600x900."""
    for view in ("signals", "errors", "health"):
        cut = _text_at_edge(_image(shots("1024x576", view, "worst")), 0)
        assert len(cut) == 0, (view, cut)
    img = _image(shots("1600x900", "all", "0305.0s"))  # ticks +4m 30s, +4m 40s, ...
    for column_x in (640, 1120):  # the signals and errors columns (4:3:3 of 1600 px)
        cut = _text_at_edge(img, column_x)
        assert len(cut) == 0, (column_x, cut)


def _last_ruler_label_px(img, x0: int, x1: int) -> int:
    """The width (pixels) of the last label of the state timeline's time ruler, up to the ruler's end
    (its torn edge), in the view spanning columns ``x0``..``x1``: a label cut there is narrower."""
    from ionav_viz.viz.blueprints import TOP_BAND_PX

    grey = img[:, x0:x1].mean(axis=-1)
    y_sep = next(y for y in range(TOP_BAND_PX, TOP_BAND_PX + 120) if (grey[y] > 90).mean() > 0.6)  # under the ruler
    ruler = grey[y_sep - 14 : y_sep - 6]  # the labels' rows, above the tick marks
    x_end = int(np.nonzero((ruler < 5).mean(axis=0) > 0.5)[0].max())
    text = np.nonzero((ruler[:, : x_end + 1] > 40).any(axis=0))[0]
    # runs of columns a few pixels apart at most (a label's glyphs); a tick mark past the last label is one column
    runs = np.split(text, np.nonzero(np.diff(text) > 4)[0] + 1)
    return max(int(run[-1] - run[0] + 1) for run in runs[-2:])


def test_the_state_timelines_last_time_label_is_whole(shots):
    """Issue 63: the state timeline's ruler spans the recording's data, and a bundled drive's ends at
    600 s, a whole ten minutes: its "+10m" was cut at the ruler's end to a lone "+" (review layout,
    signals view). The recording now ends where the label is whole: "+10m" (27 px) whole at the
    ruler's end at 1024x576 and 1600x900, in the review layout's signals column and the signals view."""
    for size in ("1024x576", "1600x900"):
        width = int(size.split("x")[0])
        for view, (x0, x1) in (("all", (int(0.4 * width), int(0.7 * width))), ("signals", (0, width))):
            label_px = _last_ruler_label_px(_image(shots(size, view, "worst")), x0, x1)
            assert label_px >= 24, (size, view, label_px)


def test_key_entries_and_y_ranges():
    """What the key names per view (the truth where it is drawn, the markers where they are),
    and y ranges: three ticks a power of ten apart with room for their labels, a flat line
    included; the squeeze-avoiding fallback in a small plot."""
    from ionav_viz.viz.blueprints import ELLIPSE_KEY_COLOR, TICK_PX, KeyEntry, Shot, axis_range, key_for, plot_range
    from ionav_viz.viz.recording_info import OutageInfo, RecordingInfo

    info = RecordingInfo(path=None, drive="d", end_s=100.0, states=[], outages=[], lat_deg=np.zeros(0), lon_deg=np.zeros(0),
                         estimators={"ins": ("INS DR", (230, 60, 50)), "ekf": ("GNSS-aided INS", (0, 170, 190))})
    texts = {view: [k.text for k in key_for(info, Shot(view, 50.0, "x"))] for view in ("all", "errors", "local", "outage")}
    assert texts["all"] == ["GNSS (truth)", "INS DR", "GNSS-aided INS", "gyro, accelerometer", "manoeuvre", "outage start"]
    assert texts["errors"] == ["INS DR", "GNSS-aided INS"] and texts["local"][-2:] == ["manoeuvre", "outage start"]
    assert texts["outage"][-1] == "start fix"
    # issue 43.4: the 95 % ellipses where the tracks are drawn, once an outage has begun
    info.ellipses = {"ekf"}
    info.outages = [OutageInfo(1, 10.0, 20.0, {"ins": 1.0, "ekf": 1.0}, np.zeros((0, 2)), np.zeros(0), np.zeros(0))]
    for view in ("all", "outage"):
        assert key_for(info, Shot(view, 50.0, "x"))[-1] == KeyEntry("ellipse", ELLIPSE_KEY_COLOR, "95 % ellipse"), view
        assert "95 % ellipse" not in [k.text for k in key_for(info, Shot(view, 5.0, "x"))]  # before the first outage
    for view in ("local", "map"):  # the whole drive: ellipses of a few pixels are not named; framed on an outage, they are
        assert "95 % ellipse" not in [k.text for k in key_for(info, Shot(view, 50.0, "x"))], view
        assert key_for(info, Shot(view, 20.0, "x", info.outages[0]))[-1] == KeyEntry("ellipse", ELLIPSE_KEY_COLOR, "95 % ellipse"), view
    for view in ("signals", "errors", "health"):
        assert "95 % ellipse" not in [k.text for k in key_for(info, Shot(view, 50.0, "x"))]
    info.outages = []
    # the filter-health view: its lines in the key (the plot shows no legend), then the grey '1'
    info.health = [("GNSS-aided INS: GNSS speed", (255, 127, 14)), ("GNSS-aided INS: GNSS course", (44, 160, 44))]
    health = key_for(info, Shot("health", 50.0, "x"))
    assert [k.text for k in health[:2]] == ["GNSS-aided INS: GNSS speed", "GNSS-aided INS: GNSS course"]
    assert health[0].rgb == (255, 127, 14) and health[-1].text.startswith("1: a consistent")
    o = OutageInfo(3, 10.0, 20.0, {"ins": 12.34, "ekf": 1.0}, np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    assert [k.text for k in key_for(info, Shot("outage", 20.0, "outage3", o))][1:3] == ["INS DR 12.3 m", "GNSS-aided INS 1.0 m"]

    def ticks(lo, hi, px):
        a, b = axis_range(lo, hi, px)
        step = 10.0 ** np.floor(np.log10((b - a) / 2))  # labelled ticks inside, at the finest step that is
        for s in (step / 10, step, step * 10):
            inside = np.arange(np.ceil(a / s), np.floor(b / s) + 1) * s
            if px * s / (b - a) >= TICK_PX:
                return a, b, inside
        return a, b, np.zeros(0)

    # the plots' heights at 1024x576 (78 and 93 px) and 1280x720 (126 px) included: three labels
    # whatever the data's span, the data filling as much of the plot as the labels allow
    for lo, hi, px in [(-0.42, 0.61, 190), (-2.45, 2.55, 114), (0.0, 29.1, 120), (0.0, 0.22, 91), (0.0, 16.5, 100),
                       (0.0, 7.32, 154), (0.0, 28.6, 93), (0.0, 36.97, 93), (-28.6, 6.44, 93), (-3.53, 3.04, 78),
                       (-2.45, 2.55, 126), (0.0, 27.6, 78), (-0.02, 0.67, 78), (0.0, 0.06, 154)]:
        a, b, inside = ticks(lo, hi, px)
        assert a <= lo and b >= hi and len(inside) >= 3, (lo, hi, px, a, b, inside)
        assert (hi - lo) / (b - a) > 0.1, (lo, hi, px)
    assert ticks(-2.45, 2.55, 130)[1] < 3.5  # where a 1 m/s² step is labelled, the range is not widened to ±10
    flat = plot_range("signals/yaw_rate_radps", 0.0, 0.0, pad=False)
    assert flat == (-0.05, 0.05) and len(ticks(*flat, 150)[2]) >= 3
    assert plot_range("errors/position_error_m", 3.0, 9.0, pad=False)[0] == 0.0  # magnitudes from zero
    a, b = axis_range(0.0, 29.1, 40)  # too small for three labels: the data's own range, its labels not cut
    assert a < 0.0 and 29.1 < b < 40.0 and 7 / 40 <= -a / (b - a) < 0.25


def test_a_long_key_takes_two_lines_in_the_band(tmp_path):
    """Six estimators with final errors and a long plug-in name at 1024 px: two lines of the key,
    every colour in the band above the views, nothing drawn below it."""
    from PIL import Image

    from ionav_viz.viz.blueprints import TOP_BAND_PX, KeyEntry
    from ionav_viz.viz.screenshot import draw_key

    blank = np.full((576, 1024, 3), 13, dtype=np.uint8)
    blank[TOP_BAND_PX] = 53  # the views' top border
    png = tmp_path / "k.png"
    Image.fromarray(blank).save(png)
    colors = [(0, 170, 80), (230, 60, 50), (0, 170, 190), (40, 110, 240), (150, 60, 200), (235, 160, 0), (230, 140, 20)]
    keys = [KeyEntry("line", c, f"estimator number {i} with a long name 12.3 m") for i, c in enumerate(colors)]
    draw_key(png, keys, "outage 31, final error:")
    img = _image(png)
    for c in colors:
        assert (np.abs(img[1:TOP_BAND_PX] - np.array(c)).max(axis=-1) <= 30).sum() > 5, c
    assert (img[TOP_BAND_PX + 1:] == blank[TOP_BAND_PX + 1:]).all()


def test_the_viewer_names_the_lines_in_a_key_not_in_legends(recording):
    """Issue 46.1 in the viewer: no time plot of the signals and errors draws a legend over its
    curves (only the sigma-vs-error and filter-health tabs keep theirs: they name series the key
    does not); a key above the signals names the truth, every estimator, the sensors and the
    ellipses by colour; screenshots leave that view out (they draw their own key)."""
    from rerun.chunk import RrdReader

    from ionav_viz.viz import entities as ent
    from ionav_viz.viz.blueprints import blueprint
    from ionav_viz.viz.recording_info import read_recording_info
    from ionav_viz.viz.style import color_word

    def views(c):
        for x in c.contents:
            yield from (views(x) if not hasattr(x, "origin") else [x])

    shown = list(views(blueprint(["INS DR"]).root_container))
    assert next(v.origin for v in shown if type(v).__name__ == "TextDocumentView") == ent.KEY
    for v in shown:
        if type(v).__name__ == "TimeSeriesView" and v.origin not in (ent.UNCERTAINTY, ent.HEALTH):
            assert "visible=[False]" in str(v.properties.get("PlotLegend")), v.origin
    texts = [chunk.to_record_batch().column(n).to_pylist()[0] for chunk in RrdReader(recording).stream()
             if str(chunk.entity_path).strip("/") == ent.KEY for n in chunk.to_record_batch().schema.names if n.endswith(":text")]
    assert len(texts) == 1
    key = str(texts[0][0] if isinstance(texts[0], list) else texts[0])
    info = read_recording_info(recording)
    for label, rgb in [(info.truth_label, GNSS_COLOR), *info.estimators.values()]:
        assert f"{label} {color_word(rgb)}" in key, (label, key)
    assert "accelerometer grey" in key and "95 % ellipses" in key


def test_the_health_view_names_its_lines_in_the_key(recording, shots):
    """Issue 46.1: the filter-health view's legend covered its curves; its lines are named in the
    key above the view (each filter's kinds of measurement, in their colours), none over the plot."""
    from ionav_viz.viz.blueprints import TITLE_BAR_PX, TOP_BAND_PX
    from ionav_viz.viz.recording_info import read_recording_info

    info = read_recording_info(recording)
    assert info.health  # the GNSS-aided INS's kinds of measurement
    img = _image(shots("1024x576", "health", "end"))
    for label, rgb in info.health:
        assert (np.abs(img[1:TOP_BAND_PX] - np.array(rgb)).max(axis=-1) <= 30).sum() > 5, label
    assert _no_legend(img, TOP_BAND_PX + TITLE_BAR_PX + 4, 576 - 24) < 25


def test_a_tab_bar_too_narrow_for_its_titles_keeps_only_the_active_tab():
    """Issue 46.1 (no clipped titles): the error column's four tabs need about 400 px at their
    shortest titles ("Error (m)", "Drift", "Sigma", "NIS": 22 characters at 6.3 px, 36 px a tab and
    100 px of buttons); at 1024 px the column has about 300, so an image keeps only the active tab;
    at 1600 (about 470 px) all four stay, as does the two-tab CRSE/CAE bar where it is drawn (1280
    px and up: a 1024x576 image leaves the CRSE and CAE out, see shot_rows)."""
    from ionav_viz.viz import entities as ent
    from ionav_viz.viz.blueprints import ShotLayout, focus_blueprint

    four = [ent.error_group("position_error_m"), ent.DRIFT, ent.UNCERTAINTY, ent.HEALTH]
    views = {f"/view/t{i}": {"ViewBlueprint": {"class_identifier": "TimeSeries", "space_origin": o}} for i, o in enumerate(four)}
    bp = {
        "/viewport": {"ViewportBlueprint": {"root_container": "/container/root"}},
        "/container/root": {"ContainerBlueprint": {"container_kind": "Vertical", "contents": ["/container/tabs", "/container/two"]}},
        "/container/tabs": {"ContainerBlueprint": {"container_kind": "Tabs", "contents": list(views), "active_tab": "/view/t0"}},
        "/container/two": {"ContainerBlueprint": {"container_kind": "Tabs", "contents": ["/view/crse", "/view/cae"], "active_tab": "/view/crse"}},
        "/view/crse": {"ViewBlueprint": {"class_identifier": "TimeSeries", "space_origin": ent.error_group("crse_m")}},
        "/view/cae": {"ViewBlueprint": {"class_identifier": "TimeSeries", "space_origin": ent.error_group("cae_m")}},
        **views,
    }
    small = focus_blueprint(bp, "all", {}, layout=ShotLayout(size=(1024, 576)))
    assert small["/container/tabs"]["ContainerBlueprint"]["contents"] == ["/view/t0"] and "/view/t3" not in small
    assert "/container/two" not in small and "/view/crse" not in small
    middle = focus_blueprint(bp, "all", {}, layout=ShotLayout(size=(1280, 720)))
    assert len(middle["/container/two"]["ContainerBlueprint"]["contents"]) == 2
    large = focus_blueprint(bp, "all", {}, layout=ShotLayout(size=(1600, 900)))
    assert large["/container/tabs"]["ContainerBlueprint"]["contents"] == list(views)


def test_a_recording_through_real_losses_alone_inspects_the_last_one(tmp_path):
    """In a replay through the log's own losses alone the inspector shows the last loss begun (its
    title names it), as it shows the last synthetic outage; before the first, 'no outage yet'."""
    from ionav_viz.viz.blueprints import TITLE_ICONS_PX, TITLE_PX_PER_CHAR, Shot, column_fraction, titles_for
    from ionav_viz.viz.recording_info import read_recording_info

    out = tmp_path / "tunnels.rrd"
    proc = run_cli("replay", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins", "-q", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    info = read_recording_info(out)
    assert info.outages == [] and info.real_outages
    last = max((o for o in info.real_outages if o.start_s < 300.0), key=lambda o: o.start_s)
    for width in (1600, 1024):
        titles = titles_for(info, Shot("all", 300.0, "300s", None), width)
        assert f"real GNSS outage {last.number} (" in titles["inspect"], titles["inspect"]
        assert len(titles["inspect"]) * TITLE_PX_PER_CHAR + TITLE_ICONS_PX <= width * column_fraction("inspect")
    assert "no outage yet" in titles_for(info, Shot("all", 1.0, "1s", None), 1600)["inspect"]


@pytest.fixture(scope="module")
def real_losses(tmp_path_factory):
    """A replay through the bundled tunnel drive's own six losses alone, and its JSON report."""
    import json

    folder = tmp_path_factory.mktemp("real")
    out = folder / "tunnels.rrd"
    proc = run_cli("replay", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins,odo", "-q", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    rep = run_cli("evaluate", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins,odo", "--json")
    assert rep.returncode == 0, rep.stderr
    return out, json.loads(rep.stdout)["gnss_outages"]["bridged"]


#: The tunnel drive's images the tests below look at (as :data:`BATCHES`).
REAL_BATCHES = {"800x450": (("local", "outage"), ("worst", "end"), ())}


@pytest.fixture(scope="module")
def real_shots(real_losses, tmp_path_factory):
    return Shots(real_losses[0], tmp_path_factory.mktemp("real-shots"), REAL_BATCHES, "V-sim-motorway-tunnels")


@pytest.fixture(scope="module")
def tunnel_replay_shots(tmp_path_factory):
    """The folder of ``replay V-sim-motorway-tunnels --on gnss-outage --estimators ins --screenshot``
    (every view at the worst real loss, 1600x900)."""
    folder = tmp_path_factory.mktemp("tunnel-replay")
    shots = folder / "shots"
    proc = run_cli("replay", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins",
                   "-o", str(folder / "t.rrd"), "--screenshot", str(shots))
    if _no_renderer(proc):
        pytest.skip(f"no renderer on this machine: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    return shots


def test_no_label_of_the_tick_before_the_plots_shows_beside_wide_y_labels(tunnel_replay_shots):
    """The tunnel drive's yaw rate (y labels "-0.1" to "0.1", the widest) showed the "s" of the tick
    before its first at the signals column's edge in the review layout: nothing there now."""
    img = _image(tunnel_replay_shots / "V-sim-motorway-tunnels-all-worst.png")
    for column_x in (640, 1120):
        cut = _text_at_edge(img, column_x)
        assert len(cut) == 0, (column_x, cut)


def test_a_recording_through_real_losses_alone_frames_them_by_number_and_as_the_worst(real_losses):
    """Read back from the .rrd alone: each real loss with every estimator's final error (as the
    report scored it), its tracks and the first fix after it to frame, the worst and each number;
    titles and key name it as a real GNSS outage."""
    from ionav_viz.core.errors import InputError
    from ionav_viz.viz.blueprints import Shot, framing, titles_for
    from ionav_viz.viz.recording_info import read_recording_info
    from ionav_viz.viz.screenshot import key_head

    out, bridged = real_losses
    info = read_recording_info(out)
    assert info.outages == [] and len(info.real_outages) == len(bridged) == 6
    for o, b in zip(info.real_outages, bridged):
        assert o.real and o.number == b["number"]
        for name in ("ins", "odo"):
            assert o.final_error_m[name] == pytest.approx(b["final_error_m"][name], abs=1e-3)
        # both estimators' tracks (one point per window boundary), the first good fix after it, and in
        # the local view its scale bar (2 points)
        assert len(o.lat_deg) == 2 * (b["outage_s"] + 1) + 1 and len(o.local_points) == len(o.lat_deg) + 2
        assert f"({b['gap_start_s']:.1f}-{b['gap_end_s']:.1f} s)" in o.head
    worst = max(bridged, key=lambda b: b["final_error_m"]["ins"])
    assert info.worst("ins").number == worst["number"]
    assert info.outage(2) is info.real_outages[1]
    with pytest.raises(InputError, match=r"no real GNSS outage 7 \(the recording has 6\)"):
        info.outage(7)
    o = info.worst("ins")
    shot = Shot("local", o.end_s, "worst", o)
    titles = titles_for(info, shot, 1600)
    assert f"real GNSS outage {o.number} (" in titles["local"], titles["local"]
    assert titles["inspect"].startswith(f"V-sim-motorway-tunnels: real GNSS outage {o.number} (")  # the inspector draws it too
    assert key_head(shot) == f"real GNSS outage {o.number}, final error:"
    # framed on its own tracks (the drive spans 7 km; one loss at motorway speed a few hundred metres)
    frame = framing(info, o, (1600, 900), "local")
    x0, x1, y0, y1 = frame.local_bounds
    assert max(x1 - x0, y1 - y0) < 1000.0 and frame.map_entities == ["map/gnss_outages/current"]


def test_a_screenshot_of_a_replay_through_real_losses_alone_frames_the_worst(real_shots):
    """'worst' in a recording without synthetic outages is the real loss with the largest final
    error of the INS DR: the local view zooms on it (its track spans much of the image, where the
    whole drive's view draws all six small). replay --screenshot failed here before."""
    framed, whole = real_shots("800x450", "local", "worst"), real_shots("800x450", "local", "end")
    # its tracks: one long line across the image where the whole drive draws six short ones (the
    # odometry's, the closer estimate there, drawn over the INS DR's)
    assert _extent_of(framed, COLORS["odo"])[0] > 0.3 * 800
    assert _pixels_near(framed, COLORS["odo"], 30) > 4 * _pixels_near(whole, COLORS["odo"], 30)


#: The band above the views (the key) and a view's title bar, in pixels of a screenshot: not the view.
BAND_AND_TITLE_PX = 66


def _view_pixels_near(path, rgb, tol=30):
    """Pixels of colour ``rgb`` in the views of a screenshot (below its key band and the title bar)."""
    return int((np.abs(_image(path)[BAND_AND_TITLE_PX:] - np.array(rgb)).max(axis=-1) <= tol).sum())


@pytest.mark.parametrize("view", ["outage", "local"])
def test_every_estimate_and_the_truth_end_are_seen_where_tracks_lie_on_one_road(real_shots, view):
    """Issue 63: on the tunnel drive's worst loss (a straight road) the odometry's track covered the
    INS DR's, whose 17.7 m error could only be read in the key: every estimate is drawn in the
    order of its error (the worst underneath) and ends in a dot, over a wider green dot at the
    truth's end. Each colour is in the view itself, not only in the key (measured in the inspector
    and the local view: INS DR 32 and 36 px, odometry 1,190 and 2,500 px, green 880 and 27 px (the
    ring: the local view draws the drive's truth faint); the INS DR 0 before)."""
    png = real_shots("800x450", view, "worst")
    for name in ("ins", "odo", "gnss"):
        assert _view_pixels_near(png, COLORS[name]) > 15, (name, {n: _view_pixels_near(png, COLORS[n]) for n in ("ins", "odo", "gnss")})


def test_the_idnn_is_seen_on_hard_brakes_worst_outage(tmp_path):
    """Issue 63: on the hard-brake example's screenshot (examples/worst_outage_screenshots.py: the
    local view at the worst outage) the IDNN's track lay under the INS DR's and the others', its
    colour nowhere in the view (0 px; its faded ellipse is another colour). Stacked by error, each
    track a rim wider than the one above it, with its end dot: measured 75 px at 1280x720."""
    out, png = tmp_path / "hb.rrd", tmp_path / "hb.png"
    proc = run_cli("replay", "hard-brake", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("screenshot", str(out), "-o", str(png), "--time", "worst", "--view", "local", "--size", "1280x720")
    if _no_renderer(proc):
        pytest.skip(f"no renderer on this machine: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(png)  # one image: the -o file itself, and its path said
    for name in COLORS:
        assert _view_pixels_near(png, COLORS[name], tol=20) > 30, (name, {n: _view_pixels_near(png, c, tol=20) for n, c in COLORS.items()})


def test_the_viewer_opens_on_time_into_the_drive_with_no_empty_view(real_losses):
    """Issue 63: the viewer opened on time_of_day (axes at "+17h 30s"), and a run through the log's
    own losses alone showed two of three error plots as "CRSE (m): none here". The recording's own
    layout, as the viewer reads it: the time panel on ``time``; no CRSE, CAE, orientation-rate
    CRSE or drift view (of synthetic outages), no sigma view (no outage with ellipses), no NIS
    view (no estimator of ins,odo reports its health)."""
    from pathlib import Path

    from ionav_viz.viz import entities as ent
    from ionav_viz.viz.viewer import HeadlessViewer, RendererMissing

    out, _ = real_losses
    try:
        with HeadlessViewer(800, 450) as viewer:
            viewer.open(Path(out))
            bp = viewer.base_blueprint
    except RendererMissing as exc:
        if os.environ.get("CI"):
            raise
        pytest.skip(f"no renderer on this machine: {exc}")
    assert bp["/time_panel"]["TimePanelBlueprint"]["timeline"] == "time"
    origins = {v["ViewBlueprint"]["space_origin"].strip("/") for v in bp.values() if "ViewBlueprint" in v}
    assert ent.error_group("position_error_m") in origins and ent.INSPECT in origins
    empty = {ent.error_group(m) for m in ("crse_m", "cae_m", "yaw_crse_radps")} | {ent.DRIFT, ent.UNCERTAINTY, ent.HEALTH}
    assert not origins & empty, origins & empty


def test_replay_through_real_losses_alone_with_screenshots(tunnel_replay_shots):
    """replay --on gnss-outage --screenshot: every view with data at the worst real loss, the inspector too
    (the loss in metres from its start fix: the INS DR's colour there; before this, the replay
    failed at 'worst', then the inspector's image was blank)."""
    shots = tunnel_replay_shots
    # no filter-health image: the INS DR reports none (it was an empty view)
    assert sorted(p.name for p in shots.iterdir()) == sorted(f"V-sim-motorway-tunnels-{v}-worst.png"
                                                             for v in ("all", "outage", "map", "local", "signals", "errors"))
    # the inspector draws the loss: the INS DR's track and the fixes around it, tens of pixels long at least
    inspector = shots / "V-sim-motorway-tunnels-outage-worst.png"
    assert _extent_of(inspector, COLORS["ins"])[0] > 200 and _pixels_near(inspector, GNSS_COLOR, 30) > 500


def test_no_labelled_tick_sits_at_a_plots_edge():
    """Tour 51: the range was framed around the data alone, so a tick just beyond it fell in the
    margin at the plot's edge and its label was cut (a real loss's errors up to 2.79 m in a 88 px
    plot: the '3' half drawn at the top, 1 px from the edge). The outermost labelled ticks now
    lie half a label's height inside."""
    from ionav_viz.viz.blueprints import LABEL_MARGIN_PX, TICK_PX, axis_range

    for lo, hi, px in [(0.0, 2.79, 88), (0.0, 28.6, 93), (0.0, 36.97, 93), (-28.6, 6.44, 93), (-3.53, 3.04, 78),
                       (0.0, 7.32, 154), (-0.42, 0.61, 190), (0.0, 0.22, 91), (0.0, 16.5, 100), (0.0, 29.1, 120)]:
        a, b = axis_range(lo, hi, px)
        step = next(10.0 ** k for k in range(-6, 6) if px * 10.0 ** k / (b - a) >= TICK_PX)  # the finest labelled
        ticks = np.arange(np.ceil(a / step - 1e-9), np.floor(b / step + 1e-9) + 1) * step
        assert a <= lo and b >= hi and len(ticks) >= 3, (lo, hi, px, a, b)
        to_edge_px = min(ticks[0] - a, b - ticks[-1]) * px / (b - a)
        assert to_edge_px >= LABEL_MARGIN_PX - 0.01, (lo, hi, px, a, b, ticks, to_edge_px)


def test_no_time_label_is_cut_at_a_columns_edge_on_a_real_roof_log(tmp_path):
    """The real roof MEMS log's review image at its worst outage (1600x900): its yaw rate's y labels
    ("-0.5") are wider than the synthetic drives', and the label of the tick before the plot's first
    showed its "s" at the signals column's edge. Each time plot now places its first tick by its own
    y axis's width (blueprints.time_axis_range_s): no text at either column's edge."""
    corpus = REPO / "tests" / "data" / "real"
    rec = tmp_path / "roof.rrd"
    proc = run_cli("replay", str(corpus / "roof_mems_rtk_gnss_imu_drive0708.mcap"), "--imu-mount", "auto",
                   "--estimators", "ins,odo,ekf", "-q", "-o", str(rec))
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("screenshot", str(rec), "-o", str(tmp_path / "shot.png"), "--view", "all", "--time", "worst", "-q")
    if _no_renderer(proc):
        pytest.skip(f"no renderer on this machine: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    img = _image(tmp_path / "shot.png")
    for column_x in (640, 1120):
        cut = _text_at_edge(img, column_x)
        assert len(cut) == 0, (column_x, cut)


def test_the_keys_words_stay_apart_in_its_smallest_type(tmp_path):
    """A key of many entries is drawn in 10 px type, whose space the default font makes 2 px wide:
    "INS DR52.5 m", "real GNSSoutage 5" in 1024 px images. A space is now 3 px at least, as the
    font's from 12 px up: one more in an entry moves the key's end 3 px or more (2 before)."""
    from PIL import Image

    from ionav_viz.viz.blueprints import TOP_BAND_PX, KeyEntry
    from ionav_viz.viz.screenshot import draw_key

    def key_end(first: str) -> int:
        blank = np.full((576, 1024, 3), 13, dtype=np.uint8)
        blank[TOP_BAND_PX] = 53  # the views' top border
        png = tmp_path / "k.png"
        Image.fromarray(blank).save(png)
        # wide enough to need the 10 px type on one line (11 px does not fit)
        keys = ([KeyEntry("line", (213, 94, 0), first)]
                + [KeyEntry("line", (86, 180, 233), f"GNSS-aided INS {i}6.8 m") for i in range(5)]
                + [KeyEntry("line", (0, 114, 178), "IDNN 4.8 m")] * 2)
        draw_key(png, keys)
        band = np.asarray(Image.open(png).convert("RGB")).astype(int)[1 : TOP_BAND_PX - 1]
        return int(np.nonzero((band.min(axis=-1) > 120).any(axis=0))[0].max())

    assert key_end("INS DR 52.5 m") - key_end("INS DR52.5 m") >= 3


def test_a_small_images_displacement_fills_its_plot():
    """At 1024x576 the signals column's three plots were 79 px high: three labelled ticks put a
    drive's 0-30 m displacement under ticks of 100 (a range of -22..222 m). Without the acceleration
    the two left are 141 px high: ticks of 10, the data over most of the plot."""
    from ionav_viz.viz import entities as ent
    from ionav_viz.viz.blueprints import axis_range, plot_heights_px

    heights = plot_heights_px((1024, 576))
    assert ent.ACCEL not in heights and ent.ACCEL in plot_heights_px((1280, 720))
    lo, hi = axis_range(0.0, 30.0, heights[ent.DISPLACEMENTS])
    assert lo < 0.0 and 30.0 < hi < 40.0
    # the errors column's one plot: a real phone's 0-52 m under ticks of 10 (two plots of 89 px: of 100)
    assert ent.error_group("crse_m") not in heights
    lo, hi = axis_range(0.0, 52.0, heights[ent.error_group("position_error_m")])
    assert 52.0 < hi < 65.0


def test_the_second_recording_of_a_run_has_its_own_layout(recording, shots, tmp_path):
    """The viewer keeps one active layout per application: after the first drive's signals column,
    the second drive's "all" image came out as a signals column too (its titles, its data, but the
    first's last layout). Each recording opened after an image is set back to its own layout: its
    "all" image from a run of both is the one a run of it alone makes."""
    first = tmp_path / "hb.rrd"
    proc = run_cli("replay", "hard-brake", "--estimators", "ins", "-q", "-o", str(first))
    assert proc.returncode == 0, proc.stderr
    alone = shots("1024x576", "all", "worst")  # the module's recording, rendered alone
    both = tmp_path / "both"
    proc = run_cli("screenshot", str(first), str(recording), "-o", str(both), "--view", "all", "--view", "signals",
                   "--size", "1024x576", "--time", "worst", "-q")
    assert proc.returncode == 0, proc.stderr
    diff = np.abs(_image(both / alone.name) - _image(alone)).mean()
    assert diff < 2.0, diff  # the same image but for a pixel here and there (the signals column instead: 17)
