"""A run's output folder, written whole: staged in a hidden sibling, renamed into place.

A run never writes into its ``--out`` folder directly. :meth:`RunFolder.prepare` checks the
target before anything is simulated (an existing folder must be empty or hold only a previous
run's files; the parent must be writable and have room for the outputs) and creates a hidden
sibling ``.<name>.drake-coop-<pid>-<token>.tmp``; the run writes everything there, and
:meth:`RunFolder.commit` renames it onto ``--out`` (the previous run's folder, if any, is
renamed aside first and removed after). A folder holding a previous run whose ``run.json``
says it completed, diverged or was stopped by a robot's watchdog (a result: the record of
what happened) is replaced only when asked (``replace=True``, the
command line's ``--force``): a long run is not lost to a short one by a repeated command.
An interrupted run, or a folder with no readable ``run.json``, is replaced as before. So the
folder holds one complete run, or one
interrupted/diverged run marked as such in its ``run.json`` — never files of two runs.
:meth:`RunFolder.discard` removes the staging folder of a run that stops before its outputs;
folders left by killed processes (their pid no longer runs) are removed by the next run
into the same place.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
from pathlib import Path

from drake_coop.results.io import Locked, lock_folder, replace_folder

__all__ = ["OutputFolderError", "RunFolder", "previous_run"]

#: Files a run writes (names or suffixes); an existing folder holding anything else is kept.
RUN_FILES = {"run.json", "metrics.json", "scenario.yaml"}
RUN_SUFFIXES = {".npz", ".csv", ".png", ".svg", ".dot", ".html"}
#: Temporary files of :func:`drake_coop.results.io.atomic_path` left by a killed writer.
ATOMIC_TEMP = re.compile(r"\..+\.[0-9a-f]{8}\.tmp")
#: Room kept free for a run: per control tick and robot (a 3-joint robot's log of 35 columns,
#: CSV included; a robot with n = 6 joints and m = 3 constraints logs 64 columns, under twice
#: as much: the estimate is a floor, not a bound) and fixed (figures, diagrams, replay).
BYTES_PER_ROBOT_TICK = 1_500
BYTES_FIXED = 50_000_000


#: The ``run.json`` statuses of a run that is a result, kept unless replacing is asked for.
RESULT_STATUSES = ("ok", "diverged", "failed", "stopped")
#: The largest ``run.json`` read to tell whether a previous run completed.
MAX_RUN_JSON_BYTES = 16_000_000


def previous_run(path: Path) -> str | None:
    """The message of the run held in ``path`` if it is a result (completed, diverged, or
    stopped by a robot's watchdog: ``drake-coop serve``), else None (no run, an interrupted
    one, or an unreadable ``run.json``).

    Parameters
    ----------
    path : Path
        The target folder.

    Returns
    -------
    str or None
        The message, or None.
    """
    meta_path = path / "run.json"
    try:
        if meta_path.is_symlink() or meta_path.stat().st_size > MAX_RUN_JSON_BYTES:
            return None
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(meta, dict) or meta.get("status") not in RESULT_STATUSES:
        return None
    return str(meta.get("message", meta["status"]))[:80]


class OutputFolderError(ValueError):
    """The output folder cannot be used; the message names it and says why (one line)."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _is_run_folder(path: Path) -> tuple[bool, str]:
    """(usable, first foreign entry): empty, or only the files of a previous run."""
    entries = list(path.iterdir())
    for e in entries:
        if not (e.is_file() and not e.is_symlink()
                and (e.name in RUN_FILES or e.suffix in RUN_SUFFIXES
                     or ATOMIC_TEMP.fullmatch(e.name))):
            return False, e.name
    if entries and not any(e.name == "run.json" or e.suffix == ".npz" for e in entries):
        return False, entries[0].name
    return True, ""


class RunFolder:
    """The staging folder of one run and its target.

    Parameters
    ----------
    out : str or Path
        The ``--out`` folder.
    """

    def __init__(self, out: str | Path):
        self.out = Path(out)
        self.staging: Path | None = None
        self._lock_fd: int | None = None
        self._created = False

    def _release(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def _pattern(self) -> re.Pattern:
        return re.compile(rf"\.{re.escape(self.out.name)}\.drake-coop-(\d+)-[0-9a-f]+\.(tmp|old)")

    def prepare(self, ticks: int, robots: int = 2, replace: bool = False) -> Path:
        """Check the target and create the staging folder; return it.

        The target is locked first (a new one is created empty; the lock,
        :func:`drake_coop.results.io.lock_folder`, is released by :meth:`commit` or
        :meth:`discard`), then checked: two runs into one new ``--out`` cannot both claim it.

        Parameters
        ----------
        ticks : int
            Control ticks of the run (for the free-space estimate).
        robots : int
            Robots of the run (for the free-space estimate).
        replace : bool
            Replace a previous run that completed or diverged (see :func:`previous_run`).

        Returns
        -------
        Path
            The staging folder.

        Raises
        ------
        OutputFolderError
            The target is a file, holds foreign files or (without ``replace``) a previous
            run's result, or its parent cannot be created, written or has too little free
            space.
        """
        out = self.out
        if out.name in ("", ".", ".."):
            raise OutputFolderError(f"--out {out}: name a folder for the run, not '{out}'")
        try:
            if out.is_symlink():
                raise OutputFolderError(f"--out {out} is a symbolic link; give the folder itself")
            if out.exists() and not out.is_dir():
                raise OutputFolderError(f"--out {out} exists and is not a folder")
            out.parent.mkdir(parents=True, exist_ok=True)
            if not out.exists():            # a new --out: created empty, to be locked
                out.mkdir()
                self._created = True
            try:
                self._lock_fd = lock_folder(out)
            except Locked:
                self._created = False
                raise OutputFolderError(
                    f"--out {out} is being written by another drake-coop run; wait for it to "
                    "end or choose another folder") from None
            if out.is_dir():
                usable, foreign = _is_run_folder(out)
                if not usable:
                    raise OutputFolderError(
                        f"--out {out} holds '{foreign[:60]}', which is not a drake-coop output; "
                        "choose a new or empty folder (a previous run's folder is replaced)")
                held = None if replace else previous_run(out)
                if held is not None:
                    raise OutputFolderError(
                        f"--out {out} holds a previous run ({held}); add --force to replace "
                        "it, or choose another folder")
            self._remove_stale()
            staging = out.parent / f".{out.name}.drake-coop-{os.getpid()}-" \
                                   f"{secrets.token_hex(4)}.tmp"
            staging.mkdir()
            self.staging = staging
            (staging / ".write-test").write_bytes(b"drake-coop")
            (staging / ".write-test").unlink()
            need = BYTES_FIXED + BYTES_PER_ROBOT_TICK * robots * ticks
            free = shutil.disk_usage(staging).free
        except OutputFolderError:
            self.discard()
            raise
        except OSError as exc:
            self.discard()
            raise OutputFolderError(f"--out {out}: cannot write there "
                                    f"({exc.strerror or exc})") from None
        if free < need:
            self.discard()
            raise OutputFolderError(f"--out {out}: {free / 1e6:.0f} MB free on its disk, the "
                                    f"run needs about {need / 1e6:.0f} MB")
        return staging

    def _remove_stale(self) -> None:
        """Staging folders of this target left by processes that no longer run."""
        pattern = self._pattern()
        for e in self.out.parent.iterdir():
            m = pattern.fullmatch(e.name)
            if m and e.is_dir() and not e.is_symlink() and not _pid_alive(int(m.group(1))):
                shutil.rmtree(e, ignore_errors=True)

    def commit(self) -> Path:
        """Rename the staging folder onto the target (replacing a previous run's folder).

        Call with SIGINT/SIGTERM deferred: between the two renames the target is briefly
        absent (the previous run is in ``.<name>.drake-coop-…old``, removed right after).

        Returns
        -------
        Path
            The target.
        """
        assert self.staging is not None, "prepare() first"
        replace_folder(self.staging, self.out)
        self.staging = None
        self._created = False
        self._release()
        return self.out

    def discard(self) -> None:
        """Remove the staging folder (a run that stopped before its outputs)."""
        if self.staging is not None:
            shutil.rmtree(self.staging, ignore_errors=True)
            self.staging = None
        if self._created:                   # the empty --out this run created
            try:
                self.out.rmdir()
            except OSError:
                pass
            self._created = False
        self._release()
