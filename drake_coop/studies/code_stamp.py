"""The code stamp of a stored case: a fingerprint of the code that computed it.

A case's hash (:attr:`~drake_coop.studies.expand.Case.hash`) covers its scenario and its
variant, not the code of the blocks the variant builds. A store resumed after a change of that
code would keep the old code's numbers for the finished cases and mix them with the new
code's. So every record the store writes carries ``"code"``, the stamp of the running code
(:func:`code_stamp`), and a resume does not reuse a record whose stamp differs, or that has
none (written before stamps), without being told (:func:`reusable_records`):

- by default it refuses, in one line naming the store and the counts;
- ``rerun`` runs those cases again, replacing their files;
- ``keep`` keeps their numbers: the results then mix code versions, and the tables record how
  many such cases they hold (``stale_kept``).

The stamp is ``<source fingerprint>+drake<version>``. The source fingerprint is the SHA-256
(its first 16 hex digits) of every ``.py`` file of the :mod:`drake_coop` package with its
comments, docstrings, trailing spaces and blank lines removed (:func:`strip_source`), each
named by its path inside the package, in sorted order: an edit of a docstring or a comment
leaves it, any edit of the code changes it (including parts that compute no case, such as a
figure's or a command's code: the stamp is conservative). It does not depend on where the
package is, on file order or on ``__pycache__``, and it uses the tokenizer's positions of
comments and strings, not the abstract syntax tree's text (which differs between Python
versions). Drake's version (the ``drake`` distribution's, ``unknown`` for a build without
package metadata) is part of the stamp: numbers differ between Drake versions at the
rounding's scale. What the stamp does not cover: the arm model files and the lab arms'
description packages (a case's scenario names them, it does not hold them).

The stamp is of the code that the running command imported, computed once per process;
cases are stamped by the process that saves them (the command's, not its workers').
"""

from __future__ import annotations

import functools
import hashlib
import io
import tokenize
from collections.abc import Mapping
from pathlib import Path

__all__ = ["STALE_CHOICES", "check_stale_choice", "code_stamp", "count_stale", "drake_version",
           "package_sources", "reusable_records", "source_fingerprint", "strip_source"]

#: What a resume may do with records written by other code (None: refuse).
STALE_CHOICES = ("rerun", "keep")

#: Tokens after which a string starts a statement of its own (a docstring or a bare string).
_STATEMENT_START = (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING)
_SKIPPED = (tokenize.NL, tokenize.COMMENT)


def _is_plain_string(token: tokenize.TokenInfo) -> bool:
    """A string literal that is not an f-string (whose tokens differ between versions)."""
    if token.type != tokenize.STRING:
        return False
    prefix = token.string[:len(token.string) - len(token.string.lstrip("rRbBuUfF"))]
    return "f" not in prefix.lower()


def _removed_spans(tokens: list[tokenize.TokenInfo]) -> list[tuple[tuple, int]]:
    """The start positions and lengths (characters) of the comments and of the statements
    made of string literals only (docstrings).

    A length, not the token's end: Python 3.12's tokenizer gives the end column of a string
    spanning lines in UTF-8 bytes, not characters, when its last line holds non-ASCII text.
    """
    spans = [(t.start, len(t.string)) for t in tokens if t.type == tokenize.COMMENT]
    previous = None
    i = 0
    while i < len(tokens):
        token = tokens[i]
        if token.type in _SKIPPED:
            i += 1
            continue
        if token.type == tokenize.STRING and (previous is None or previous in _STATEMENT_START):
            j, run = i, []
            while j < len(tokens) and (tokens[j].type == tokenize.STRING
                                       or tokens[j].type in _SKIPPED):
                if tokens[j].type == tokenize.STRING:
                    run.append(tokens[j])
                j += 1
            ends = j == len(tokens) or tokens[j].type in (tokenize.NEWLINE, tokenize.ENDMARKER)
            if ends and all(_is_plain_string(t) for t in run):
                spans += [(t.start, len(t.string)) for t in run]
            previous = tokenize.STRING
            i = j
            continue
        previous = token.type
        i += 1
    return spans


def strip_source(text: str) -> str:
    """Python source without its comments, docstrings, trailing spaces and blank lines.

    A docstring here is any statement made of string literals only (not f-strings); its
    lines go, as do comments. The result is for fingerprinting, not for running (a function
    whose body was its docstring is left without a body).

    Parameters
    ----------
    text : str
        The source (it must tokenize: a module that imports).

    Returns
    -------
    str
        The remaining lines, right-stripped, joined by newlines.

    Raises
    ------
    ValueError
        The source does not tokenize.
    """
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, SyntaxError) as exc:
        raise ValueError(f"source: does not tokenize ({exc})") from None
    lines = io.StringIO(text).readlines()
    starts = [0]
    for line in lines:
        starts.append(starts[-1] + len(line))
    pieces, at = [], 0
    for (r0, c0), length in sorted(_removed_spans(tokens)):
        a = starts[r0 - 1] + c0
        b = a + length
        pieces += [text[at:a], "\n" * text.count("\n", a, b)]   # its lines stay lines
        at = b
    pieces.append(text[at:])
    kept = (line.rstrip() for line in "".join(pieces).splitlines())
    return "\n".join(line for line in kept if line)


def source_fingerprint(sources: Mapping[str, str]) -> str:
    """The fingerprint of a set of Python sources, comments and docstrings aside.

    Parameters
    ----------
    sources : Mapping of str to str
        Each module's name (its path inside the package, ``/``-separated) -> its source.

    Returns
    -------
    str
        16 hexadecimal digits (the start of a SHA-256): the same for the same names and
        stripped sources (:func:`strip_source`) in any order.
    """
    digest = hashlib.sha256()
    for name in sorted(sources):
        for part in (name, strip_source(sources[name])):
            data = part.encode("utf-8")
            digest.update(len(data).to_bytes(8, "big") + data)
    return digest.hexdigest()[:16]


def package_sources(root: str | Path | None = None) -> dict[str, str]:
    """Every ``.py`` file under ``root`` (``__pycache__`` aside), by its path inside it.

    Parameters
    ----------
    root : str or Path or None
        A package's folder; None: the :mod:`drake_coop` package's.

    Returns
    -------
    dict of str to str
        ``/``-separated path inside ``root`` -> the file's text (UTF-8).
    """
    if root is None:
        import drake_coop

        root = Path(drake_coop.__file__).parent
    root = Path(root)
    return {path.relative_to(root).as_posix(): path.read_text(encoding="utf-8")
            for path in root.rglob("*.py")
            if "__pycache__" not in path.relative_to(root).parts and path.is_file()}


def drake_version() -> str:
    """The installed Drake's version (``unknown`` without package metadata).

    Returns
    -------
    str
        E.g. ``1.51.1``.
    """
    from importlib import metadata

    try:
        return metadata.version("drake")
    except metadata.PackageNotFoundError:
        return "unknown"


@functools.lru_cache(maxsize=None)
def code_stamp() -> str:
    """The running code's stamp (computed once per process; see the module docstring).

    Returns
    -------
    str
        ``<16 hex digits>+drake<version>``, e.g. ``3f9a0c1b2d4e5f60+drake1.51.1``.
    """
    return f"{source_fingerprint(package_sources())}+drake{drake_version()}"


def check_stale_choice(stale: str | None) -> None:
    """Refuse a ``stale`` choice other than None or one of :data:`STALE_CHOICES`.

    Parameters
    ----------
    stale : str or None
        The choice.

    Raises
    ------
    ValueError
        One line naming the field and what is allowed.
    """
    if stale is not None and stale not in STALE_CHOICES:
        raise ValueError(f"stale: must be one of {', '.join(STALE_CHOICES)} (or none: "
                         f"refuse), got {stale!r}")


def reusable_records(records: Mapping[str, dict], hashes, stamp: str, stale: str | None,
                     where: str) -> tuple[dict[str, dict], int]:
    """The stored records a resume reuses, by the ``stale`` choice.

    Parameters
    ----------
    records : Mapping of str to dict
        The store's records by hash (:meth:`~drake_coop.studies.store.ResultStore.load`).
    hashes : iterable of str
        The run's cases' hashes: only their records are judged (a stored case the run does
        not include is left alone).
    stamp : str
        The running code's stamp (:func:`code_stamp`).
    stale : str or None
        None: refuse if any of the run's records was written by other code (or carries no
        stamp); ``"rerun"``: those records are not reused (their cases run again);
        ``"keep"``: they are reused.
    where : str
        The store, as the refusal names it (e.g. ``--out DIR``).

    Returns
    -------
    records : dict of str to dict
        The records to reuse.
    stale : int
        How many of the run's records were written by other code (rerun or kept).

    Raises
    ------
    ValueError
        ``stale`` is not None nor one of :data:`STALE_CHOICES`; or it is None and the run's
        records include some written by other code (one line: the store, the counts, the
        two ways on).
    """
    check_stale_choice(stale)
    ours = {h: records[h] for h in set(hashes) if h in records}
    other = [h for h, r in ours.items() if r.get("code") != stamp]
    if not other:
        return dict(records), 0
    if stale is None:
        bare = sum("code" not in ours[h] for h in other)
        raise ValueError(
            f"{where}: {len(other)} of the {len(ours)} stored cases of this run were "
            f"computed by other code ({bare} of them carry no code stamp: written before "
            "stamps); give --stale rerun to run them again (replacing their files) or --stale "
            "keep to keep their numbers (the results then mix code versions)")
    if stale == "keep":
        return dict(records), len(other)
    rerun = set(other)
    return {h: r for h, r in records.items() if h not in rerun}, len(other)


def count_stale(records: Mapping[str, dict], hashes, stamp: str) -> int:
    """How many of the cases' records were written by other code (or carry no stamp).

    Parameters
    ----------
    records : Mapping of str to dict
        Finished records by hash.
    hashes : iterable of str
        The cases' hashes (each distinct one counted once).
    stamp : str
        The running code's stamp.

    Returns
    -------
    int
        The count.
    """
    return sum(records[h].get("code") != stamp for h in set(hashes) if h in records)
