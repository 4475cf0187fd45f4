"""Atomic file output: a file is written whole or not at all.

Everything the package writes goes to a temporary file in the target's directory first and is
renamed onto the target (``os.replace``, atomic on POSIX) only once complete. A failure leaves
the previous target (if any) untouched and no temporary file behind.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text"]


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
        ``path``.
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
        ``path``.
    """
    return atomic_write_bytes(path, text.encode("utf-8"))
