"""Files in and out: outputs appear at their target path only when complete and never onto an
input; inputs are regular files (never a FIFO, device or socket), JSON inputs bounded in size and
depth."""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import re
import stat
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

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
           errno.EROFS: "the file system is read-only",
           errno.EIO: "the device failed"}.get(exc.errno, "is the disk full?")
    return ToolFailure(f"{target}: write failed ({exc.strerror}); {why}")


def check_output_file(target: Path, *, create_parent: bool = False, package_ok: bool = False) -> Path:
    """Check, before any work, that ``target`` can be written as a file: its folder exists (or,
    with ``create_parent``, can be made in an existing folder), and it is absent or a regular file
    (never a directory, device node, FIFO or socket: those are not replaced). ``package_ok``: it may
    lie inside the installed package (``simulate --bundled`` alone). Returns ``target``."""
    target = Path(target)
    parent = target.parent if str(target.parent) else Path(".")
    refuse_system_output(target, package_ok=package_ok)
    if create_parent and not parent.exists() and parent.parent.is_dir():
        if not os.access(parent.parent, os.W_OK | os.X_OK):
            raise InputError(f"{target}: cannot create {parent} in {parent.parent} (permission denied)",
                             "choose a writable output directory",
                             param="output")
        return target
    if not parent.is_dir():
        blocking = next((p for p in [parent, *parent.parents] if p.exists()), None)
        if blocking is not None and not blocking.is_dir():  # a file where a folder of the path should be
            raise InputError(f"{target}: {blocking} is a file, not a folder", "choose another output", param="output")
        raise InputError(f"{target}: output directory {parent} does not exist", "create it or choose another output",
                         param="output")
    if target.is_dir():
        raise InputError(f"{target}: is a directory", "name a file inside it", param="output")
    if target.exists() and not target.is_file():  # a link to a regular file, or a dangling one, is fine
        raise InputError(f"{target}: exists and is not a regular file",
                         "ionav-viz only ever replaces regular files; choose another output",
                         param="output")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{target}: cannot write in {parent} (permission denied)",
                         "choose a writable output directory", param="output")
    return target


#: Folders of the system's own special files: an output there (``-o /dev/stdout``, a link into
#: ``/proc/self/fd``) would replace a system file, never write a user's (``/dev/shm`` is a user's tmpfs).
_SYSTEM_DIRS = (Path("/dev"), Path("/proc"), Path("/sys"))
_USER_DIRS_IN_SYSTEM = (Path("/dev/shm"),)


#: The installed package: its shipped drives and manifest are read-only package data (only
#: ``simulate --bundled`` regenerates the samples, where it is told: ``package_ok``).
PACKAGE_DIR = Path(__file__).resolve().parents[1]


def package_dirs() -> list[Path]:
    """The installed package's folders: :data:`PACKAGE_DIR`, and the shipped model's package
    ``ionav_viz.models`` where it lies elsewhere (an editable install maps it to the repository's
    ``models/``; a wheel puts it inside :data:`PACKAGE_DIR`)."""
    import importlib.util

    dirs = [PACKAGE_DIR]
    try:
        spec = importlib.util.find_spec("ionav_viz.models")
    except (ImportError, ValueError):
        spec = None
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        where = Path(location).resolve()
        if where != PACKAGE_DIR and PACKAGE_DIR not in where.parents:
            dirs.append(where)
    return dirs


def refuse_system_output(target: str | Path, param: str = "output", *, package_ok: bool = False) -> None:
    """Refuse an output under ``/dev``, ``/proc`` or ``/sys``, as given or once links are resolved
    (``-o /dev/stdout`` when standard output is a file passed every other check, and the rename
    replaced the system's ``/dev/stdout`` link with a regular file), a link loop, and an output
    inside the installed package (:func:`package_dirs`: ``simulate -o`` onto a bundled drive replaced
    it) unless ``package_ok``."""
    target = Path(target)
    try:
        os.stat(target)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(f"{target}: is a loop of symbolic links", "remove the link or choose another output",
                             param=param) from None
    real = Path(os.path.realpath(target))
    inside = next((d for d in package_dirs() if real == d or d in real.parents), None) if not package_ok else None
    if inside is not None:
        raise InputError(f"{target}: is inside the installed ionav-viz package ({inside}), whose shipped model, "
                         "bundled drives and data are read-only", "write it in a folder of yours", param=param)
    for where in [*_link_chain(target), Path(os.path.realpath(target))]:
        if any(where == d or d in where.parents for d in _SYSTEM_DIRS) and not any(
                where == d or d in where.parents for d in _USER_DIRS_IN_SYSTEM):
            shown = "" if where == Path(os.path.abspath(target)) else f" (a link to {where})"
            raise InputError(f"{target}: is a system file{shown}, not an output ionav-viz writes",
                             "name a regular file in a folder of yours (standard output is redirected by the shell, "
                             "not named)", param=param)


def _link_chain(path: Path) -> list[Path]:
    """``path`` (absolute) and every path its symbolic links lead through, in order (at most 40)."""
    chain = [Path(os.path.abspath(path))]
    for _ in range(40):
        try:
            step = os.readlink(chain[-1])
        except OSError:  # not a link (or gone): the chain ends
            break
        chain.append(Path(os.path.abspath(os.path.join(chain[-1].parent, step))))
    return chain


def check_output_folder(folder: Path, param: str = "output") -> Path:
    """Check, before any work, that ``folder`` is a directory or can be made (with its parents) in
    the nearest existing one, which must be writable. Returns ``folder``; nothing is created."""
    folder = Path(folder)
    refuse_system_output(folder, param)
    if folder.exists():
        if not folder.is_dir():
            raise InputError(f"{folder}: exists and is not a folder", "choose a folder name", param=param)
        existing = folder
    else:
        existing = next((p for p in folder.absolute().parents if p.exists()), Path("/"))
        if not existing.is_dir():
            raise InputError(f"{folder}: {existing} is not a folder", "choose a folder name", param=param)
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{folder}: cannot write in {existing} (permission denied)", "choose a writable folder",
                         param=param)
    return folder


def current_umask() -> int:
    """The process's file-creation mask (reading it means setting it: set back at once)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def staging_folder(beside: Path, parent: Path | None = None, *, refused: Any = None) -> Iterator[Path]:
    """A new hidden folder ``.<name>.*`` beside ``beside`` (in ``parent``, default its folder) to
    write an output into before it is moved into place; removed with whatever is left in it when
    the block ends, however it ends (a folder renamed into place is gone already).

    Made with stop signals held, which act only once its removal is armed (a signal cannot leave it
    behind), with the usual permissions (``mkdtemp`` makes it 0700; renamed into place, it is the
    output). ``refused``: turns the ``OSError`` of a folder that cannot be made into the exception
    to raise (default: the ``OSError``)."""
    import shutil

    release = hold_signals()
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{beside.name}.", dir=beside.parent if parent is None else parent))
    except OSError as exc:
        release()
        if refused is None:
            raise
        raise refused(exc) from None
    except BaseException:
        release()
        raise
    try:
        release()  # a signal held since before mkdtemp acts here, inside the cleanup
        stage.chmod(0o777 & ~current_umask())
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)


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
        raise InputError(f"{target}: cannot write in {parent} ({exc.strerror})", "choose a writable output",
                         param="output") from None
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
            raise InputError(f"{target}: cannot write it ({exc.strerror})", "choose another output",
                             param="output") from None
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
                    raise InputError(f"{folder}: cannot create {level} ({exc.strerror})",
                                     "choose a writable output folder",
                                     param="output") from None
                made.append(level)
        yield
    except BaseException:
        for level in reversed(made):
            with contextlib.suppress(OSError):
                level.rmdir()
        raise


#: What a special file is called in messages, by its ``stat`` test.
_SPECIAL_KINDS = ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISCHR, "a character device"),
                  (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _special_kind(mode: int) -> str | None:
    return next((name for test, name in _SPECIAL_KINDS if test(mode)), None)


def check_regular_input(path: str | Path, param: str, *, hint: str | None = None, folder_ok: bool = False,
                        missing_ok: bool = False) -> Path:
    """Check, without opening it, that the input ``path`` is a regular file (or, with
    ``folder_ok``, a folder): a named pipe would block the reader forever, a device could be
    endless. A link is followed. Returns ``path``; an :class:`InputError` for ``param`` otherwise
    (a missing path too, unless ``missing_ok``: then the caller says what it expected)."""
    path = Path(path)
    hint = hint or "give a regular file"
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if missing_ok:
            return path
        raise InputError(f"{path}: no such file", hint, param=param) from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read it ({exc.strerror})", hint, param=param) from None
    if (kind := _special_kind(mode)) is not None:
        raise InputError(f"{path}: is {kind}, not a regular file",
                         f"{hint}; ionav-viz reads no pipes or devices (save the data to a file first)",
                         param=param)
    if stat.S_ISDIR(mode) and not folder_ok:
        raise InputError(f"{path}: is a folder", hint, param=param)
    return path


def check_regular_tree(folder: str | Path, param: str, *, hint: str | None = None, max_depth: int = 3,
                       max_entries: int = 200_000) -> Path:
    """:func:`check_regular_input` for the files a reader opens inside an input folder (a ROS 2
    bag's ``metadata.yaml`` and ``.db3``, a KITTI drive's OXTS text files): no named pipe, device
    or socket within ``max_depth`` levels (the first ``max_entries`` entries; directory listings only,
    no file is opened). Returns ``folder``."""
    folder = Path(folder)
    level, seen = [folder], 0
    for _ in range(max_depth):
        below = []
        for directory in level:
            try:
                entries = list(os.scandir(directory))
            except OSError:
                continue
            for entry in entries:
                seen += 1
                if seen > max_entries:
                    return folder
                if entry.is_dir():
                    below.append(entry.path)
                elif not entry.is_file():
                    # a dangling link is the reader's to name
                    check_regular_input(entry.path, param, hint=hint, missing_ok=True)
        level = below
    return folder


#: The longest first line a line-based text input (a trajectory CSV's header, a TUM line) may have.
TEXT_LINE_MAX_BYTES = 1 << 16


def check_text_head(path: str | Path, param: str, *, hint: str, what: str = "a text file") -> None:
    """Check the start of the text input ``path`` before parsing it line by line: no NUL byte (a
    sparse or binary file: its first "line" is the whole file, read into memory and quoted in the
    message) and a first line shorter than :data:`TEXT_LINE_MAX_BYTES`."""
    try:
        with open(path, "rb") as f:
            head = f.read(TEXT_LINE_MAX_BYTES)
    except OSError as exc:
        raise InputError(f"{path}: cannot read it ({exc.strerror})", hint, param=param) from None
    nul = head.find(b"\x00")
    if nul >= 0:
        raise InputError(f"{path}: binary data (a NUL byte at byte {nul}), not {what}", hint, param=param)
    if len(head) == TEXT_LINE_MAX_BYTES and b"\n" not in head:
        raise InputError(f"{path}: line 1 is longer than {TEXT_LINE_MAX_BYTES} bytes, not {what}", hint, param=param)


#: A JSON input's default limits: an outage plan or a report is kilobytes and a few levels deep.
JSON_MAX_BYTES = 64 << 20
JSON_MAX_DEPTH = 64

_JSON_STRING = re.compile(rb'"(?:[^"\\]++|\\.)*+"')


def _json_depth(data: bytes) -> int:
    """The deepest nesting of arrays and objects in ``data`` (strings skipped; 0 for none)."""
    import numpy as np

    brackets = _JSON_STRING.sub(b"", data).translate(None, bytes(b for b in range(256) if b not in b"[]{}"))
    if not brackets:
        return 0
    step = np.full(256, -1, dtype=np.int32)
    step[list(b"[{")] = 1
    return int(np.cumsum(step[np.frombuffer(brackets, dtype=np.uint8)], dtype=np.int32).max())


def read_bytes_bounded(path: str | Path, *, param: str, max_bytes: int, hint: str, what: str) -> bytes:
    """The bytes of the file ``path``, read safely: a regular file (checked before opening, and again
    on the opened file: a named pipe would block, a device never end) of at most ``max_bytes``
    (checked by its size before reading, and by what was read: a file that grows while read).
    Anything else is one :class:`InputError` for ``param`` naming ``path``, the limit and ``what``
    the file should hold."""
    path = Path(path)
    check_regular_input(path, param, hint=hint)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(f"{path}: cannot read it ({exc.strerror})", hint, param=param) from None
    with os.fdopen(fd, "rb") as stream:
        info = os.fstat(stream.fileno())
        if not stat.S_ISREG(info.st_mode):  # replaced since the check above
            raise InputError(f"{path}: is not a regular file", hint, param=param)
        if info.st_size > max_bytes:
            raise InputError(f"{path}: {info.st_size} bytes is too large for {what} (at most {max_bytes})", hint,
                             param=param)
        try:
            data = stream.read(max_bytes + 1)
        except OSError as exc:
            raise InputError(f"{path}: cannot read it ({exc.strerror})", hint, param=param) from None
    if len(data) > max_bytes:  # grew while read
        raise InputError(f"{path}: more than {max_bytes} bytes is too large for {what}", hint, param=param)
    return data


def read_json_bounded(path: str | Path, *, param: str, max_bytes: int = JSON_MAX_BYTES, max_depth: int = JSON_MAX_DEPTH,
                      hint: str | None = None, what: str = "a JSON file", allow_nan: bool = False) -> Any:
    """The JSON value in the file ``path``, read safely: a regular file (checked before opening,
    and again on the opened file), at most ``max_bytes`` long, nested at most ``max_depth``
    arrays/objects deep, UTF-8, strict JSON (no NaN or Infinity, no number that overflows to
    infinity; ``allow_nan`` takes them, as Python's ``json.dumps`` writes them, for a file whose
    reader checks its numbers field by field) and no key given twice in one object (JSON would keep
    the last silently).

    Anything else is one :class:`InputError` for ``param`` naming ``path`` and what is wrong
    (``what`` names the expected content in messages, ``hint`` says what to give instead); never a
    RecursionError or a hang."""
    path = Path(path)
    hint = hint or f"give {what}"
    data = read_bytes_bounded(path, param=param, max_bytes=max_bytes, hint=hint, what=what)
    return parse_json_bounded(data, path, param=param, max_bytes=max_bytes, max_depth=max_depth, hint=hint, what=what,
                              allow_nan=allow_nan)


def parse_json_bounded(data: bytes | str, path: str | Path, *, param: str, max_bytes: int = JSON_MAX_BYTES,
                       max_depth: int = JSON_MAX_DEPTH, hint: str | None = None, what: str = "a JSON file",
                       allow_nan: bool = False) -> Any:
    """:func:`read_json_bounded`'s checks on JSON already in memory (``data``; ``path`` names where
    it came from in messages, e.g. the recording that carried it): size, depth, strict JSON."""
    hint = hint or f"give {what}"
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogatepass")
    if len(data) > max_bytes:
        raise InputError(f"{path}: {len(data)} bytes is too large for {what} (at most {max_bytes})", hint, param=param)
    depth = _json_depth(data)
    if depth > max_depth:
        raise InputError(f"{path}: nested {depth} levels deep; {what} nests at most {max_depth}", hint, param=param)

    def constant(token: str) -> Any:
        raise ValueError(f"{token} is not a number JSON allows")

    def finite(token: str) -> float:
        value = float(token)
        if not math.isfinite(value):
            raise ValueError(f"{token} overflows to infinity")
        return value

    def whole(token: str) -> int:
        value = int(token)
        # as a float it overflows: 1e400 was refused, 10**400 written out a traceback downstream
        if abs(value) > 2**1023 * 2:
            raise ValueError(f"the integer {token[:20]}... ({len(token)} digits) overflows to infinity")
        return value

    def no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        body: dict[str, Any] = {}
        for key, value in pairs:
            if key in body:
                raise ValueError(f"key {key!r} appears twice in one object")
            body[key] = value
        return body

    try:
        return json.loads(data.decode("utf-8"), parse_constant=None if allow_nan else constant,
                          parse_float=float if allow_nan else finite,
                          parse_int=int if allow_nan else whole, object_pairs_hook=no_duplicates)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte {exc.start})", hint, param=param) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON (line {exc.lineno} column {exc.colno}: {exc.msg})", hint,
                         param=param) from None
    except (ValueError, RecursionError) as exc:  # our checks above; an integer of over 4300 digits
        why = "a number has over 4300 digits" if "4300" in str(exc) else str(exc).splitlines()[0]
        raise InputError(f"{path}: not usable JSON ({why})", hint, param=param) from None


def refuse_output_onto_input(output: str | Path | None, inputs: Iterable[str | Path | None], *, param: str = "output",
                             output_is_folder: bool = False) -> None:
    """Refuse, before any work, an output that is one of the command's inputs: the same path once
    links are resolved, or another name (a hard link) of the same file. With ``output_is_folder``
    (a folder that is replaced whole) an input inside it is refused too; an output inside an input
    folder (a ROS 2 bag, a KITTI drive) always is. ``None`` entries are skipped."""
    if output is None:
        return
    out = Path(output)
    out_real = Path(os.path.realpath(out))
    out_stat = _stat_or_none(out)
    for given in inputs:
        if given is None:
            continue
        inp = Path(given)
        inp_real = Path(os.path.realpath(inp))
        inp_stat = _stat_or_none(inp)
        hint = "choose another output; ionav-viz never writes over its input"
        if out_real == inp_real or (out_stat is not None and inp_stat is not None and
                                    os.path.samestat(out_stat, inp_stat)):
            how = ("is another name (a hard link) of" if out_real != inp_real
                   else "is a link to" if os.path.islink(out) else "is")
            what = f"the input {inp}" + (" (a link to it)" if os.path.islink(inp) and not os.path.islink(out) else "")
            raise InputError(f"{out}: {how} {what}", hint, param=param)
        if output_is_folder and out_real in inp_real.parents:
            raise InputError(f"{out}: holds the input {inp}, and the output folder is replaced whole", hint,
                             param=param)
        if inp_stat is not None and stat.S_ISDIR(inp_stat.st_mode) and inp_real in out_real.parents:
            raise InputError(f"{out}: is inside the input folder {inp}", hint, param=param)


def refuse_output_onto_output(file: str | Path | None, folder: str | Path | None, *, param: str,
                              file_is: str = "the recording",
                              folder_is: str = "the export folder", replaced: Iterable[str] = ()) -> None:
    """Refuse, before any work, two outputs of one command that collide: the file output ``file``
    (``-o X.rrd``, ``file_is`` in messages) and the folder output ``folder`` (``--export``,
    ``--screenshot``: ``folder_is``) the same path (the file was written, then the other output
    failed on it), or ``file`` inside one of ``replaced``, the subfolders of ``folder`` that are
    replaced whole (``--export``'s ``tum``: the file would be deleted). ``None`` skips the check."""
    if file is None or folder is None:
        return
    file_real, folder_real = Path(os.path.realpath(file)), Path(os.path.realpath(folder))
    hint = "give the two outputs different places"
    if file_real == folder_real or file_real in folder_real.parents:
        raise InputError(f"{folder}: is both {file_is} and {folder_is}" if file_real == folder_real else
                         f"{folder}: {folder_is} would lie inside {file_is} {file}", hint, param=param)
    for name in replaced:
        if folder_real / name == file_real or folder_real / name in file_real.parents:
            raise InputError(f"{file}: {file_is} would lie in {Path(folder) / name}, which {folder_is} replaces whole",
                             hint, param=param)


def _stat_or_none(path: Path) -> os.stat_result | None:
    try:
        return os.stat(path)
    except OSError:
        return None


def safe_stem(name: str) -> str:
    """A file-name stem from text that comes from inside a file (a recording's drive name): only
    letters, digits, '.', '-' and '_', no leading dot, never a path."""
    cleaned = "".join(c if c.isascii() and (c.isalnum() or c in "._-") else "_" for c in name)
    cleaned = re.sub(r"\.{2,}", ".", cleaned).lstrip(".")
    return cleaned[:100] or "recording"
