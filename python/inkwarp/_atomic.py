"""Temporary names for atomic writes, and the cleanup of those left by killed runs.

Every writer in inkwarp writes under a hidden name beside its output,
``.<name>.<pid>.<random>.part<suffix>``, and renames it at the end. A run killed by
SIGKILL (or by SIGHUP outside the command line) cannot delete its temporary file; the
next write to the same output removes every such file whose process is no longer alive
(and, for names written before the process id was part of them, those untouched for a
day).
"""

from __future__ import annotations

import errno
import os
import re
import secrets
import shutil
import time
from pathlib import Path

from inkwarp.errors import MissingFileError

#: Temporary files without a process id (older versions) are removed after this long.
LEGACY_AGE_S = 24 * 3600


def _alive(pid: int) -> bool:
    if pid <= 0:
        return False
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's live process
    except OverflowError:
        return False
    return True


def clean_stale(target: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files and folders beside ``target`` left by runs that were
    killed; returns what was removed. Files of live processes are never touched."""
    target = Path(os.fspath(target)).absolute()
    parent = target.parent
    name = re.escape(target.name)
    with_pid = re.compile(rf"^\.{name}\.(\d+)\.[0-9a-f]{{12}}\.(part|tmp)")
    legacy = re.compile(rf"^\.{name}\.[0-9a-f]{{12}}\.(part|tmp)")
    removed: list[Path] = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        if not entry.name.startswith("."):
            continue
        match = with_pid.match(entry.name)
        if match:
            stale = not _alive(int(match.group(1)))
        elif legacy.match(entry.name):
            try:
                stale = now - entry.stat(follow_symlinks=False).st_mtime > LEGACY_AGE_S
            except OSError:
                continue
        else:
            continue
        if not stale:
            continue
        path = Path(entry.path)
        try:
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(path)
            else:
                path.unlink()
            removed.append(path)
        except OSError:
            pass  # not ours to remove, or already gone
    return removed


def _unwritable(parent: Path, err: OSError) -> OSError:
    """The error for a folder that cannot take the temporary file, naming the folder."""
    if isinstance(err, PermissionError) or err.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        why = "read-only file system" if err.errno == errno.EROFS else "permission denied"
        return PermissionError(
            err.errno, f"cannot write in this output folder ({why}); choose an output in a "
            "writable folder or change the folder's permissions", str(parent))
    if err.errno == errno.ENOENT and not parent.exists():
        return MissingFileError(err.errno, "the folder does not exist; create it first", str(parent))
    # Any other refusal (a folder of the system's, such as /proc): name the folder, not the
    # hidden temporary name nobody asked for.
    why = "it takes no new files" if err.errno == errno.ENOENT else (err.strerror or str(err)).lower()
    return PermissionError(f"{parent}: cannot create a file in this output folder ({why}); "
                           "choose an output in an ordinary writable folder")


def temp_path(target: str | os.PathLike[str], suffix: str = "", *, directory: bool = False) -> Path:
    """A new empty file (or folder) beside ``target`` under a hidden temporary name that
    carries this process's id, created with the permissions of any new file (0o666, or
    0o777 for a folder, less the umask). Stale temporary files of ``target`` are removed
    first. A folder that cannot be written raises PermissionError naming the folder (one
    that does not exist, FileNotFoundError)."""
    target = Path(os.fspath(target))
    parent = target.absolute().parent
    clean_stale(target)
    while True:
        name = parent / f".{target.name}.{os.getpid()}.{secrets.token_hex(6)}.part{suffix}"
        try:
            if directory:
                os.mkdir(name, 0o777)
            else:
                os.close(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return name
        except FileExistsError:
            continue
        except OSError as err:
            raise _unwritable(parent, err) from None


def write_text(target: str | os.PathLike[str], text: str, *, suffix: str = "",
               mode: int | None = None, sync: bool = False) -> Path:
    """Write ``text`` to ``target`` atomically: into a :func:`temp_path` beside it, then
    renamed over it, so a reader never sees half a file and a failure leaves none.
    ``mode`` sets the file's permissions (default: those of any new file); ``sync``
    flushes it to disk before the rename."""
    target = Path(os.fspath(target))
    tmp = temp_path(target, suffix)
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            if sync:
                fh.flush()
                os.fsync(fh.fileno())
        if mode is not None:
            os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return target
