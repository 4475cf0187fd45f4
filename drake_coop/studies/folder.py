"""A study's ``--out`` folder: owned by one study, used by one process at a time.

Ownership
    :meth:`StudyFolder.claim` accepts a folder that does not exist yet (it is created), an
    empty folder, or the folder of the *same* study (same ``name``: a resume). The folder is
    marked as a study's by the file ``.drake-coop-study`` (JSON ``{"name": …}``); a folder
    written before that marker existed is recognized by its ``study.json`` of the same name.
    Anything else — a folder holding a user's files, a run's outputs, another study — is
    refused, naming what is there, before anything is written.

One process per folder
    The claim takes an exclusive ``fcntl.flock`` on ``.drake-coop-study.lock`` inside the
    folder (non-blocking: a second study on the same folder exits at once, naming the pid of
    the first). The kernel releases the lock when the holding process ends, however it ends
    (``kill -9`` included), so a killed study never leaves the folder locked.

Every problem is a :class:`StudyFolderError` with a one-line message that starts with
``--out <folder>`` (an ``OSError`` such as a read-only or full disk included).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from drake_coop.results.io import Locked, atomic_write_text, lock_file

__all__ = ["LOCK", "MARKER", "REACH", "StudyFolder", "StudyFolderError"]

#: The file that marks a folder as a study's (JSON: the study's name).
MARKER = ".drake-coop-study"
#: The lock file (holds the pid of the process that holds the lock).
LOCK = ".drake-coop-study.lock"
#: The reachability checks the study's folder keeps for a resume (JSON: a list of ``[what the
#: check reads, its refusal or null]``, :func:`~drake_coop.scenario.validation.reach_inputs`).
REACH = "reach_checks.json"
_OURS = {MARKER, LOCK}


class StudyFolderError(ValueError):
    """The folder cannot be used for this study (one-line message naming it and why)."""


def _shown(name: str, n: int = 60) -> str:
    text = name if name.isprintable() else repr(name)
    return text if len(text) <= n else text[:n] + "…"


class StudyFolder:
    """The ``--out`` folder of a study (see the module's docstring).

    Parameters
    ----------
    out : str or Path
        The folder.
    """

    def __init__(self, out: str | Path):
        self.out = Path(out)
        self._fd: int | None = None

    # --- reading what is there -----------------------------------------------------------
    def owner(self) -> str | None:
        """The name of the study that owns the folder, or None (no marker, no study.json).
        """
        for name, key in ((MARKER, "name"), ("study.json", "name")):
            path = self.out / name
            try:
                if path.is_symlink() or not path.is_file() or path.stat().st_size > 256_000_000:
                    continue
                with open(path, "rb") as f:
                    doc = json.loads(f.read().decode("utf-8"))
            except (OSError, ValueError, RecursionError):
                continue
            if isinstance(doc, dict) and isinstance(doc.get(key), str):
                return doc[key]
        return None

    def recorded_size(self) -> dict | None:
        """The size the folder's study was run at (:mod:`drake_coop.studies.size`): the
        marker's ``size``; ``{}`` (the file's own size) for a folder written before sizes
        were recorded; None for a folder that holds no study yet.
        """
        path = self.out / MARKER
        try:
            if not path.is_symlink() and path.is_file() and path.stat().st_size < 1_000_000:
                doc = json.loads(path.read_bytes().decode("utf-8"))
                if isinstance(doc, dict) and isinstance(doc.get("size"), dict):
                    return doc["size"]
        except (OSError, ValueError, RecursionError):
            pass
        return {} if (self.out / "study.json").is_file() else None

    def record_size(self, name: str, size: dict) -> None:
        """Write study ``name``'s size into the marker (atomically).

        Parameters
        ----------
        name : str
            The study's name.
        size : dict
            Its size (:mod:`drake_coop.studies.size`).
        """
        atomic_write_text(self.out / MARKER, json.dumps({"name": name, "size": size}) + "\n")

    def stored_reach(self) -> dict:
        """The reachability checks a run of the study stored here (:meth:`store_reach`), as
        :func:`~drake_coop.scenario.validation.validate`'s ``cache``; empty when none (or a
        damaged file: then everything is checked again).

        Returns
        -------
        dict
            ``("reach", inputs) -> refusal or None``.
        """
        path = self.out / REACH
        try:
            if not path.is_symlink() and path.is_file():
                doc = json.loads(path.read_bytes().decode("utf-8"))
                if isinstance(doc, list) and all(
                        isinstance(e, list) and len(e) == 2 and isinstance(e[0], str)
                        and (e[1] is None or isinstance(e[1], str)) for e in doc):
                    return {("reach", inputs): result for inputs, result in doc}
        except (OSError, ValueError, RecursionError):
            pass
        return {}

    def store_reach(self, cache: dict) -> None:
        """Keep the reachability checks of ``cache`` for a resume (atomically; the folder
        must be claimed).

        Parameters
        ----------
        cache : dict
            :func:`~drake_coop.scenario.validation.validate`'s ``cache``.
        """
        entries = sorted([key[1], result] for key, result in cache.items()
                         if isinstance(key, tuple) and key[0] == "reach")
        atomic_write_text(self.out / REACH, json.dumps(entries) + "\n")

    def _check(self, name: str) -> bool:
        """Raise unless the folder may be used by study ``name``; True if it exists."""
        out = self.out
        if out.is_symlink():
            raise StudyFolderError(f"--out {out} is a symbolic link; give the folder itself")
        if not out.exists():
            return False
        if not out.is_dir():
            raise StudyFolderError(f"--out {out} exists and is not a folder")
        entries = sorted(e for e in os.listdir(out) if e not in _OURS)
        owner = self.owner()
        if owner is None:
            if entries:
                raise StudyFolderError(
                    f"--out {out} holds '{_shown(entries[0])}', which is not part of a "
                    "drake-coop study; choose a new or empty folder")
        elif owner != name:
            raise StudyFolderError(
                f"--out {out} is the folder of study '{_shown(owner)}', not of "
                f"'{_shown(name)}'; choose another folder")
        return True

    # --- claiming ----------------------------------------------------------------------------
    def claim(self, name: str) -> StudyFolder:
        """Check the folder, create it if needed, lock it and mark it as study ``name``'s.

        Parameters
        ----------
        name : str
            The study's name.

        Returns
        -------
        StudyFolder
            This folder, locked and marked as study ``name``'s.

        Raises
        ------
        StudyFolderError
            Foreign content, another study's folder, a running study, or an OS error.
        """
        try:
            existed = self._check(name)
            if not existed:
                self.out.mkdir(parents=True, exist_ok=True)
            self._lock()
            self._check(name)          # again under the lock: another process may have won
            if self.owner() is None or not (self.out / MARKER).is_file():
                atomic_write_text(self.out / MARKER, json.dumps({"name": name}) + "\n")
            (self.out / "cases").mkdir(exist_ok=True)
        except StudyFolderError:
            self.release()
            raise
        except OSError as exc:
            self.release()
            raise StudyFolderError(f"--out {self.out}: {exc.strerror or exc}") from None
        return self

    def lock_existing(self) -> StudyFolder:
        """Lock a folder that already holds a study (for ``study --plot``).

        Returns
        -------
        StudyFolder
            This folder, locked.

        Raises
        ------
        StudyFolderError
            Not a study folder, a running study, or an OS error.
        """
        if not self.out.is_dir() or self.out.is_symlink():
            raise StudyFolderError(f"--plot {self.out}: no such study folder")
        if self.owner() is None:
            raise StudyFolderError(f"--plot {self.out}: no study.json (run `drake-coop study` "
                                   "first)")
        try:
            self._lock()
        except OSError as exc:
            raise StudyFolderError(f"--plot {self.out}: {exc.strerror or exc}") from None
        return self

    def _lock(self) -> None:
        try:
            self._fd = lock_file(self.out / LOCK)
        except Locked as exc:
            raise StudyFolderError(f"--out {self.out} is in use by another study process"
                                   f"{exc.by()}; wait for it to end or stop it") from None

    def release(self) -> None:
        """Release the lock (the kernel also does when the process ends)."""
        if self._fd is not None:
            try:
                os.close(self._fd)
            finally:
                self._fd = None

    def __enter__(self) -> StudyFolder:
        return self

    def __exit__(self, *exc) -> None:
        self.release()
