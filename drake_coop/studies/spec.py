"""Study file: typed dataclasses of a parameter study, YAML loading and validation.

A study file is YAML with these top-level keys (all optional except that a study needs at
least one ``grid`` entry or a ``monte_carlo`` block)::

    name: h_sweep                  # default: the file's stem
    base: ../scenarios/paper.yaml  # scenario file (relative to the study file) or inline
                                   # mapping; default: the paper's scenario
    t_end: 35.0                    # stop every case here (s); default: the scenario's t_end
    grid:                          # dotted scenario paths -> lists of values (Cartesian product)
      control_period: [0.003, 0.009]
      robots.*.gains.k_d: [20, 40, 80]
      # base: [../scenarios/two_pandas.yaml, ../scenarios/two_ur5.yaml]   # an axis of base
      #                            # scenario files instead of the top-level base (see below)
    monte_carlo:                   # n random samples per grid point
      n: 50
      seed: 1
      perturb:
        robots.*.gains.K_R: {scale_uniform: [0.9, 1.1]}
    phase: circle                  # phase whose metrics go into results.csv and the plots
    metrics: [worst.force_error.rms, worst.position_error.max]   # plotted columns
    guides:                        # straight lines y = slope x + intercept on the 2-D maps
      - {label: "(26), robot 1", slope: 0.639, intercept: 0}

A study file is read as a scenario file is (:mod:`drake_coop.scenario.safe_yaml`): at most
1 MB of strict UTF-8, aliases bounded, duplicate keys refused; so is a ``base:`` file. The
``name`` is 1 to 100 printable characters; it becomes part of file names only through
:func:`file_stem`. Every problem is a :class:`StudyError` whose message starts with the
field's dotted name, e.g. ``grid.robots.0.gains.k_x: no such field``.

A grid axis ``base`` (the key :data:`BASE_AXIS`) lists base scenario files instead of the
top-level ``base`` (which it then replaces: giving both is refused): every other grid value
and every Monte Carlo draw is applied to each of them, so one study runs the same variants on
several arm sets. Each file is read as a top-level ``base:`` file is (relative to the study
file); its text, as written in the grid, is the axis's value in ``results.csv``. Paths
resolve against each base on its own (``robots.*`` matches the arms each base has), and the
draws are the same on every base when the perturbed paths match alike (``plant.object_mass``:
paired draws across the arm sets).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["BASE_AXIS", "DISTRIBUTIONS", "Guide", "MonteCarlo", "Perturbation", "Study", "StudyError",
           "file_stem", "load_study"]

#: Monte Carlo distributions: name -> meaning of its two parameters ``[a, b]``.
DISTRIBUTIONS = {
    "uniform": "[lo, hi]: value ~ U(lo, hi)",
    "normal": "[mean, std]: value ~ N(mean, std^2)",
    "scale_uniform": "[lo, hi]: value = base value * U(lo, hi)",
}
PHASES = ("free", "lift", "circle", "put_down", "return", "all")
#: The grid key whose values are base scenario files (see the module's docstring).
BASE_AXIS = "base"
#: Most files on the ``base`` axis.
MAX_BASES = 20
_TOP_KEYS = ("name", "description", "base", "t_end", "grid", "monte_carlo", "phase", "metrics",
             "guides")


class StudyError(ValueError):
    """A study file field is missing, of the wrong type, or out of its allowed range."""


@dataclass
class Perturbation:
    """One Monte Carlo perturbation: ``path`` drawn from ``distribution(a, b)``.

    Attributes
    ----------
    path : str
        Dotted scenario path; a ``*`` draws independently for every element it matches.
    distribution : str
        A key of :data:`DISTRIBUTIONS`.
    a, b : float
        Its two parameters (``lo, hi`` or ``mean, std``).
    """

    path: str
    distribution: str
    a: float
    b: float


@dataclass
class MonteCarlo:
    """``n`` samples drawn with ``numpy.random.default_rng(seed)``.

    Attributes
    ----------
    n : int
        The samples per grid point.
    seed : int
        The generator's seed.
    perturb : list of Perturbation
        The perturbations.
    """

    n: int
    seed: int
    perturb: list[Perturbation] = field(default_factory=list)


@dataclass
class Guide:
    """A line ``y = slope x + intercept`` drawn on every 2-D map (e.g. condition (26)).

    Attributes
    ----------
    label : str
        Its legend.
    slope : float
        In the map's axes' units.
    intercept : float
        In the vertical axis's unit.
    """

    label: str
    slope: float
    intercept: float = 0.0


@dataclass
class Study:
    """A parsed, structurally valid study (its scenarios are checked by expansion).

    Attributes
    ----------
    name : str
        The study's name (its figures' file names).
    description : str
        What the study shows, one paragraph.
    base_yaml : str or None
        The base scenario as YAML text; None means the paper's scenario.
    bases : dict[str, str]
        With a ``base`` grid axis: each of its values (the file as written) -> that base
        scenario's YAML text; empty without one.
    t_end : float or None
        Simulation stop of every case (s).
    grid : dict[str, list]
        Dotted path -> values, in file order.
    monte_carlo : MonteCarlo or None
        The samples per grid point; None for one (the base scenario's values).
    phase : str
        Phase of the summary metrics (``circle`` by default).
    metrics : list[str]
        Summary columns to plot.
    guides : list[Guide]
        Lines drawn on every 2-D map.
    """

    name: str
    description: str = ""
    base_yaml: str | None = None
    bases: dict[str, str] = field(default_factory=dict)
    t_end: float | None = None
    grid: dict[str, list] = field(default_factory=dict)
    monte_carlo: MonteCarlo | None = None
    phase: str = "circle"
    metrics: list[str] = field(default_factory=lambda: [
        "worst.position_error.max", "worst.force_error.rms", "worst.estimate_error.rms"])
    guides: list[Guide] = field(default_factory=list)


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise StudyError(f"{where}: must be a finite number, got {value!r}")
    return float(value)


def _integer(value, where: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise StudyError(f"{where}: must be an integer >= {minimum}, got {_short(value)}")
    return value


def _perturbation(path: str, spec, where: str) -> Perturbation:
    if not isinstance(spec, dict) or len(spec) != 1:
        raise StudyError(f"{where}: must be one of {{uniform: [lo, hi]}}, {{normal: [mean, "
                         f"std]}}, {{scale_uniform: [lo, hi]}}, got {spec!r}")
    (kind, params), = spec.items()
    if kind not in DISTRIBUTIONS:
        raise StudyError(f"{where}: unknown distribution {kind!r}; allowed: "
                         f"{', '.join(DISTRIBUTIONS)}")
    if not isinstance(params, list) or len(params) != 2:
        raise StudyError(f"{where}.{kind}: must be a list of 2 numbers "
                         f"{DISTRIBUTIONS[kind].split(':')[0]}, got {params!r}")
    a, b = (_number(p, f"{where}.{kind}") for p in params)
    if kind == "normal" and b < 0:
        raise StudyError(f"{where}.normal: std must be >= 0, got {b}")
    if kind != "normal" and b < a:
        raise StudyError(f"{where}.{kind}: needs lo <= hi, got [{a}, {b}]")
    return Perturbation(path=path, distribution=kind, a=a, b=b)


def _monte_carlo(data) -> MonteCarlo:
    if not isinstance(data, dict):
        raise StudyError(f"monte_carlo: must be a mapping with n, seed, perturb; got {data!r}")
    for key in data:
        if key not in ("n", "seed", "perturb"):
            raise StudyError(f"monte_carlo.{key}: no such field; allowed: n, seed, perturb")
    if "n" not in data or "seed" not in data:
        raise StudyError("monte_carlo: needs n (samples) and seed (integer)")
    n = _integer(data["n"], "monte_carlo.n", 1)
    seed = _integer(data["seed"], "monte_carlo.seed", 0)
    perturb = data.get("perturb") or {}
    if not isinstance(perturb, dict) or not perturb:
        raise StudyError("monte_carlo.perturb: must map scenario paths to distributions")
    for p in perturb:
        if not isinstance(p, str) or not 0 < len(p) <= 200:
            raise StudyError(f"monte_carlo.perturb: a key must be a dotted scenario path, got "
                             f"{_short(p)}")
    return MonteCarlo(n=n, seed=seed, perturb=[
        _perturbation(p, s, f"monte_carlo.perturb.{p}") for p, s in perturb.items()])


def _base_yaml(base, folder: Path) -> str | None:
    from pydrake.common.yaml import yaml_dump

    from drake_coop.scenario.safe_yaml import YamlInputError, read_text_file

    if base is None:
        return None
    if isinstance(base, dict):
        return yaml_dump(base)
    if isinstance(base, str) and 0 < len(base) <= 4096 and "\0" not in base:
        path = Path(base) if Path(base).is_absolute() else folder / base
        if not path.exists():
            raise StudyError(f"base: scenario file not found: {path}")
        try:
            text = read_text_file(path, "scenario file")
        except YamlInputError as exc:
            raise StudyError(f"base: {exc}") from None
        if _is_empty(text):     # never the paper's scenario in its place
            raise StudyError(f"base: the scenario file {_short(str(path), 200)} is empty (0 "
                             "bytes, blanks or comments only): it must be a mapping of fields")
        return _models_beside(text, path.resolve().parent)
    raise StudyError(f"base: must be a scenario file path or an inline scenario, got "
                     f"{_short(base)}")


def _is_empty(text: str) -> bool:
    """Whether a scenario file's text holds no YAML document (0 bytes, blanks, comments)."""
    from drake_coop.scenario.loading import _load_untyped
    from drake_coop.scenario.schema import ScenarioError

    try:
        return _load_untyped(text) is None
    except ScenarioError:
        return False                     # not empty: the scenario's own checks report it


def _bases(values: list, top, folder: Path) -> dict[str, str]:
    """The ``base`` grid axis: each file as written -> its scenario YAML text."""
    where = f"grid.{BASE_AXIS}"
    if top is not None:
        raise StudyError(f"{where}: the grid's base files replace the top-level base; give "
                         "one or the other, not both")
    if len(values) > MAX_BASES:
        raise StudyError(f"{where}: at most {MAX_BASES} base scenario files, got {len(values)}")
    bases: dict[str, str] = {}
    for value in values:
        if not isinstance(value, str) or not value.endswith((".yaml", ".yml")):
            raise StudyError(f"{where}: each value must be a scenario file path (.yaml, "
                             f"relative to the study file), got {_short(value)}")
        if value in bases:
            raise StudyError(f"{where}: {value!r} is listed twice")
        try:
            bases[value] = _base_yaml(value, folder)
        except StudyError as exc:
            raise StudyError(f"{where} = {value!r}: {str(exc).removeprefix('base: ')}") from None
    return bases


def _models_beside(text: str, folder: Path) -> str:
    """A base file's text with each robot's relative ``model`` / ``controller_model`` URDF
    that lies beside the file made absolute, as ``drake-coop run`` finds it
    (:func:`~drake_coop.scenario.resources.resolve_models`; e.g. the ``identified.yaml`` that
    ``drake-coop identify`` writes beside its URDFs); the text unchanged when none does."""
    from pydrake.common.yaml import yaml_dump

    from drake_coop.scenario.loading import _load_untyped
    from drake_coop.scenario.resources import MODEL_FIELDS, model_beside
    from drake_coop.scenario.schema import ScenarioError

    try:
        data = _load_untyped(text)
    except ScenarioError:
        return text                      # the scenario's own checks report it
    robots = data.get("robots") if isinstance(data, dict) else None
    changed = False
    for robot in robots if isinstance(robots, list) else []:
        for key in MODEL_FIELDS:
            beside = model_beside(robot.get(key), folder) if isinstance(robot, dict) else None
            if beside is not None:
                robot[key] = beside
                changed = True
    return yaml_dump(data) if changed else text


def _short(value, n: int = 80) -> str:
    text = " ".join(repr(value).split())
    return text if len(text) <= n else text[:n] + "…"


#: Longest study name (characters); names become file names only after :func:`file_stem`.
MAX_NAME = 100


def _name(value, where: str = "name") -> str:
    if not isinstance(value, (str, int, float)) or isinstance(value, bool):
        raise StudyError(f"{where}: must be a text of 1 to {MAX_NAME} characters, got "
                         f"{_short(value)}")
    text = str(value)
    if not 0 < len(text) <= MAX_NAME or not text.isprintable():
        raise StudyError(f"{where}: must be 1 to {MAX_NAME} printable characters (no control "
                         f"characters), got {_short(text)}")
    return text


def file_stem(name: str) -> str:
    """A study name as a file name part: letters, digits, ``-``, ``_`` and ``.`` kept, any
    other run of characters one ``_``, no leading dot, at most :data:`MAX_NAME` characters
    (``study`` when nothing is left). Never a path: ``../x`` gives ``x``.

    Parameters
    ----------
    name : str
        The study's name.
    """
    import re

    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("._")[:MAX_NAME].rstrip("._")
    return stem or "study"


def load_study(path: str | Path | None = None, *, data: str | None = None,
               folder: str | Path = ".") -> Study:
    """Parse a study file (or YAML text with relative paths taken from ``folder``).

    Parameters
    ----------
    path : str or Path, optional
        The study file (its folder resolves the relative paths).
    data : str, optional
        The study's YAML text instead of a file.
    folder : str or Path
        Where the relative paths of ``data`` are taken from (default: the working
        folder).

    Returns
    -------
    Study
        The study.

    Raises
    ------
    StudyError
        With a one-line message starting with the offending field's name.
    """
    from drake_coop.scenario.safe_yaml import (
        MAX_BYTES,
        YamlInputError,
        load_untrusted,
        read_text_file,
    )

    name = "study"
    try:
        if path is not None:
            path = Path(path)
            data, folder, name = read_text_file(path, "study file"), path.parent, path.stem
        elif data is not None and len(data) > MAX_BYTES:
            raise YamlInputError(f"study text is longer than {MAX_BYTES} characters")
        raw = load_untrusted(data or "")
    except YamlInputError as exc:
        raise StudyError(str(exc)) from None
    if not isinstance(raw, dict):
        raise StudyError(f"study: must be a mapping of fields ({', '.join(_TOP_KEYS)})")
    for key in raw:
        if key not in _TOP_KEYS:
            shown = key if isinstance(key, str) and len(key) <= 60 and key.isprintable() \
                else _short(key, 60)
            raise StudyError(f"{shown}: no such field; allowed: "
                             f"{', '.join(_TOP_KEYS)}")
    description = raw.get("description", "")
    if not isinstance(description, (str, int, float)) or len(str(description)) > 2000:
        raise StudyError("description: must be a text of at most 2000 characters")
    study = Study(name=_name(raw["name"]) if "name" in raw else _name(name, "the file name"),
                  description=str(description))
    study.base_yaml = _base_yaml(raw.get("base"), Path(folder))
    if raw.get("t_end") is not None:
        from drake_coop.control.params import PERIOD_RANGE

        study.t_end = _number(raw["t_end"], "t_end")
        if study.t_end < PERIOD_RANGE[0]:     # shorter than any control period: no run
            raise StudyError(f"t_end: must be at least {PERIOD_RANGE[0]:g} s (one control "
                             f"period at the least), got {study.t_end:g}")
    grid = raw.get("grid") or {}
    if not isinstance(grid, dict):
        raise StudyError(f"grid: must map scenario paths to lists of values, got {grid!r}")
    for key, values in grid.items():
        if not isinstance(key, str) or not 0 < len(key) <= 200:
            raise StudyError(f"grid: a key must be a dotted scenario path, got {_short(key)}")
        if not isinstance(values, list) or not values:
            raise StudyError(f"grid.{key}: must be a non-empty list of values, got "
                             f"{_short(values)}")
        study.grid[key] = values
    if BASE_AXIS in study.grid:
        study.bases = _bases(study.grid[BASE_AXIS], raw.get("base"), Path(folder))
    if raw.get("monte_carlo") is not None:
        study.monte_carlo = _monte_carlo(raw["monte_carlo"])
    if not study.grid and study.monte_carlo is None:
        raise StudyError("grid: a study needs a grid, a monte_carlo block, or both")
    study.phase = raw.get("phase", study.phase)
    if study.phase not in PHASES:
        raise StudyError(f"phase: must be one of {', '.join(PHASES)}, got "
                         f"{_short(study.phase)}")
    if "metrics" in raw:
        metrics = raw["metrics"]
        if not isinstance(metrics, list) or not 0 < len(metrics) <= 20 or not all(
                isinstance(m, str) and len(m) <= 100 for m in metrics):
            raise StudyError(f"metrics: must be a non-empty list of column names, got "
                             f"{metrics!r}")
        study.metrics = list(metrics)
    guides = raw.get("guides") or []
    if not isinstance(guides, list) or len(guides) > 20:
        raise StudyError(f"guides: must be a list of at most 20 lines, got {_short(guides)}")
    for i, g in enumerate(guides):
        where = f"guides.{i}"
        if not isinstance(g, dict) or not {"label", "slope"} <= set(g) or not set(g) <= {
                "label", "slope", "intercept"}:
            raise StudyError(f"{where}: must be {{label, slope, intercept}}, got {g!r}")
        study.guides.append(Guide(label=_name(g["label"], f"{where}.label"), slope=_number(g["slope"], where),
                                  intercept=_number(g.get("intercept", 0.0), where)))
    return study
