"""Downloading IO-VNBD files by run name, verified against the LFS manifest (``ionav-viz fetch``).

A file is requested at ``<base URL>/<URL-encoded repository path>`` (the base URL stands for the
repository root: by default the dataset's Git LFS media address; ``--base-url`` or
``$IONAV_BASE_URL`` for mirrors and tests) and stored under the data root at the same relative
path, so the data root mirrors the repository's layout and run names resolve in it.

* Downloads go to ``<file>.part``; an interrupted download resumes with an HTTP range request
  (a server that ignores the range restarts it from zero). A dropped connection is retried.
* Size and sha256 are checked against the manifest; on a mismatch the partial file is removed
  and the error reported. Files already present with the right size and checksum are skipped
  (the check is remembered in ``<data root>/.ionav-verified.json`` by size and modification time).
* Nothing escapes the data root: manifest paths that are absolute, contain ``..`` or other
  unsafe parts, and any symlink on the way inside the data root are refused.
"""

from __future__ import annotations

import contextlib
import hashlib
import http.client
import json
import os
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ..core.errors import InputError, ToolFailure
from .catalog import ManifestEntry

DEFAULT_BASE_URL = "https://media.githubusercontent.com/media/onyekpeu/IO-VNBD/master"
VERIFIED_CACHE = ".ionav-verified.json"
CHUNK = 1 << 16


class FetchError(ToolFailure):
    """A download failed (network, server or checksum); the message says which file and why."""


class _Retry(Exception):
    """A transient failure worth another attempt (dropped connection, timeout, HTTP 5xx)."""


def default_data_root() -> Path:
    """The per-user data directory where ``fetch`` puts the dataset."""
    from platformdirs import user_data_dir

    return Path(user_data_dir("ionav-viz", appauthor=False)) / "IO-VNBD"


def configured_data_root(option: str | Path | None) -> Path | None:
    """The data root the user chose: the option, else ``$IONAV_DATA``, else None (then the
    per-user :func:`default_data_root` applies); ``~`` expanded."""
    value = option if option not in (None, "") else os.environ.get("IONAV_DATA") or None
    return Path(value).expanduser() if value is not None else None


def base_url(option: str | None) -> str:
    """The repository root to download from: the option, ``$IONAV_BASE_URL``, or the dataset's; checked."""
    url = (option or os.environ.get("IONAV_BASE_URL") or DEFAULT_BASE_URL).rstrip("/")
    try:
        parts = urllib.parse.urlsplit(url)
        parts.port  # noqa: B018  (raises ValueError for a bad port)
    except ValueError as exc:
        raise InputError(f"base URL {url!r} is not a valid URL ({exc})", "give e.g. https://host/path",
                         param="base_url") from None
    if parts.scheme not in ("http", "https") or not parts.netloc:
        raise InputError(f"base URL {url!r} is not an http(s) URL", "give e.g. https://host/path", param="base_url")
    return url


def safe_target(root: Path, repo_path: str) -> Path:
    """Where ``repo_path`` goes under ``root``; refuses anything that could leave it."""
    pure = PurePosixPath(repo_path)
    parts = pure.parts
    if (not repo_path or pure.is_absolute() or repo_path.startswith(("/", "\\")) or "\\" in repo_path
            or any(p in ("", ".", "..") for p in parts) or ":" in parts[0] or "\x00" in repo_path):
        raise InputError(f"manifest path {repo_path!r} is unsafe (absolute, '..' or a drive letter)",
                         "only relative paths inside the data root are fetched")
    root_resolved = root.resolve()
    current = root
    for part in parts:
        current = current / part
        if current.is_symlink():
            raise InputError(f"{current}: a symlink inside the data root; refusing to write through it",
                             "remove the link")
    target = root_resolved.joinpath(*parts)
    if root_resolved not in target.resolve().parents:
        raise InputError(f"manifest path {repo_path!r} leaves the data root",
                         "only relative paths inside the data root are fetched")
    return target


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


class VerifiedCache:
    """Remembers which files were verified, by path, size and modification time."""

    def __init__(self, root: Path) -> None:
        from ..core.errors import InputError
        from ..core.fileio import read_json_bounded

        self.path = root / VERIFIED_CACHE
        try:  # a cache: one that is missing, damaged, a pipe or nested deep is empty
            data = (read_json_bounded(self.path, param="data_root", what="the verified-files cache")
                    if self.path.exists() else {})
        except InputError:
            data = {}
        self.data = data if isinstance(data, dict) else {}

    def _key(self, file: Path) -> list:
        st = file.stat()
        return [st.st_size, st.st_mtime_ns]

    def status(self, entry: ManifestEntry, file: Path, check: bool) -> str:
        """'missing', 'verified', 'present' (not checked) or 'mismatch'."""
        if not file.is_file():
            return "missing"
        if file.stat().st_size != entry.size_bytes:
            return "mismatch"
        if self.data.get(entry.path) == [*self._key(file), entry.sha256]:
            return "verified"
        if not check:
            return "present"
        if sha256_of(file) != entry.sha256:
            return "mismatch"
        self.remember(entry, file)
        return "verified"

    def remember(self, entry: ManifestEntry, file: Path) -> None:
        self.data[entry.path] = [*self._key(file), entry.sha256]
        try:
            from ..core.fileio import atomic_write_bytes

            atomic_write_bytes(self.path, json.dumps(self.data, indent=0).encode())
        except (OSError, InputError, ToolFailure):
            pass  # the cache only saves time


@dataclass
class FetchResult:
    entry: ManifestEntry
    path: Path
    action: str  # "downloaded", "resumed" or "skipped"


Progress = Callable[[ManifestEntry, int], None]


def fetch_file(entry: ManifestEntry, root: Path, url_base: str, *, timeout_s: float = 30.0, retries: int = 3,
               cache: VerifiedCache | None = None, progress: Progress | None = None) -> FetchResult:
    """Download one manifest entry into ``root`` (resuming, verifying); see the module docstring."""
    target = safe_target(root, entry.path)
    cache = cache or VerifiedCache(root)
    state = cache.status(entry, target, check=True) if target.exists() else "missing"
    if state == "verified":
        return FetchResult(entry, target, "skipped")
    if state == "mismatch":
        target.unlink()
    new_dirs = [p for p in [target.parent, *target.parent.parents] if root.resolve() in p.parents and not p.exists()]
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        return _fetch_into(entry, root, target, url_base, timeout_s, retries, cache, progress)
    except BaseException:
        for folder in new_dirs:  # leave no empty folders behind a failed first download
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


def _fetch_into(entry: ManifestEntry, root: Path, target: Path, url_base: str, timeout_s: float, retries: int,
                cache: VerifiedCache, progress: Progress | None) -> FetchResult:
    """Download ``entry`` to ``target`` (its folder exists): resume, retry, verify, rename."""
    safe_target(root, entry.path)  # re-check: no symlink appeared among the new folders
    part = target.with_name(target.name + ".part")
    if part.is_symlink():
        raise InputError(f"{part}: a symlink inside the data root; refusing to write through it", "remove the link")
    url = f"{url_base}/{urllib.parse.quote(entry.path)}"
    resumed = part.exists() and part.stat().st_size > 0
    attempt = 0
    while True:
        attempt += 1
        try:
            _download(url, part, entry, timeout_s, progress)
            break
        except FetchError:
            raise
        except (_Retry, urllib.error.URLError, http.client.HTTPException, TimeoutError, ConnectionError,
                OSError) as exc:
            if attempt >= retries:
                reason = getattr(exc, "reason", None) or str(exc) or type(exc).__name__
                reason = " ".join(str(reason).split())[:200]  # one line, even when quoting a server's reply
                host = urllib.parse.urlsplit(url).hostname or url_base
                raise FetchError(f"{entry.path}: download failed after {attempt} attempts from {host} ({reason}) "
                                 "(hint: check the network connection, or give a mirror with --base-url; fetch "
                                 "again to resume)") from None
            time.sleep(min(2.0 ** (attempt - 1) * 0.2, 5.0))
            resumed = True
    size = part.stat().st_size
    if size != entry.size_bytes:
        part.unlink()
        raise FetchError(f"{entry.path}: got {size} bytes, the manifest says {entry.size_bytes}; removed the "
                         "partial file")
    digest = sha256_of(part)
    if digest != entry.sha256:
        part.unlink()
        raise FetchError(f"{entry.path}: sha256 {digest[:12]}... does not match the manifest's {entry.sha256[:12]}...; "
                         "removed the download")
    os.replace(part, target)
    cache.remember(entry, target)
    return FetchResult(entry, target, "resumed" if resumed else "downloaded")


def _download(url: str, part: Path, entry: ManifestEntry, timeout_s: float, progress: Progress | None) -> None:
    have = part.stat().st_size if part.exists() else 0
    if have > entry.size_bytes:
        part.unlink()
        have = 0
    if have == entry.size_bytes:
        return
    request = urllib.request.Request(url,
                                     headers={"User-Agent": "ionav-viz",
                                              **({"Range": f"bytes={have}-"} if have else {})})
    try:
        response = urllib.request.urlopen(request, timeout=timeout_s)
    except urllib.error.HTTPError as exc:
        if exc.code == 416 and have:  # range not satisfiable: start over
            part.unlink()
            raise _Retry("range not satisfiable; restarting") from None
        if exc.code in (408, 429) or exc.code >= 500:
            raise _Retry(f"HTTP {exc.code} {exc.reason} for {url}") from None
        raise FetchError(f"{entry.path}: HTTP {exc.code} {exc.reason} for {url}") from None
    with response:
        mode = "ab" if have and response.status == 206 else "wb"
        done = have if mode == "ab" else 0
        with open(part, mode) as out:
            while True:
                block = response.read(CHUNK)
                if not block:
                    break
                out.write(block)
                done += len(block)
                if progress:
                    progress(entry, done)
                if done > entry.size_bytes:
                    break
    if done < entry.size_bytes:
        raise _Retry(f"connection closed after {done} of {entry.size_bytes} bytes")
