"""Where drake_uav writes: the overwrite rule, checked before any work and again at the swap.

The rule: drake_uav only ever replaces what it wrote itself, and never the user's files.

An output **folder** (a report, the tracking plots) may be

* missing: it is created (with its parents);
* an empty folder: it receives the output;
* a folder holding an earlier output and nothing else: it is replaced as a whole. Such a
  folder is recognised by its manifest, ``drake_uav_manifest.json``, the last file written
  into it, which lists every file of the folder; a folder holding anything the manifest does
  not list (a file the user added, a flight log, code) is never replaced;
* anything else (a folder with other files, a file, the current folder or one of its
  parents, a folder that cannot be written): refused with a one-line
  :class:`OutputRefusedError`, before any work when the caller checks first
  (:func:`check_output_folder`).

A folder is written into a hidden sibling ``.<name>.partial-<random>`` and swapped into place
by :func:`replace_folder` only when complete, under an exclusive lock on the parent folder
(``flock``), so two processes writing the same output take turns: the target is re-checked
under the lock, the earlier output moved aside and deleted, and Ctrl-C is held back until the
swap is done. A check (:func:`check_output_folder`) holds a shared lock on the parent, so it
never looks at a folder another writer is swapping (moved aside, not yet replaced). A
process killed while writing leaves at most a ``.partial-`` folder, never a half-written
output.

An output **file** (a replay page) may be missing or a file drake_uav wrote (recognised by the
caller's ``ours`` test, e.g. a marker in its first bytes); it is never an input of the same
command. It is written to a hidden temporary sibling and renamed into place
(:func:`replace_file`).

This module uses the standard library only, so the command line checks its outputs before the
analysis stack loads.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import signal
import tempfile
import threading
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

__all__ = ["MANIFEST", "OutputRefusedError", "check_output_folder", "check_output_file",
           "check_writable",
           "new_partial_folder", "write_manifest", "replace_folder", "replace_file",
           "output_folder",
           "is_drake_uav_output", "is_replay_page", "REPLAY_MARKER"]

REPLAY_MARKER = "<!-- drake_uav replay page -->"
"""Written on the second line of a replay page: the marker of a page drake_uav may replace."""

MANIFEST = "drake_uav_manifest.json"
"""The marker of a folder drake_uav wrote: JSON ``{"written_by": "drake_uav", "kind": ...,
"files": [...]}``, written last."""

_WRITER = "drake_uav"
_SHOWN = 4  # files named in a refusal


class OutputRefusedError(FileExistsError, ValueError):
    """An output path drake_uav must not write to (module docstring); the message is one line
    naming the path and what to do. A ``ValueError`` too, so the command line exits 2."""


def _read_manifest(folder: Path) -> dict | None:
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(data, dict) and data.get("written_by") == _WRITER
            and isinstance(data.get("files"), list)):
        return None
    return data


def is_drake_uav_output(folder: str | os.PathLike) -> bool:
    """True if ``folder`` holds an output drake_uav wrote and nothing else: its manifest, and
    only entries the manifest lists (one the user deleted does not matter, one the user added
    does)."""
    folder = Path(folder)
    manifest = _read_manifest(folder)
    if manifest is None:
        return False
    try:
        entries = {p.name for p in folder.iterdir()}
    except OSError:
        return False
    return MANIFEST in entries and entries <= {*map(str, manifest["files"]), MANIFEST}


def is_replay_page(path: str | os.PathLike) -> bool:
    """True if ``path`` is a replay page drake_uav wrote (:data:`REPLAY_MARKER` near its top)."""
    try:
        with open(path, "rb") as f:
            head = f.read(256)
    except OSError:
        return False
    return REPLAY_MARKER.encode() in head


@contextlib.contextmanager
def _os_errors_refused(what: str, path: str | os.PathLike) -> Iterator[None]:
    """An OSError while looking at ``path`` (a folder that cannot be searched) refuses it."""
    try:
        yield
    except OutputRefusedError:
        raise
    except OSError as err:
        raise OutputRefusedError(f"{what} {os.fspath(path)}: cannot be checked "
                                 f"({err.strerror or err})") from None


def _listing(names: Iterable[str]) -> str:
    names = sorted(names)
    more = f", ... ({len(names)} entries)" if len(names) > _SHOWN else ""
    return ", ".join(names[:_SHOWN]) + more


def _inside(path: str | os.PathLike, folder: str | os.PathLike) -> bool:
    """True if ``path`` is ``folder`` or lies in it (links resolved)."""
    path, folder = Path(os.path.realpath(path)), Path(os.path.realpath(folder))
    return path == folder or folder in path.parents


def check_writable(path: str | os.PathLike, what: str) -> None:
    """Raises OutputRefusedError unless ``path`` can be created: the nearest existing ancestor
    of its parent is a folder this process can create entries in (tried for real, so
    permissions, read-only mounts and special file systems such as /proc all count)."""
    path = Path(os.path.abspath(path))
    ancestor = path.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise OutputRefusedError(f"{what} {path}: {ancestor} is a file, not a folder")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".drake_uav-probe-", dir=ancestor))
    except OSError as err:
        raise OutputRefusedError(f"{what} {path}: cannot write in {ancestor} "
                                 f"({err.strerror or err})") from None


def check_output_folder(path: str | os.PathLike, *, what: str = "--out",
                        inputs: Sequence[str | os.PathLike] = ()) -> Path:
    """Checks that ``path`` may receive an output folder (module docstring); returns it
    absolute.

    Parameters
    ----------
    path : the output folder.
    what : how the message names it (the command-line option).
    inputs : files the same command reads; a folder holding one is refused by name.

    Raises
    ------
    OutputRefusedError
        ``path`` is a file, the current folder or one of its parents, holds an input, holds
        anything but an earlier drake_uav output, or cannot be written.
    """
    path = Path(os.path.abspath(path))
    with _os_errors_refused(what, path), _parent_locked(path, fcntl.LOCK_SH):
        return _checked_folder(path, what, inputs)


def _checked_folder(path: Path, what: str, inputs: Sequence[str | os.PathLike]) -> Path:
    if path.name in ("", ".", ".."):
        raise OutputRefusedError(f"{what} {path}: give a folder name for the output")
    shown = f"{what} {os.fspath(path)}"
    if path.is_symlink():
        raise OutputRefusedError(f"{shown}: is a link; give a folder for the output")
    if path.exists() and not path.is_dir():
        raise OutputRefusedError(f"{shown}: is an existing file; give a folder for the output")
    if _inside(os.getcwd(), path):
        raise OutputRefusedError(f"{shown}: is the current folder or contains it; the output "
                                 "replaces its folder as a whole, give a sub-folder, e.g. "
                                 f"{path / 'report'}")
    for item in inputs:
        if _inside(item, path):
            raise OutputRefusedError(f"{shown}: holds the input {item}; give another folder "
                                     "for the output")
    if path.is_dir():
        try:
            entries = [p.name for p in path.iterdir()]
        except OSError as err:
            raise OutputRefusedError(f"{shown}: cannot be read ({err.strerror or err})") from None
        if entries and not is_drake_uav_output(path):
            raise OutputRefusedError(
                f"{shown}: holds files drake_uav did not write ({_listing(entries)}); give a "
                "new or empty folder (only a folder holding nothing but an earlier output, "
                f"per its {MANIFEST}, is replaced)")
    check_writable(path, what)  # the output is written beside it, then renamed
    return path


def check_output_file(path: str | os.PathLike, *, ours: Callable[[Path], bool],
                      what: str, inputs: Sequence[str | os.PathLike] = ()) -> Path:
    """Checks that the file ``path`` may be written (module docstring); returns it absolute.

    Parameters
    ----------
    path : the output file.
    ours : ``ours(path)`` is True for an existing file drake_uav wrote (it may be replaced).
    what : how the message names it (the command-line option).
    inputs : files the same command reads; none of them is ever overwritten.

    Raises
    ------
    OutputRefusedError
        ``path`` is an input, a folder, a file drake_uav did not write, or cannot be written.
    """
    with _os_errors_refused(what, path):
        return _checked_file(Path(os.path.abspath(path)), ours, what, inputs)


def _checked_file(path: Path, ours: Callable[[Path], bool], what: str,
                  inputs: Sequence[str | os.PathLike]) -> Path:
    shown = f"{what} {os.fspath(path)}"
    for item in inputs:
        item = Path(item)
        if path == Path(os.path.abspath(item)) or (
                path.exists() and item.exists() and os.path.samefile(path, item)):
            raise OutputRefusedError(f"{shown}: is the input {item}; give another file name")
    if path.is_dir():
        raise OutputRefusedError(f"{shown}: is a folder; give a file name")
    if path.exists() and not ours(path):
        raise OutputRefusedError(f"{shown}: exists and was not written by drake_uav; give "
                                 "another file name (it is not replaced)")
    check_writable(path, what)
    return path


def new_partial_folder(target: str | os.PathLike) -> Path:
    """A new empty hidden sibling ``.<name>.partial-<random>`` of ``target`` (parents
    created), readable by all, where an output is written before :func:`replace_folder`."""
    target = Path(os.path.abspath(target))
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
    partial.chmod(0o755)  # mkdtemp makes it private; an output is meant to be shared
    return partial


def write_manifest(folder: str | os.PathLike, kind: str) -> None:
    """Writes the manifest of ``folder`` (every entry in it, and ``kind``), synced to disk.
    Call it last: a folder without a manifest is never taken for a finished output."""
    folder = Path(folder)
    files = sorted(p.name for p in folder.iterdir() if p.name != MANIFEST)
    _write_synced(folder / MANIFEST, json.dumps(
        {"written_by": _WRITER, "kind": kind, "files": files}, indent=2) + "\n")


def _write_synced(path: Path, text: str) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


@contextlib.contextmanager
def _parent_locked(target: Path, mode: int = fcntl.LOCK_EX) -> Iterator[None]:
    """A ``flock`` on the parent folder of ``target`` (released on close, also when the
    process dies): exclusive for a writer's swap (writers of one parent take turns), shared
    for a check (it waits for a swap in progress). Nothing is left on disk. A parent that
    cannot be opened (missing: nothing to order) and a file system without ``flock`` (some
    network mounts) leave the callers unordered; the check then reports what it finds. Never
    nest two locks on one parent in one process: ``flock`` treats each open of the folder as
    another holder."""
    try:
        fd = os.open(target.parent, os.O_RDONLY)
    except OSError:
        fd = None
    if fd is None:
        yield
        return
    try:
        with contextlib.suppress(OSError):  # no flock on this file system: writers unordered
            fcntl.flock(fd, mode)
        yield
    finally:
        os.close(fd)


@contextlib.contextmanager
def _interrupts_held() -> Iterator[None]:
    """Ctrl-C (SIGINT) waits until the block is done, then takes effect (main thread only:
    Python handles signals there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if received:
            if callable(previous):
                previous(signal.SIGINT, None)
            elif previous == signal.SIG_DFL:
                os.kill(os.getpid(), signal.SIGINT)


def replace_folder(partial: str | os.PathLike, target: str | os.PathLike,
                   what: str = "output folder") -> Path:
    """Moves the complete folder ``partial`` to ``target``, replacing an empty folder or an
    earlier drake_uav output there, under the parent's lock; returns ``target``.

    Raises
    ------
    OutputRefusedError
        ``target`` now holds something else (``partial`` is left for the caller to remove).
    """
    partial, target = Path(partial), Path(os.path.abspath(target))
    with _parent_locked(target), _interrupts_held():
        with _os_errors_refused(what, target):
            _checked_folder(target, what, ())
        if target.is_dir() and any(target.iterdir()):
            old = target.with_name(f".{target.name}.old-{uuid.uuid4().hex[:8]}")
            os.rename(target, old)
            try:
                os.rename(partial, target)
            except BaseException:
                os.rename(old, target)
                raise
            shutil.rmtree(old)
        else:
            os.rename(partial, target)  # an empty folder is replaced in one step
    return target


@contextlib.contextmanager
def output_folder(target: str | os.PathLike, kind: str,
                  what: str = "output folder") -> Iterator[Path]:
    """Writes an output folder whole: yields a new partial folder to write into; when the
    block ends normally, writes the manifest (``kind``) and swaps the folder into
    ``target`` (:func:`replace_folder`); when it raises, removes the partial folder and
    leaves ``target`` as it was.

    Parameters
    ----------
    target : path-like
        The output folder: missing, empty, or an earlier drake_uav output.
    kind : str
        What the folder holds, recorded in its manifest (e.g. ``"report"``).
    what : str
        How a refusal names the folder (e.g. ``"--out"``).

    Yields
    ------
    Path
        The partial folder to write every file of the output into.

    Raises
    ------
    OutputRefusedError
        ``target`` holds something else, checked before the block and again at the swap.
    """
    check_output_folder(target, what=what)
    partial = new_partial_folder(target)
    try:
        yield partial
        write_manifest(partial, kind)  # last: the marker of a finished output
        replace_folder(partial, target, what=what)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise


def replace_file(write: Callable[[Path], None], target: str | os.PathLike, *,
                 ours: Callable[[Path], bool], what: str = "output file") -> Path:
    """Writes a file through ``write(temporary_path)`` and renames it to ``target`` (missing,
    or a file ``ours`` recognises), under the parent's lock; returns ``target``.

    Raises
    ------
    OutputRefusedError
        ``target`` is not a file drake_uav may replace (nothing is written).
    """
    target = check_output_file(target, ours=ours, what=what)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        write(tmp)
        with _parent_locked(target), _interrupts_held():
            check_output_file(target, ours=ours, what=what)
            os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
    return target
