"""``replay --serve-web`` in a real browser: Debian's ``chromium``, headless on the CPU (SwiftShader),
driven by selenium through Debian's ``chromium-driver``; nothing is downloaded at run time (the
driver's path is given, so Selenium Manager is never asked). The page the command prints is
opened, and the rendered views are checked by their pixels, as the screenshot tests do.

The browser is kept on this machine (every other host name fails to resolve), so the test needs
no network and sends nothing; the hosts the page tries are read from the browser's network log.
Skipped where chromium, chromedriver or selenium are missing, except under CI, where it fails.
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ionav_viz.nav.ins import InsEstimator
from ionav_viz.nav.odometry import OdometryEstimator
from ionav_viz.viz.style import GNSS_COLOR, SCALE_COLOR

from .conftest import HANG_S, REPO

ARGS = ("replay", "hard-brake", "--estimators", "ins,odo", "--every", "60s", "-q")
WINDOW_PX = (1280, 720)
#: The left column of the review layout (outage inspector, drive, map) as a share of the page's
#: width, and the web viewer's top bar and time panel (pixels) left out of it.
LEFT_COLUMN = 0.4
TOP_BAR_PX, TIME_PANEL_PX = 40, 40
#: Least pixels of each colour in the left column: the truth's green track, the odometry's pink
#: track (in the outage inspector), the INS DR's vermillion (its end dot at least) and the scale
#: bars' grey (white before, lost on the light theme's white). Measured on rendered pages (light,
#: dark): about (2,450-3,040, 2,600-3,220), (1,150-1,670, 1,160-1,760), (39-93, 39-180) and
#: (2,400, 700-770): on the light theme the grid lines' antialiased edges are of that grey too.
MIN_PIXELS = {"gnss": (GNSS_COLOR, 200), "odo": (OdometryEstimator.color, 150), "ins": (InsEstimator.color, 30),
              "scale": (SCALE_COLOR, 40)}
#: The page in the browser's light and dark colour scheme (the viewer follows it).
THEMES = ("light", "dark")
RENDER_TIMEOUT_S = HANG_S  # a hang guard: the loop ends when the page is drawn (~10-20 s on an idle 2-core machine)
#: What Rerun's web viewer (rerun-sdk 0.41) asks of other hosts, as the README's --serve-web
#: paragraph lists them: fonts, map tiles, Rerun's release and examples lists, its usage events.
DOCUMENTED_HOSTS = {"fonts.googleapis.com", "tile.openstreetmap.org", "api.github.com", "app.rerun.io", "tel.rerun.io"}


def _browser_or_skip() -> tuple[str, str]:
    """Paths of chromium and chromedriver, with selenium importable; skip without them (fail under CI)."""
    found = {name: shutil.which(name) for name in ("chromium", "chromedriver")}
    missing = [f"the '{name}' command" for name, path in found.items() if path is None]
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("the selenium package")
    if missing:
        reason = (f"needs {', '.join(missing)} (Debian: apt-get install chromium chromium-driver; "
                  "pip install -e '.[test]')")
        if os.environ.get("CI"):
            pytest.fail(f"CI must run the browser test: {reason}")
        pytest.skip(reason)
    return found["chromium"], found["chromedriver"]


def _chrome(chromium: str, chromedriver: str, profile: Path, log: Path, env: dict[str, str]):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in ("--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",  # WebGL on the CPU
                f"--window-size={WINDOW_PX[0]},{WINDOW_PX[1]}", f"--user-data-dir={profile}",
                "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1", "--no-proxy-server",  # this machine only
                "--disable-background-networking", "--disable-component-update", "--no-first-run",
                "--disable-dev-shm-usage"):  # containers' small /dev/shm
        options.add_argument(arg)
    if os.geteuid() == 0:  # Chromium refuses its sandbox to root (CI containers)
        options.add_argument("--no-sandbox")
    options.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "SEVERE"})
    service = Service(executable_path=chromedriver, log_output=str(log), env=env)  # the test's HOME: nothing written in the user's
    return webdriver.Chrome(service=service, options=options)


def _counts(png: bytes) -> dict[str, int]:
    """Pixels of each colour of MIN_PIXELS in the left column, below the top bar and above the time panel,
    and its median grey level ("background", 0-255)."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    left = img[TOP_BAR_PX : img.shape[0] - TIME_PANEL_PX, : int(LEFT_COLUMN * img.shape[1])]
    counts = {name: int((np.abs(left - np.array(rgb)).max(axis=-1) <= (12 if name == "scale" else 30)).sum())
              for name, (rgb, _) in MIN_PIXELS.items()}
    return {**counts, "background": int(np.median(left.mean(axis=-1)))}


def _drawn(counts: dict[str, int], theme: str) -> bool:
    """The page shows the recording in ``theme``: every colour of MIN_PIXELS, on a light or dark background."""
    return ((counts["background"] > 128) == (theme == "light")
            and all(counts[name] >= least for name, (_, least) in MIN_PIXELS.items()))


def _requested_hosts(driver) -> set[str]:
    """Hosts of every http(s) request the page made, from the browser's network log."""
    hosts = set()
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        if message["method"] == "Network.requestWillBeSent":
            url = message["params"]["request"]["url"]
            if url.startswith(("http://", "https://")):
                hosts.add(url.split("/")[2])
    return hosts


def _processes_with(fragment: str) -> list[str]:
    """Ids of processes whose command line holds ``fragment`` (this test's own profile or ports)."""
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                if fragment.encode() in (proc / "cmdline").read_bytes():
                    found.append(proc.name)
            except OSError:
                continue
    return found


def test_served_recording_renders_in_a_browser(tmp_path, monkeypatch):
    """The page ``replay --serve-web`` prints shows the recording, in the browser's light and dark
    colour schemes: the truth's green, both estimators' colours and the scale bars' grey in the
    left column (outage inspector, drive, map). The user's Rerun
    analytics setting (disabled here) is left as it was; the page asks no host beyond the
    README's list. Browser, driver and server are gone afterwards."""
    from ionav_viz.viz.viewer import free_port, rerun_executable

    chromium, chromedriver = _browser_or_skip()
    monkeypatch.setenv("SE_OFFLINE", "true")  # Selenium Manager, were it ever asked, downloads nothing
    home = tmp_path / "home"  # Rerun's analytics.json lives under the user's config folder
    env = {**os.environ, "HOME": str(home), "XDG_CONFIG_HOME": str(home / ".config"), "XDG_DATA_HOME": str(home / ".local" / "share")}
    env.pop("IONAV_DATA", None)
    optout = subprocess.run([rerun_executable(), "analytics", "disable"], env=env, capture_output=True, text=True, timeout=HANG_S)
    config = home / ".config" / "rerun" / "analytics.json"
    assert optout.returncode == 0 and config.is_file(), optout.stderr
    config_before = config.read_bytes()
    queued = home / ".local" / "share" / "rerun" / "analytics"  # Rerun's events waiting to be sent
    queued_before = sorted(queued.iterdir()) if queued.is_dir() else []

    grpc_port, web_port = free_port(), free_port()
    out, profile = tmp_path / "hb.rrd", tmp_path / "profile"
    start = time.monotonic()
    server = subprocess.Popen([sys.executable, "-m", "ionav_viz.cli", *ARGS, "-o", str(out), "--serve-web",
                               "--grpc-port", str(grpc_port), "--web-port", str(web_port)],
                              cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    counts: dict[str, dict[str, int]] = {}
    hosts: set[str] = set()
    severe: list[str] = []
    try:
        assert server.stdout.readline().strip() == str(out)
        line = server.stdout.readline()
        url = re.search(r"open (http://127\.0\.0\.1:\d+/\S*)", line)
        assert url and f":{web_port}/" in url.group(1), line
        driver = _chrome(chromium, chromedriver, profile, tmp_path / "chromedriver.log", env)
        try:  # one browser, the page loaded again in each colour scheme (a second browser cost a minute)
            # the page itself 1280x720 (--window-size counts the browser's own bars: the page was 1280x577)
            driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {"width": WINDOW_PX[0], "height": WINDOW_PX[1],
                                                                         "deviceScaleFactor": 1, "mobile": False})
            driver.set_page_load_timeout(HANG_S)
            for theme in THEMES:
                driver.execute_cdp_cmd("Emulation.setEmulatedMedia", {"features": [{"name": "prefers-color-scheme", "value": theme}]})
                if theme == THEMES[0]:
                    driver.get(url.group(1))
                else:
                    driver.refresh()
                deadline = time.monotonic() + RENDER_TIMEOUT_S
                while True:  # a screenshot waits for the next frame: seconds apart while the viewer loads
                    png = driver.get_screenshot_as_png()
                    counts[theme] = _counts(png)
                    if _drawn(counts[theme], theme) or time.monotonic() > deadline:
                        break
                    time.sleep(0.5)
                (tmp_path / f"browser-{theme}.png").write_bytes(png)
            hosts |= _requested_hosts(driver) - {f"127.0.0.1:{web_port}", f"127.0.0.1:{grpc_port}"}
            severe += [entry["message"] for entry in driver.get_log("browser") if "ERR_NAME_NOT_RESOLVED" not in entry["message"]]
        finally:
            driver.quit()
    finally:
        server.send_signal(signal.SIGINT)
        try:
            code = server.wait(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            server.kill()
            code = server.wait()
    elapsed_s = time.monotonic() - start
    for theme in THEMES:
        assert (counts[theme]["background"] > 128) == (theme == "light"), (theme, counts[theme]["background"])
        for name, (_, least) in MIN_PIXELS.items():
            assert counts[theme][name] >= least, (f"{theme} theme, {name}: {counts[theme][name]} pixels of its colour after {elapsed_s:.0f} s "
                                                  f"(see {tmp_path / f'browser-{theme}.png'}; console: {severe[-3:]})")
    for theme in THEMES:
        from PIL import Image

        assert Image.open(tmp_path / f"browser-{theme}.png").size == WINDOW_PX, theme
    assert hosts <= DOCUMENTED_HOSTS, f"the page asked hosts the README does not name: {sorted(hosts - DOCUMENTED_HOSTS)}"
    assert "tel.rerun.io" in hosts  # the README says the page sends usage events, opt-out or not
    assert code == 130 and "Traceback" not in server.stderr.read()
    assert config.read_bytes() == config_before  # still disabled: ionav-viz never touches the setting
    assert (sorted(queued.iterdir()) if queued.is_dir() else []) == queued_before  # and the server it starts heeds it
    assert _processes_with(str(profile)) == [] and _processes_with(f"--web-viewer-port\0{web_port}") == []
    shutil.rmtree(profile)  # ~50 MB of browser profile; the screenshot and the driver's log stay
