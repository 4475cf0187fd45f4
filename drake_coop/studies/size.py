"""A study sized from the command line: ``--t-end``, ``--draws``, ``--cases``.

A user trying a shipped study shrinks it without copying its file::

    drake-coop study studies/object_carry.yaml --out runs/try --t-end 5 --draws 1 --cases 4

``--t-end S``
    Every case stops at ``S`` seconds (the study's ``t_end``; at least one control period's
    lower bound, as in a study file).
``--draws N``
    ``N`` Monte Carlo samples per grid point (the study's ``monte_carlo.n``; the draws are
    the first ``N`` of the seed's sequence, so a larger ``N`` keeps the smaller one's cases).
``--cases N``
    Only the first ``N`` cases in the study's order (grid outer, samples inner).

The size given is recorded in the folder's marker (:data:`~drake_coop.studies.folder.MARKER`,
``{"name": …, "size": {…}}``, ``{}`` for the study file's own size). A resume without these
options runs at the recorded size; a resume with a size other than the recorded one is
refused with one line (the case hashes hold ``t_end``, so a mixed folder would hold two
studies). A folder written before the size was recorded counts as the file's own size.
"""

from __future__ import annotations

import dataclasses
import math

from drake_coop.studies.spec import Study, StudyError

__all__ = ["OPTIONS", "apply_size", "given_size", "size_text"]

#: Size field -> its command-line option.
OPTIONS = {"t_end": "--t-end", "draws": "--draws", "cases": "--cases"}


def given_size(args) -> dict:
    """The size options given on the command line (``{}`` for none).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    dict
        Option key → value.
    """
    return {key: getattr(args, key) for key in OPTIONS if getattr(args, key, None) is not None}


def size_text(size: dict) -> str:
    """A size as the options that give it (``the study file's size`` for ``{}``).

    Parameters
    ----------
    size : dict
        Option key → value.
    """
    if not size:
        return "the study file's own size (no " + ", ".join(OPTIONS.values()) + ")"
    return " ".join(f"{OPTIONS[k]} {size[k]:g}" if isinstance(size[k], float)
                    else f"{OPTIONS[k]} {size[k]}" for k in OPTIONS if k in size)


def apply_size(study: Study, size: dict) -> tuple[Study, int | None]:
    """``study`` with ``size``'s ``t_end`` and ``draws`` set, and the ``cases`` bound.

    Parameters
    ----------
    study : Study
        The study.
    size : dict
        Option key → value.

    Returns
    -------
    study : Study
        The sized study.
    cases : int or None
        The bound on the cases, or None.

    Raises
    ------
    StudyError
        A value out of range, one line starting with the option's name.
    """
    from drake_coop.control.params import PERIOD_RANGE

    for key in size:
        if key not in OPTIONS:
            raise StudyError(f"size: unknown field {key!r}; allowed: {', '.join(OPTIONS)}")
    study = dataclasses.replace(study)
    if "t_end" in size:
        t_end = size["t_end"]
        if isinstance(t_end, bool) or not isinstance(t_end, (int, float)) \
                or not math.isfinite(t_end) or t_end < PERIOD_RANGE[0]:
            raise StudyError(f"--t-end: must be a finite number of seconds >= "
                             f"{PERIOD_RANGE[0]:g}, got {t_end!r}")
        study.t_end = float(t_end)
    if "draws" in size:
        draws = size["draws"]
        if study.monte_carlo is None:
            raise StudyError(f"--draws: study {study.name!r} has no monte_carlo block (its "
                             "cases are its grid's points; --cases takes the first N)")
        if isinstance(draws, bool) or not isinstance(draws, int) or draws < 1:
            raise StudyError(f"--draws: must be an integer >= 1, got {draws!r}")
        study.monte_carlo = dataclasses.replace(study.monte_carlo, n=draws)
    cases = size.get("cases")
    if cases is not None and (isinstance(cases, bool) or not isinstance(cases, int)
                              or cases < 1):
        raise StudyError(f"--cases: must be an integer >= 1, got {cases!r}")
    if cases is not None:
        from drake_coop.studies.expand import study_size

        total = study_size(study)[0]
        if cases > total:
            raise StudyError(f"--cases: study {study.name!r} has {total} cases at this size, "
                             f"got {cases}")
    return study, cases
