"""Finding a drive from what a user types: a path, a bundled scenario name or an IO-VNBD run name.

Order: (1) an existing file or folder (a ROS 2 bag, a KITTI drive); (2) a bundled sample: a scenario name
(``roundabout``) means its bundled test drive, ``stationary`` the bundled stationary drive, and bundled file names work
too (``V-sim-roundabout``); (3) a run name
looked up under the data root (``--data-root`` or ``$IONAV_DATA``), case-insensitively and
tolerant of zero padding (``V-Vw8``, ``Vw8``, ``v-vw8.csv``, ``V-Vta01a``), preferring the
``Unsynchronised`` tree (complete runs) over the synchronised copies.
"""

from __future__ import annotations

import difflib
import errno
import logging
import os
from functools import lru_cache
from pathlib import Path

from ..core.errors import InputError
from ..core.fileio import check_regular_input, check_regular_tree
from ..dataset.catalog import DATASET_URL, paper_role, run_key, vehicle_runs
from ..dataset.samples import SAMPLES, address, by_scenario, sample_path, stand_in, what_it_is

log = logging.getLogger("ionav_viz")


def data_root(option: str | Path | None) -> Path | None:
    """The data root from the option, else ``$IONAV_DATA``, else the per-user data directory
    that ``ionav-viz fetch`` fills (when it exists), else None."""
    from ..dataset.fetch import configured_data_root, default_data_root

    root = configured_data_root(option)
    if root is None:
        default = default_data_root()
        return default if default.is_dir() else None
    if not root.is_dir():
        raise InputError(f"data root {root} is not a directory", "give the IO-VNBD checkout (or set IONAV_DATA to it)",
                         param="data_root")
    return root


def _preference(path: Path) -> tuple:
    text = str(path).lower()
    return (0 if "unsynchronised" in text else 1, 0 if "/categorised" in text.replace("\\", "/") else 1, len(text),
            text)


@lru_cache(maxsize=8)
def index_data_root(root: Path) -> dict[str, list[Path]]:
    """All ``V-*.csv`` under ``root`` by run key, best copy first."""
    index: dict[str, list[Path]] = {}
    for path in root.rglob("*"):
        name = path.name.lower()
        if name.startswith("v-") and name.endswith(".csv") and path.is_file():
            index.setdefault(run_key(path.name), []).append(path)
    return {k: sorted(v, key=_preference) for k, v in index.items()}


def _bundled(spec: str) -> Path | None:
    key = spec.strip().lower()
    named = by_scenario(key) or by_scenario(key, role="bias")  # 'stationary' is the bias drive
    if named:
        return sample_path(named[0])
    for sample in SAMPLES:
        if run_key(sample.file) == run_key(spec):
            return sample_path(sample)
    return None


def warn_if_not_published(spec: str, path: Path) -> None:
    """Warn when a run name (``spec``, not a file's path) found a file under the data root (``path``)
    with the size of none of that run's files in the dataset's manifest (``ionav-viz list`` calls it
    a mismatch): an edited copy, another version or a damaged download is read as the run, and its
    results would be taken for the published run's. Only the size: a sha256 of a large file is
    ``list --verify``'s to take. Called by the reader, once per drive read (not by
    :func:`resolve_drive`, which also serves the output checks and ``--dry-run``)."""
    if Path(spec).expanduser().exists():  # a path the user gave: their file, whatever its size
        return
    sizes = sorted({e.size_bytes for e in vehicle_runs().get(run_key(spec), [])})
    try:
        size = path.stat().st_size
    except OSError:  # gone since: its reader names it
        return
    if sizes and size not in sizes:
        log.warning("%s: %s is %d bytes, not the size of the published run's file (%s bytes in the dataset's "
                    "manifest): an edited copy, another version or a damaged download ('ionav-viz fetch %s' gets the "
                    "published one)",
                    spec, path, size, " or ".join(str(n) for n in sizes), spec)


def resolve_drive(spec: str, root: Path | None) -> Path:
    """Path of the drive ``spec`` names (see module docstring), or an :class:`InputError`."""
    path = Path(spec).expanduser()
    if path.is_dir():  # a ROS 2 bag, a KITTI drive: no pipe or device among the files read in it
        return check_regular_tree(path, "drive", hint="give the log's file or folder")
    if path.is_file():
        return path
    if path.exists():  # a named pipe would block the reader forever, a device could be endless
        return check_regular_input(path, "drive", hint="give the log's file or folder", folder_ok=True)
    if path.is_symlink():  # a dangling link or a loop: "unknown drive" (a run name?) said nothing of the link
        try:
            os.stat(path)
        except OSError as exc:
            why = ("a loop of symbolic links"
                   if exc.errno == errno.ELOOP else f"a link to {os.readlink(path)}, which does not exist")
            raise InputError(f"{spec}: is {why}", "give the log's file or folder") from None
    # a run name may end in .csv
    if path.suffix.lower() in (".mcap", ".bag", ".db3", ".yaml") or os.sep in spec or "/" in spec:
        raise InputError(f"{spec}: no such file or folder", "check the path (relative to the current directory)")
    bundled = _bundled(spec)
    if bundled is not None:
        if not bundled.is_file():
            raise InputError(f"bundled sample {bundled} is missing",
                             "reinstall ionav-viz; the package ships it under ionav_viz/data/samples")
        return bundled
    key = run_key(spec)
    if root is not None:
        # the index is cached: a file may be gone since
        found = [p for p in index_data_root(root.resolve()).get(key, []) if p.is_file()]
        if found:
            return found[0]
    known = vehicle_runs()
    role = paper_role(spec)
    if key in known or role:
        what = f"{spec} is {role}" if role else f"{spec} is a run"
        where = f"it is not under the data root {root}" if root else "no data root is set"
        sample = stand_in(spec)
        bundled_one = f"; its bundled stand-in is {address(sample)} ({what_it_is(sample)})" if sample else ""
        raise InputError(
            f"{what} of the real IO-VNBD dataset, and {where}",
            f"get it with 'ionav-viz fetch {spec}' (from {DATASET_URL}), or pass --data-root DIR / set IONAV_DATA to a "
            f"copy{bundled_one}",
        )
    candidates = {s.scenario for s in SAMPLES if s.role == "test"} | {Path(s.file).stem for s in SAMPLES}
    candidates |= {f"V-{k}" for k in known}
    if root is not None:
        candidates |= {p[0].stem for p in index_data_root(root.resolve()).values()}
    close = difflib.get_close_matches(spec, sorted(candidates), n=3, cutoff=0.6)
    hint = (f"did you mean {', '.join(close)}?"
            if close
            else "give a file path, a bundled scenario (motorway, roundabout, quick-accel, hard-brake, "
                 "sharp-cornering) or an IO-VNBD run name")
    if path.suffix:  # it names a file (no run or scenario has a suffix but .csv, looked up above)
        raise InputError(f"{spec}: no such file",
                         hint if close else "check the path (relative to the current directory)")
    raise InputError(f"unknown drive {spec!r}", hint)
