"""Atomic file output: a file, or a folder of files, is written whole or not at all.

Everything the package writes goes to a temporary file in the target's directory first and is
renamed onto the target (``os.replace``, atomic on POSIX) only once complete. A failure leaves
the previous target (if any) untouched and no temporary file behind. A command's output folder
is checked before any work (:func:`check_output_folder`) and written the same way, staged in a
hidden sibling and swapped in at the end (:func:`staged_folder`).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import secrets
import shutil
from pathlib import Path
from typing import Iterator

__all__ = ["Locked", "OutputError", "atomic_path", "lock_file", "lock_folder", "atomic_write_bytes", "atomic_write_text",
           "check_output_folder", "replace_folder", "staged_folder"]

#: Free space a command's output folder needs at least (figures, tables, URDFs).
MIN_FREE_BYTES = 20_000_000


class OutputError(ValueError):
    """An output folder that cannot be written (one line naming it and why)."""


def _new_temp(path: Path) -> Path:
    """Create an empty, uniquely named file beside ``path`` (mode 0666 minus the umask)."""
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return tmp
    raise FileExistsError(f"no free temporary name beside {path}")


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` if the block succeeds.

    Parameters
    ----------
    path : str or Path
        The target file. Its directory is created if needed.

    Yields
    ------
    Path
        An empty temporary file in the same directory, to be written by the block (its name
        ends in ``.tmp``: pass an explicit format to writers that guess it from the suffix).

    Notes
    -----
    If the block raises, the temporary file is removed, ``path`` is left as it was and the
    exception propagates.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _new_temp(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
        The target file.
    data : bytes
        Its whole content.

    Returns
    -------
    Path
        ``path``, the file now holding the data.
    """
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically, UTF-8 encoded.

    Parameters
    ----------
    path : str or Path
        The target file.
    text : str
        Its whole content.

    Returns
    -------
    Path
        ``path``, the file now holding the data.
    """
    return atomic_write_bytes(path, text.encode("utf-8"))


def check_output_folder(out: str | Path, option: str = "--out",
                        need_bytes: int = MIN_FREE_BYTES) -> Path:
    """Check, before any work, that the folder ``out`` can be written whole.

    ``out`` (or, when it does not exist yet, its nearest existing ancestor) must be a folder
    that accepts a new file and has ``need_bytes`` free; nothing is left behind.

    Parameters
    ----------
    out : str or Path
        The folder.
    option : str
        The option naming it, for messages.
    need_bytes : int
        The free space required, bytes.

    Returns
    -------
    Path
        ``out``, checked and ready to be written.

    Raises
    ------
    OutputError
        ``<option> <out>: ...``: a file in the way (``out`` itself or an ancestor), a
        read-only folder, too little free space.
    """
    out = Path(out)
    if out.name in ("", ".", ".."):
        raise OutputError(f"{option} {out}: name a folder, not {str(out)!r}")
    probe_dir = out
    while not probe_dir.exists() and probe_dir != probe_dir.parent:
        if probe_dir.is_symlink():
            break
        probe_dir = probe_dir.parent
    if not probe_dir.is_dir():
        where = "exists" if probe_dir == out else f"is inside {probe_dir}, which exists"
        raise OutputError(f"{option} {out} {where} and is not a folder")
    tmp = None
    try:
        tmp = _new_temp(probe_dir / ".drake-coop-write-test")
        tmp.write_bytes(b"drake-coop")
    except OSError as exc:
        raise OutputError(f"{option} {out}: cannot write there ({exc.strerror or exc})") from None
    finally:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
    free = shutil.disk_usage(probe_dir).free
    if free < need_bytes:
        raise OutputError(f"{option} {out}: {free / 1e6:.0f} MB free on its disk, the outputs "
                          f"need about {need_bytes / 1e6:.0f} MB")
    return out


@contextlib.contextmanager
def staged_folder(out: str | Path) -> Iterator[Path]:
    """Yield an empty hidden sibling of the folder ``out``; when the block succeeds, it
    replaces ``out`` (a previous ``out`` is renamed aside, then removed).

    If the block raises (a full disk, a signal), the staging folder is removed, ``out`` is
    left as it was and the exception propagates.

    Parameters
    ----------
    out : str or Path
        The folder to replace.

    Yields
    ------
    Path
        The staging folder.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = out.parent / f".{out.name}.drake-coop-{os.getpid()}-{secrets.token_hex(4)}.tmp"
    staging.mkdir()
    try:
        yield staging
        replace_folder(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def replace_folder(staging: Path, out: Path) -> None:
    """Rename the folder ``staging`` onto ``out``; a previous ``out`` is renamed aside to
    ``staging`` with the suffix ``.old`` first and removed after (put back if the rename
    fails). Between the two renames ``out`` is briefly absent: call with signals deferred.

    Parameters
    ----------
    staging : Path
        The finished folder.
    out : Path
        The target.
    """
    old = None
    if out.is_dir():
        old = staging.with_suffix(".old")
        os.rename(out, old)
    try:
        os.rename(staging, out)
    except OSError:
        if old is not None:
            os.rename(old, out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


class Locked(Exception):
    """The lock file is held by another process (``holder``: its pid as text, or "").

    Parameters
    ----------
    holder : str
        The holder's pid as text, or ``""``.
    """

    def __init__(self, holder: str):
        super().__init__(holder)
        self.holder = holder

    def by(self) -> str:
        """`` (pid N)`` when the holder is known, else an empty string.
        """
        return f" (pid {self.holder})" if self.holder.isdigit() else ""


def lock_file(path: str | Path) -> int:
    """Take an exclusive ``fcntl.flock`` on ``path`` (created if needed) without waiting, write
    this process's pid into it, and return its descriptor (closing it releases the lock; the
    kernel releases it when the process ends, however it ends).

    Parameters
    ----------
    path : str or Path
        The lock file.

    Returns
    -------
    int
        The open file's descriptor; closing it releases the lock.

    Raises
    ------
    Locked
        Another process (or another descriptor of this one) holds it.
    OSError
        The file cannot be opened (a read-only folder, a symbolic link).
    """
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        try:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        except OSError:
            holder = ""
        os.close(fd)
        raise Locked(holder) from None
    except OSError:
        os.close(fd)
        raise
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return fd


def lock_folder(path: str | Path) -> int:
    """Take an exclusive ``fcntl.flock`` on the folder ``path`` itself without waiting (the lock
    of :func:`lock_file`, with no file to leave behind) and return its descriptor.

    Parameters
    ----------
    path : str or Path
        The folder.

    Returns
    -------
    int
        The open file's descriptor; closing it releases the lock.

    Raises
    ------
    Locked
        Another process (or another descriptor of this one) holds it.
    OSError
        ``path`` is not a folder or cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise Locked("") from None
    except OSError:
        os.close(fd)
        raise
    return fd
