"""The ``{result}`` role: a number printed from a shipped results file, with its unit.

The docs' measured numbers are not typed: each is read, at build time, from the file the
command that measured it wrote (a study's ``results.csv``, a run's ``metrics.json``), so
re-running the study and rebuilding the docs updates the prose. Syntax (MyST)::

    {result}`SOURCE:EXPR as FORMAT UNIT`

``SOURCE``
    a study's name, read as ``docs/figures/studies/<name>_results.csv`` (where ``drake-coop
    study --plot`` ships its ``results.csv``), or a path from the repository's root to a
    ``.csv`` or ``.json`` file.
``EXPR``
    ``COLUMN [where FILTER [and FILTER ...]]``, or ``AGG(COLUMN [where ...])`` with ``AGG`` one
    of ``min``, ``max``, ``mean``, ``median``, ``pNN`` (the NN th percentile, ``p10``),
    ``sum``, ``range`` (printed ``lo–hi``, or one value when both print the same) and
    ``count`` (of the selected rows; any column).
    ``COLUMN`` is a CSV column, named in full or by a unique ending after a ``.``
    (``force_source`` for ``robots.*.force_source``); without ``AGG`` the filters must select
    exactly one row. A ``FILTER`` is ``COLUMN=VALUE`` (numbers compared as numbers, text
    exactly; ``COLUMN=`` alone: the cell is empty), ``COLUMN~TEXT`` (the cell contains the text), or ``COLUMN<NUMBER``,
    ``COLUMN>NUMBER`` (in the file's SI unit). In a JSON file ``COLUMN`` is a
    dotted key path (list items by index; ``*`` in a key matches any, as ``fnmatch``), and an
    ``AGG`` applies to every value it reaches (``max(*.circle.force_error.rms)``: the worst
    robot's).
``FORMAT``
    a Python format specification (``.3f``, ``.2g``, ``.0f``); ``.3g`` when omitted;
    ``text`` prints one CSV cell as written (a variant's label).
``UNIT``
    the unit printed after the value; the file's SI value is scaled to it
    (:data:`UNITS`). ``[UNIT]`` scales the same and prints no unit (a table whose header
    names it). A number without a unit (a ratio, a count) writes ``as .2f`` alone.

Example: ``{result}`force_sensing:robot1.force_error.rms where force_source=observer and
noise_std=0.1 as .3f N``` prints ``0.047 N``. A role that does not resolve (no file, no such
column, no row, several rows, an unknown unit) is a build error, fatal under ``-W``; the
test ``tests/test_docs_numbers.py`` resolves every role of every page, and checks that the
claims pages and the object guide hold no measured number outside a role.
"""

from __future__ import annotations

import csv
import fnmatch
import json
import math
import re
import statistics
from functools import lru_cache
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive, directives

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "docs" / "figures" / "studies"

#: Units a value may be printed in, and the factor from the file's SI value to that unit.
UNITS: dict[str, float] = {
    "": 1.0, "m": 1.0, "mm": 1e3, "µm": 1e6, "N": 1.0, "mN": 1e3, "N/s": 1.0, "N m": 1.0,
    "s": 1.0, "ms": 1e3, "µs": 1e6, "kg": 1.0, "g": 1e3, "rad": 1.0, "mrad": 1e3,
    "rad/s": 1.0, "mrad/s": 1e3, "m/s": 1.0, "mm/s": 1e3, "%": 100.0, "×": 1.0,
    "MPa": 1e-6, "N·m": 1.0, "µrad": 1e6, "°": 180.0 / math.pi,
}
AGGREGATES = ("min", "max", "mean", "median", "sum", "range", "count")

_SPEC = re.compile(r"^(?P<source>[^:\s]+):(?P<expr>.+?)(?:\s+as\s+(?P<fmt>[^\s]*)"
                   r"(?:\s+(?P<unit>.+?))?)?\s*$", re.S)
_PERCENTILE = re.compile(r"^p(\d{1,2})$")
_AGG = re.compile(r"^(?P<agg>\w+)\((?P<inner>.+)\)$", re.S)
_FILTER = re.compile(r"^(?P<col>[^=~<>\s]+)\s*(?P<op>[=~<>])\s*(?P<value>.*?)$")


class ResultError(ValueError):
    """A ``{result}`` role that does not resolve (the message names what is wrong)."""


class MissingValue(ResultError):
    """The selected cell is empty or not finite (a metric a diverged or ungrasped case lacks)."""


def source_path(source: str, root: Path = ROOT) -> Path:
    """The file a role's ``SOURCE`` names (a study's name or a path from ``root``, the
    repository's root unless the Sphinx config value ``results_root`` says otherwise)."""
    root = Path(root)
    if source.endswith((".csv", ".json")):
        path = root / source
    else:
        path = root / STUDIES.relative_to(ROOT) / f"{source}_results.csv"
    if not path.is_file():
        raise ResultError(f"{source}: no file {path.relative_to(root)}")
    return path


@lru_cache(maxsize=64)
def _read(path: Path, stamp: tuple[int, int]) -> object:
    if path.suffix == ".json":
        return json.loads(path.read_text())
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def load(path: Path) -> object:
    """The rows of a CSV file (dicts) or the document of a JSON file, cached per version
    (modification time and size)."""
    stat = path.stat()
    return _read(path, (stat.st_mtime_ns, stat.st_size))


def _column(rows: list[dict], name: str, source: str) -> str:
    columns = list(rows[0]) if rows else []
    if name in columns:
        return name
    ends = [c for c in columns if c.endswith("." + name)]
    if len(ends) != 1:
        raise ResultError(f"{source}: column {name!r} " + (
            "matches none" if not ends else f"is ambiguous ({', '.join(ends)})"))
    return ends[0]


def _number(text: str) -> float | None:
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def _matches(cell: str, op: str, value: str) -> bool:
    if op == "~":
        return value in cell
    if op == "=" and not value.strip():         # COLUMN= : the cell is empty
        return not cell.strip()
    a, b = _number(cell), _number(value)
    if op in "<>":
        if b is None:
            raise ResultError(f"{op}{value}: a comparison needs a number")
        return a is not None and (a < b if op == "<" else a > b)
    if a is not None and b is not None:
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)
    return cell.strip() == value.strip()


def _csv_values(rows: list[dict], inner: str, source: str, numeric: bool = True) -> list:
    column, _, where = inner.partition(" where ")
    column = _column(rows, column.strip(), source)
    selected = rows
    for item in (where.split(" and ") if where.strip() else []):
        m = _FILTER.match(item.strip())
        if m is None:
            raise ResultError(f"{source}: filter {item.strip()!r} is not COLUMN=VALUE, "
                              "COLUMN~TEXT, COLUMN<NUMBER or COLUMN>NUMBER")
        col = _column(rows, m["col"], source)
        selected = [r for r in selected if _matches(r[col], m["op"], m["value"])]
    values = [_number(r[column]) if numeric else r[column] for r in selected]
    if not values and numeric:
        raise ResultError(f"{source}: no row where {where.strip() or 'any'}")
    if numeric and any(v is None or not math.isfinite(v) for v in values):
        raise MissingValue(f"{source}: {column} is not a finite number in every selected row")
    return values


def _json_values(document: object, path: str, source: str) -> list[float]:
    nodes_ = [document]
    for key in path.strip().split("."):
        found = []
        for node in nodes_:
            if isinstance(node, list) and key.isdigit() and int(key) < len(node):
                found.append(node[int(key)])
            elif isinstance(node, dict):
                found += [node[k] for k in node if fnmatch.fnmatchcase(k, key)]
        if not found:
            raise ResultError(f"{source}: no key {key!r} on the path {path.strip()!r}")
        nodes_ = found
    values = [v for node in nodes_ for v in (node if isinstance(node, list) else [node])]
    if not values or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                             and math.isfinite(v) for v in values):
        raise ResultError(f"{source}: {path.strip()!r} is not a finite number or list of them")
    return [float(v) for v in values]


def percentile(values: list[float], p: int) -> float:
    """The ``p`` th percentile, linear between the closest ranks (NumPy's default rule)."""
    ordered = sorted(values)
    rank = (len(ordered) - 1) * p / 100.0
    lo = math.floor(rank)
    hi = min(lo + 1, len(ordered) - 1)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (rank - lo)


def resolve(spec: str, root: Path = ROOT) -> str:
    """The text a ``{result}`` role prints for ``spec`` (raises :class:`ResultError`)."""
    return resolve_with_source(spec, root)[0]


def resolve_with_source(spec: str, root: Path = ROOT) -> tuple[str, Path]:
    """The text a ``{result}`` role prints for ``spec``, and the file it read."""
    m = _SPEC.match(" ".join(spec.split()))
    if m is None:
        raise ResultError(f"{spec!r} is not SOURCE:EXPR [as FORMAT [UNIT]]")
    source, expr = m["source"], m["expr"].strip()
    fmt = m["fmt"] or ".3g"
    unit = (m["unit"] or "").strip()
    silent = unit.startswith("[") and unit.endswith("]")    # scaled, not printed
    unit = unit[1:-1].strip() if silent else unit
    if unit not in UNITS:
        raise ResultError(f"{spec!r}: unit {unit!r} is not one of {', '.join(u for u in UNITS if u)}")
    agg = None
    a = _AGG.match(expr)
    if a is not None:
        agg, expr = a["agg"], a["inner"].strip()
        if agg not in AGGREGATES and not _PERCENTILE.match(agg):
            raise ResultError(f"{spec!r}: {agg!r} is not one of {', '.join(AGGREGATES)}")
    path = source_path(source, root)
    data = load(path)
    if fmt == "text":               # a CSV cell as it is written (a variant's label)
        if agg is not None or unit or not isinstance(data, list):
            raise ResultError(f"{spec!r}: 'as text' takes one CSV cell, no aggregate or unit")
        cells = _csv_values(data, expr, source, numeric=False)
        if len(cells) != 1:
            raise ResultError(f"{spec!r}: {len(cells)} values where one was meant")
        return cells[0], path
    if isinstance(data, list):
        values = _csv_values(data, expr, source, numeric=agg != "count")
    else:
        if " where " in expr:
            raise ResultError(f"{spec!r}: 'where' applies to a CSV file only")
        values = _json_values(data, expr, source)
    if agg is None and len(values) != 1:
        raise ResultError(f"{spec!r}: {len(values)} values where one was meant "
                          "(filter further, or aggregate: " + ", ".join(AGGREGATES) + ")")
    scale = UNITS[unit]

    def fmt_one(v: float) -> str:
        try:
            return format(v * scale, fmt)
        except ValueError as exc:
            raise ResultError(f"{spec!r}: format {fmt!r}: {exc}") from None

    if agg == "count":
        text = str(len(values))
    elif agg == "range":
        lo, hi = fmt_one(min(values)), fmt_one(max(values))
        text = lo if lo == hi else f"{lo}–{hi}"
    else:
        value = values[0] if agg is None else percentile(values, int(agg[1:])) \
            if _PERCENTILE.match(agg) else {
            "min": min, "max": max, "mean": statistics.fmean,
            "median": statistics.median, "sum": math.fsum}[agg](values)
        text = fmt_one(value)
    return (f"{text} {unit}" if unit and not silent and agg != "count" else text), path


def _and_filter(expr: str, where: str) -> str:
    """``EXPR`` (``COL [where F]`` or ``AGG(COL [where F])``) with ``where`` ANDed in."""
    if not where:
        return expr
    a = _AGG.match(expr)
    inner = a["inner"].strip() if a else expr
    inner = f"{inner} and {where}" if " where " in inner else f"{inner} where {where}"
    return f"{a['agg']}({inner})" if a else inner


_CELL = re.compile(r"\{([^{}]+)\}")
_ROW_FILTER = re.compile(r"^\s*\[([^\]]*)\]\s*\|?")


def table_cells(source: str, lines: list[str], where: str = "",
                each_row: bool = False, root: Path = ROOT) -> list[list[str]]:
    """The body of a ``result-table``: ``lines`` are its rows, cells split on `` | ``; a cell's
    ``{EXPR as FORMAT UNIT}`` parts are resolved against ``source`` (anything else is text);
    ``{EXPR as FORMAT UNIT else TEXT}`` prints ``TEXT`` where the value is missing (an empty
    cell: a metric the case does not have), and only there.
    A row may start with ``[FILTER]``, ANDed (with ``where``) into each of its expressions.
    With ``each_row`` the one line is a template repeated for every file row ``where``
    selects, in the file's order."""
    if each_row:
        if len(lines) != 1:
            raise ResultError(f"{source}: :each-row: takes one template line, got {len(lines)}")
        rows = load(source_path(source, root))
        if not isinstance(rows, list):
            raise ResultError(f"{source}: :each-row: needs a CSV file")
        index = _column(rows, "index", source)
        picked = _csv_values(rows, f"{index}" + (f" where {where}" if where else ""), source)
        lines = [f"[{index}={int(i)}] {lines[0]}" for i in picked]
        where = ""
    body = []
    for line in lines:
        m = _ROW_FILTER.match(line)
        row_where = " and ".join(w for w in (where, m[1].strip() if m else "") if w)
        line = line[m.end():] if m else line
        cells = []
        for cell in line.split(" | "):
            def one(match: re.Match) -> str:
                body, has_else, fallback = match[1].partition(" else ")
                expr, sep, fmt = body.partition(" as ")
                spec = f"{source}:{_and_filter(expr.strip(), row_where)}" + (
                    f" as {fmt.strip()}" if sep else "")
                try:
                    return resolve(spec, root)
                except MissingValue:
                    if not has_else:
                        raise
                    return fallback.strip()
            cells.append(_CELL.sub(one, cell.strip()))
        body.append(cells)
    return body


#: A page's short source names, defined once in an HTML comment (hidden on a forge and on
#: the site)::
#:
#:     <!-- result sources:
#:     carry = docs/figures/run_results/contact_decentralized/metrics.json
#:     split = docs/results/paced_split.json
#:     -->
_SOURCES = re.compile(r"<!--\s*result sources:(?P<body>.*?)-->", re.S)
_ALIAS = re.compile(r"^\s*(?P<name>[A-Za-z_][\w-]*)\s*=\s*(?P<source>\S+)\s*$")
#: A role's text that carries its value: ``VALUE <SPEC>`` (the value as the page prints it).
_WRITTEN = re.compile(r"^(?P<value>[^<>:]*?)\s*<(?P<spec>[^\s<>][^:]*:.+)>\s*$", re.S)


def page_sources(text: str) -> dict[str, str]:
    """The short source names a page defines (``name = SOURCE`` lines of its
    ``<!-- result sources: ... -->`` comment); a malformed line is a :class:`ResultError`."""
    names: dict[str, str] = {}
    for block in _SOURCES.finditer(text):
        for line in block["body"].splitlines():
            if not line.strip():
                continue
            m = _ALIAS.match(line)
            if m is None:
                raise ResultError(f"result sources: {line.strip()!r} is not NAME = SOURCE")
            if m["name"] in names and names[m["name"]] != m["source"]:
                raise ResultError(f"result sources: {m['name']!r} is defined twice")
            names[m["name"]] = m["source"]
    return names


def expand(spec: str, sources: dict[str, str]) -> str:
    """``spec`` with a short source name replaced by the source it stands for."""
    source, sep, rest = spec.strip().partition(":")
    return f"{sources[source]}:{rest}" if sep and source in sources else spec


def _same(written: str, printed: str) -> bool:
    return " ".join(written.replace("\u00a0", " ").split()) == \
        " ".join(printed.replace("\u00a0", " ").split())


def check_written(text: str, sources: dict[str, str] | None = None,
                  root: Path = ROOT) -> tuple[str, Path]:
    """The value a role's ``text`` prints and the file it read.

    ``text`` is ``VALUE <SPEC>`` (the value written beside its source, so that the page read
    as plain Markdown, on a forge, shows the number) or a bare ``SPEC``. ``SPEC`` is resolved
    (:func:`resolve_with_source`, a short name of ``sources`` expanded first) and must print
    ``VALUE`` exactly (spaces aside): a written value its file no longer gives is a
    :class:`ResultError` naming both (``python docs/_ext/results_role.py --write PAGE``
    rewrites the values from the files).
    """
    m = _WRITTEN.match(text)
    spec = m["spec"] if m else text
    printed, path = resolve_with_source(expand(spec, sources or {}), root)
    if m is not None and not _same(m["value"], printed):
        raise ResultError(f"written {m['value'].strip()!r}, the file gives {printed!r} "
                          f"({spec.strip()})")
    return printed, path


@lru_cache(maxsize=256)
def _page_sources_cached(path: str, stamp: int) -> dict[str, str]:
    return page_sources(Path(path).read_text(encoding="utf-8"))


def result_role(name, rawtext, text, lineno, inliner, options=None, content=None):
    """Docutils role: ``{result}`VALUE <SOURCE:EXPR as FORMAT UNIT>``` (or without the
    written ``VALUE``); ``SOURCE`` may be a short name the page defines."""
    env = getattr(inliner.document.settings, "env", None)
    root = Path(env.config.results_root) if env is not None and env.config.results_root \
        else ROOT
    try:
        page = Path(inliner.document["source"]) if inliner.document.get("source") else None
        sources = _page_sources_cached(str(page), page.stat().st_mtime_ns) \
            if page is not None and page.is_file() else {}
        value, path = check_written(text, sources, root)
    except ResultError as exc:
        msg = inliner.reporter.error(f"{{result}} role: {exc}", line=lineno)
        return [inliner.problematic(rawtext, rawtext, msg)], [msg]
    if env is not None:             # a re-run study's results.csv re-reads the page
        env.note_dependency(str(path))
    node = nodes.inline(rawtext, value.replace(" ", "\u00a0", 1) if " " in value else value,
                        classes=["result"])
    return [node], []


class ResultTable(Directive):
    """``result-table``: a table whose numbers are read from a results file.

    ::

        ```{result-table} object_carry
        :header: object model | λ − λ_d RMS, median / max (N)
        :where: robots.*~mass_scale=1.1
        [object_model=mode=none] `none` | {median(worst.force_error.rms) as .3g} / {max(worst.force_error.rms) as .3g}
        ```

    ``:header:`` names the columns (`` | ``-separated), ``:where:`` filters every expression,
    ``:each-row:`` repeats the one template line for each selected file row.
    """

    required_arguments = 1
    has_content = True
    option_spec = {"header": directives.unchanged_required, "where": directives.unchanged,
                   "each-row": directives.flag}

    def run(self):
        source = self.arguments[0]
        header = [h.strip() for h in self.options["header"].split(" | ")]
        lines = [line for line in self.content if line.strip()]
        env = self.state.document.settings.env
        root = Path(env.config.results_root) if env.config.results_root else ROOT
        try:
            body = table_cells(source, lines, " ".join(self.options.get("where", "").split()),
                               "each-row" in self.options, root)
            width = {len(row) for row in body} | {len(header)}
            if len(width) != 1:
                raise ResultError(f"{source}: rows of {sorted(width)} cells under a header of "
                                  f"{len(header)}")
            env.note_dependency(str(source_path(source, root)))
        except ResultError as exc:
            raise self.error(f"result-table: {exc}") from None
        table = nodes.table(classes=["result-table"])
        group = nodes.tgroup(cols=len(header))
        table += group
        group += [nodes.colspec(colwidth=1) for _ in header]
        thead, tbody = nodes.thead(), nodes.tbody()
        group += thead
        group += tbody
        for cells, parent in [(header, thead)] + [(row, tbody) for row in body]:
            row = nodes.row()
            for text in cells:
                entry = nodes.entry()
                inline, messages = self.state.inline_text(text, self.lineno)
                entry += nodes.paragraph("", "", *inline)
                entry += messages
                row += entry
            parent += row
        return [table]


def setup(app):
    app.add_config_value("results_root", "", "env")     # "" : the repository's root
    app.add_role("result", result_role)
    app.add_directive("result-table", ResultTable)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}


# --- Writing the values into the pages --------------------------------------------------------

#: A role in a page's Markdown source.
ROLE = re.compile(r"\{result\}`([^`]*)`")
#: A number written in plain Markdown beside its source, for a page no role renders (the
#: README, a forge's landing page): ``0.83 ms<!-- result: split:... as .2f ms -->``.
COMMENTED = re.compile(r"(?P<value>[-−+]?\d[^\s<>]*(?:[ \u00a0][^\s<>\d][^\s<>]*)?)"
                       r"<!--\s*result:\s*(?P<spec>.+?)\s*-->", re.S)


def _short_name(source: str, taken: dict[str, str]) -> str:
    """A short name for a path source: its run's folder (``…/contact/metrics.json``) or the
    file's stem, made unique on the page."""
    path = Path(source)
    stem = path.parent.name if path.name in ("metrics.json", "results.csv") else path.stem
    stem = re.sub(r"\W+", "_", stem).strip("_") or "src"
    name, n = stem, 2
    while name in taken and taken[name] != source:
        name, n = f"{stem}{n}", n + 1
    return name


def write_values(text: str, root: Path = ROOT, shorten: bool = False) -> str:
    """``text`` (a page's Markdown) with each role's written value set to what its file
    gives: ``{result}`SPEC``` becomes ``{result}`VALUE <SPEC>```. With ``shorten``, path
    sources are replaced by short names, defined in the page's ``result sources`` comment
    (added after the page's title)."""
    sources = page_sources(text)
    inverse = {v: k for k, v in sources.items()}

    def one(match: re.Match) -> str:
        m = _WRITTEN.match(match[1])
        spec = " ".join((m["spec"] if m else match[1]).split())
        source, sep, rest = spec.partition(":")
        if shorten and sep and source.endswith((".csv", ".json")) and source not in sources:
            name = inverse.get(source) or _short_name(source, sources)
            sources[name], inverse[source] = source, name
            spec = f"{name}:{rest}"
        printed, _ = resolve_with_source(expand(spec, sources), root)
        return f"{{result}}`{printed} <{spec}>`"

    out = ROLE.sub(one, text)
    out = COMMENTED.sub(lambda m: f"{resolve(expand(m['spec'], sources), root)}"
                        f"<!-- result: {m['spec']} -->", out)
    old = page_sources(text)
    if sources != old:
        block = "<!-- result sources:\n" + "".join(
            f"{k} = {v}\n" for k, v in sorted(sources.items())) + "-->\n"
        if _SOURCES.search(out):
            out = _SOURCES.sub(block.rstrip("\n"), out, count=1)
        else:
            lines = out.split("\n")
            at = next((i + 1 for i, line in enumerate(lines) if line.startswith("# ")), 0)
            lines[at:at] = ["", block.rstrip("\n")] if at else [block.rstrip("\n"), ""]
            out = "\n".join(lines)
    return out


_TABLE = re.compile(r"^(`{3,})\{result-table\}\s+(\S+)\s*\n(.*?)^\1\s*$", re.S | re.M)


def tables_to_markdown(text: str, root: Path = ROOT) -> str:
    """``text`` with each ``result-table`` directive written out as a Markdown table whose
    numbers are ``{result}`VALUE <SPEC>``` roles (a forge shows a directive as code; it
    shows this table with its numbers). A cell whose value is missing prints its ``else``
    text."""
    sources = page_sources(text)
    inverse = {v: k for k, v in sources.items()}

    def one(match: re.Match) -> str:
        source = match[2]
        if source.endswith((".csv", ".json")):
            name = inverse.get(source) or _short_name(source, sources)
            sources[name], inverse[source] = source, name
        else:
            name = source
        options, lines = {}, []
        for line in match[3].splitlines():
            opt = re.match(r"^:([\w-]+):\s*(.*)$", line)
            if opt and not lines:
                options[opt[1]] = opt[2]
            elif line.strip():
                lines.append(line)
        where = " ".join(options.get("where", "").split())
        if "each-row" in options:
            rows = load(source_path(source, root))
            index = _column(rows, "index", source)
            picked = _csv_values(rows, f"{index}" + (f" where {where}" if where else ""),
                                 source)
            lines = [f"[{index}={int(i)}] {lines[0]}" for i in picked]
            where = ""
        header = [h.strip() for h in options["header"].split(" | ")]
        out = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
        for line in lines:
            m = _ROW_FILTER.match(line)
            row_where = " and ".join(w for w in (where, m[1].strip() if m else "") if w)
            line = line[m.end():] if m else line

            def cell(c: re.Match) -> str:
                body, has_else, fallback = c[1].partition(" else ")
                expr, sep, fmt = body.partition(" as ")
                spec = f"{name}:{_and_filter(expr.strip(), row_where)}" + (
                    f" as {fmt.strip()}" if sep else "")
                try:
                    printed = resolve(expand(spec, sources), root)
                except MissingValue:
                    if not has_else:
                        raise
                    return fallback.strip()
                return f"{{result}}`{printed} <{spec}>`"
            out.append("| " + " | ".join(_CELL.sub(cell, c.strip())
                                         for c in line.split(" | ")) + " |")
        return "\n".join(out) + "\n"

    out = _TABLE.sub(one, text)
    if sources != page_sources(text):
        block = "<!-- result sources:\n" + "".join(
            f"{k} = {v}\n" for k, v in sorted(sources.items())) + "-->"
        if _SOURCES.search(out):
            out = _SOURCES.sub(block, out, count=1)
        else:
            lines = out.split("\n")
            at = next((i + 1 for i, line in enumerate(lines) if line.startswith("# ")), 0)
            lines[at:at] = ["", block]
            out = "\n".join(lines)
    return out


def main(argv: list[str] | None = None) -> int:
    """``python docs/_ext/results_role.py [--write] [--shorten] PAGE ...``: list (or, with
    ``--write``, rewrite) each role whose written value differs from its file's."""
    import argparse

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("pages", nargs="+", type=Path)
    parser.add_argument("--write", action="store_true", help="rewrite the pages in place")
    parser.add_argument("--shorten", action="store_true",
                        help="give path sources short names defined once per page")
    parser.add_argument("--tables", action="store_true",
                        help="write result-table directives out as Markdown tables of roles")
    args = parser.parse_args(argv)
    stale = 0
    for page in args.pages:
        text = page.read_text(encoding="utf-8")
        new = tables_to_markdown(text) if args.tables else text
        new = write_values(new, shorten=args.shorten)
        if new != text:
            stale += 1
            print(f"{page}: values or names to update")
            if args.write:
                page.write_text(new, encoding="utf-8")
    return 1 if stale and not args.write else 0


if __name__ == "__main__":
    raise SystemExit(main())
