"""Atomic writes: outputs appear at their target path only when complete."""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import InputError, ToolFailure
from .signals import hold_signals

#: errno values of a write that failed for lack of room or a broken device.
_WRITE_FAILURES = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EIO, errno.EROFS}


def write_failure(target: str | Path, exc: OSError) -> ToolFailure | None:
    """The one-line failure for a write that found no room (disk full, a file size limit, a
    read-only or failing device), naming ``target``; None for any other error."""
    if exc.errno not in _WRITE_FAILURES:
        return None
    why = {errno.EFBIG: "a file size limit was reached ('ulimit -f', or the file system's largest file)",
           errno.EROFS: "the file system is read-only", errno.EIO: "the device failed"}.get(exc.errno, "is the disk full?")
    return ToolFailure(f"{target}: write failed ({exc.strerror}); {why}")


def check_output_file(target: Path, *, create_parent: bool = False) -> Path:
    """Check, before any work, that ``target`` can be written as a file: its folder exists (or,
    with ``create_parent``, can be made in an existing folder), and it is absent or a regular file
    (never a directory, device node, FIFO or socket: those are not replaced). Returns ``target``."""
    target = Path(target)
    parent = target.parent if str(target.parent) else Path(".")
    if create_parent and not parent.exists() and parent.parent.is_dir():
        if not os.access(parent.parent, os.W_OK | os.X_OK):
            raise InputError(f"{target}: cannot create {parent} in {parent.parent} (permission denied)", "choose a writable output directory",
                             param="output")
        return target
    if not parent.is_dir():
        raise InputError(f"{target}: output directory {parent} does not exist", "create it or choose another output", param="output")
    if target.is_dir():
        raise InputError(f"{target}: is a directory", "name a file inside it", param="output")
    if target.exists() and not target.is_file():  # a link to a regular file, or a dangling one, is fine
        raise InputError(f"{target}: exists and is not a regular file", "ionav-viz only ever replaces regular files; choose another output",
                         param="output")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{target}: cannot write in {parent} (permission denied)", "choose a writable output directory", param="output")
    return target


def check_output_folder(folder: Path, param: str = "output") -> Path:
    """Check, before any work, that ``folder`` is a directory or can be made (with its parents) in
    the nearest existing one, which must be writable. Returns ``folder``; nothing is created."""
    folder = Path(folder)
    if folder.exists():
        if not folder.is_dir():
            raise InputError(f"{folder}: exists and is not a folder", "choose a folder name", param=param)
        existing = folder
    else:
        existing = next((p for p in folder.absolute().parents if p.exists()), Path("/"))
        if not existing.is_dir():
            raise InputError(f"{folder}: {existing} is not a folder", "choose a folder name", param=param)
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{folder}: cannot write in {existing} (permission denied)", "choose a writable folder", param=param)
    return folder


def current_umask() -> int:
    """The process's file-creation mask (reading it means setting it: set back at once)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(target: Path, suffix: str = ".tmp", *, create_parent: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it onto ``target`` if the block succeeds.

    ``suffix`` ends the temporary name (writers that infer the format from it need e.g. ``.png``).
    ``create_parent``: make ``target``'s missing folder (one level) first; it is removed again,
    if still empty, when the block fails.

    On any exception (including Ctrl-C, SIGTERM and SIGHUP) the temporary file is removed and
    ``target`` is untouched. Signals are held back while the temporary file is created, so no
    signal can fall between its creation and the cleanup that removes it.
    """
    target = check_output_file(Path(target), create_parent=create_parent)
    parent = target.parent if str(target.parent) else Path(".")
    release = hold_signals()
    made_parent = False
    try:
        if create_parent and not parent.exists():
            parent.mkdir()
            made_parent = True
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix, dir=parent)
    except OSError as exc:
        _remove_if_empty(parent, made_parent)
        release()
        raise InputError(f"{target}: cannot write in {parent} ({exc.strerror})", "choose a writable output", param="output") from None
    tmp = Path(tmp_name)
    try:
        release()  # a signal held back since before mkstemp is delivered here, inside the cleanup
        os.close(fd)
        os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp creates 0600; outputs get the usual permissions
        yield tmp
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        _remove_if_empty(parent, made_parent)
        if (failure := write_failure(target, exc)) is not None:
            raise failure from None
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EISDIR):
            raise InputError(f"{target}: cannot write it ({exc.strerror})", "choose another output", param="output") from None
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        _remove_if_empty(parent, made_parent)
        raise


def _remove_if_empty(folder: Path, made: bool) -> None:
    if made:
        with contextlib.suppress(OSError):  # not empty (another process wrote there): keep it
            folder.rmdir()


def atomic_write_bytes(target: Path, data: bytes) -> None:
    """Write ``data`` to ``target`` atomically (temporary file + rename)."""
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)


def swap_in_directory(new: Path, directory: Path) -> None:
    """Put the complete directory ``new`` at ``directory``, replacing any directory there.

    The old directory is renamed aside, ``new`` renamed in, the old one removed, all with stop
    signals held: the process cannot stop between the renames (with nothing at the path) or leave
    the old directory under its hidden name. A rename that fails puts the old one back.
    """
    import shutil

    release = hold_signals()
    try:
        if not directory.exists():
            new.rename(directory)
            return
        old = Path(tempfile.mkdtemp(prefix=f".{directory.name}.old.", dir=directory.parent))
        old.rmdir()
        directory.rename(old)
        try:
            new.rename(directory)
        except BaseException:
            old.rename(directory)
            raise
        shutil.rmtree(old, ignore_errors=True)
    finally:
        release()  # a signal that came during the swap acts now, with the swap complete


@contextlib.contextmanager
def utf8_alias(path: Path) -> Iterator[Path]:
    """``path``, or when its name is not valid UTF-8 (legal on Linux; Rerun's Rust code takes only
    UTF-8 paths) a symbolic link to it in a private temporary folder, removed afterwards."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        with tempfile.TemporaryDirectory(prefix="ionav-viz-") as folder:
            alias = Path(folder) / f"alias{''.join(path.suffixes[-1:]).encode('ascii', 'replace').decode()}"
            alias.symlink_to(Path(path).absolute())
            yield alias
        return
    yield path


@contextlib.contextmanager
def made_folders(folder: Path | None) -> Iterator[None]:
    """Make ``folder`` and its missing parents for the block; if the block fails, the folders made
    here are removed again (those still empty: nothing the block wrote is lost)."""
    made: list[Path] = []
    try:
        for level in [*reversed(Path(folder).parents), Path(folder)] if folder is not None else []:
            if not level.exists():
                try:
                    level.mkdir()
                except OSError as exc:
                    raise InputError(f"{folder}: cannot create {level} ({exc.strerror})", "choose a writable output folder",
                                     param="output") from None
                made.append(level)
        yield
    except BaseException:
        for level in reversed(made):
            with contextlib.suppress(OSError):
                level.rmdir()
        raise
