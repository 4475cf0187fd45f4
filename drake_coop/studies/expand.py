"""Expansion of a study into cases: dotted paths, grid product, Monte Carlo draws, case hashes.

Paths
-----
The dotted paths naming scenario fields (``robots.0.gains.k_d``, ``*`` for every element) and
how a value is set at one are :mod:`drake_coop.studies.paths`'s.

Order of application (overlapping paths)
----------------------------------------
A case starts from the base scenario; the grid values are set in file order, then the Monte
Carlo draws in the order of ``perturb`` (file order), each matched element in turn. A later
path overrides what an earlier one set on the same element, and ``scale_uniform`` multiplies
the value the element has *at that moment* (the grid's value, or an earlier draw's). So with
``robots.*.gains.K_R: {scale_uniform: [0.9, 1.1]}`` followed by
``robots.0.gains.K_R.*: {uniform: [80, 160]}``, robot 0's three gains are the uniform draws
(robot 1's the scaled list). The values written into ``results.csv`` and ``study.json``
(:attr:`Case.values`) are read back from the case's resolved scenario, so they are the values
the case ran with whatever the overlap.

Bases
-----
A grid axis ``base`` (:data:`~drake_coop.studies.spec.BASE_AXIS`: base scenario files, see
:mod:`~drake_coop.studies.spec`) picks each case's base scenario; the other paths resolve,
and the other values and the draws apply, on that base. The Monte Carlo draws are made per
base from the same seed, so a path matched alike on every base (``plant.friction``) gets the
same draws on every base (paired); ``robots.*`` draws follow each base's arm count.

Cases
-----
Grid points are the Cartesian product of the grid's lists (first key outermost); each grid point
is combined with every Monte Carlo sample ``i = 0 … n−1`` (the same draws at every grid point:
common random numbers). Draws come from ``numpy.random.default_rng(seed)`` in the order
sample, perturbation (file order), matched element. A case is identified by the SHA-256 of its
validated scenario (every field, as canonical JSON) and the study's ``t_end``.

Size and validation
-------------------
The number of cases (grid points × samples) is computed from the study before anything is
expanded and refused above ``max_cases`` (:data:`MAX_CASES` unless raised on purpose). Every
case is validated as ``drake-coop run`` validates its scenario (the field checks of
:func:`~drake_coop.scenario.validation.validate` and the run size of
:func:`~drake_coop.experiment.ticks.check_run_size` at the study's ``t_end``). Numbers and lists
of numbers are set on a copy of the validated base :class:`~drake_coop.scenario.Scenario`
(converted as the YAML loader converts them), other values (variants, texts, ``null``) go
through the scenario's YAML loading; the reachability check, which reads only the task and the
arms' geometry, is shared between cases with the same geometry. 10 000 cases validate in
seconds (see ``docs/studies.md``).
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import itertools
import json
import math
import re
import typing
from dataclasses import is_dataclass

import numpy as np

from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.schema import Scenario, ScenarioError
from drake_coop.studies.paths import (
    KeyPath,
    _hints,
    _unwrap_optional,
    get_value,
    resolve,
    set_value,
)
from drake_coop.studies.spec import BASE_AXIS, Perturbation, Study, StudyError, _short

__all__ = ["MAX_CASES", "Case", "case_hash", "draw", "expand", "study_size"]


#: Largest number of cases (grid points × Monte Carlo samples) of a study unless raised on
#: purpose (``drake-coop study --max-cases``).
MAX_CASES = 10_000


class Case:
    """One run of a study.

    Parameters
    ----------
    index, params, hash
        As the attributes below.
    scenario_yaml : str, optional
        The canonical, validated scenario; None: written from ``scenario`` when first needed.
    values : dict, optional
        As below; default: ``params``.
    scenario : Scenario, optional
        The resolved scenario, when ``scenario_yaml`` is not given.

    Attributes
    ----------
    index : int
        Position in the expansion order.
    params : dict
        What identifies the case in the study: grid path -> the grid's value, and for Monte
        Carlo ``sample`` (the figures group cases by these).
    values : dict
        The values the case ran with, read from its resolved scenario: every grid path and
        every concrete Monte Carlo path -> its value (a list when a ``*`` path's elements
        differ). ``results.csv`` shows these.
    scenario_yaml : str
        The canonical, validated scenario (written when first needed).
    hash : str
        16 hex digits of SHA-256 over the validated scenario and ``t_end``.
    """

    __slots__ = ("index", "params", "values", "hash", "_yaml", "_scenario")

    def __init__(self, index: int, params: dict, scenario_yaml: str | None = None,
                 hash: str = "", values: dict | None = None, scenario: Scenario | None = None):
        self.index, self.params, self.hash = index, params, hash
        self.values = dict(params) if values is None else values
        self._yaml, self._scenario = scenario_yaml, scenario

    @property
    def scenario_yaml(self) -> str:
        """The case's validated scenario as YAML text (dumped once, on first use)."""
        if self._yaml is None:
            self._yaml = dump_scenario(self._scenario)
            self._scenario = None
        return self._yaml

    def __repr__(self) -> str:
        return f"Case(index={self.index}, hash={self.hash!r}, params={self.params!r})"


#: Robot fields added as opt-ins after cases were stored: at their null default (off) they
#: change nothing in a run and are left out of :func:`case_hash`, so a stored case keeps the
#: hash it had before the field existed.
HASH_OMITS_NULL = ("anti_windup", "anti_windup_gain")


def case_hash(scenario: Scenario | str, t_end: float | None) -> str:
    """16 hex digits of SHA-256 over the validated scenario (every field but those of
    :data:`HASH_OMITS_NULL` at null, canonical JSON) and the study's ``t_end``; ``scenario``
    may also be its YAML text (loaded and validated).

    Parameters
    ----------
    scenario : Scenario or str
        The scenario, or its YAML text.
    t_end : float or None
        The study's ``t_end``, s.
    """
    if isinstance(scenario, str):
        scenario = load_scenario(data=scenario)
    data = dataclasses.asdict(scenario)
    for robot in data["robots"]:
        for name in HASH_OMITS_NULL:
            if robot.get(name) is None:
                robot.pop(name, None)
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    text += f"\n# t_end: {t_end!r}\n"
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def draw(p: Perturbation, base, rng: np.random.Generator):
    """One Monte Carlo value of ``p``: uniform ``U(a, b)``, normal ``N(a, b²)``, or
    ``base * U(a, b)`` for ``scale_uniform`` (element-wise on a list base, one factor).

    Parameters
    ----------
    p : Perturbation
        The perturbation.
    base : float or list of float
        The base scenario's value.
    rng : numpy.random.Generator
        The study's generator.
    """
    if p.distribution == "uniform":
        return float(rng.uniform(p.a, p.b))
    if p.distribution == "normal":
        return float(rng.normal(p.a, p.b))
    return _scaled(base, float(rng.uniform(p.a, p.b)))


def _scaled(base, factor: float):
    if isinstance(base, list):
        return [float(v) * factor for v in base]
    return float(base) * factor


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _numeric(value) -> bool:
    return _is_number(value) or (isinstance(value, list) and all(map(_is_number, value)))


def study_size(study: Study) -> tuple[int, int, int]:
    """``(cases, grid points, samples)`` of a study, computed without expanding it.

    Parameters
    ----------
    study : Study
        The study.
    """
    points = math.prod(len(v) for v in study.grid.values())
    samples = study.monte_carlo.n if study.monte_carlo is not None else 1
    return points * samples, points, samples


# --- building one case: an assignment is (key path, operation, value) ------------------------
# operation "set": the value; "scale": multiply the current value by the factor.

Assignment = tuple[KeyPath, str, object]

_SLOW = object()     # "this value needs the YAML loading"


def _coerce(schema, old, value):
    """``value`` converted as ``yaml_load_typed`` converts it for a field of type ``schema``
    (numbers and lists of numbers only), or ``_SLOW``."""
    schema = _unwrap_optional(schema)
    if value is None:                       # null: the loader decides (Optional or not)
        return _SLOW
    if schema is float and _is_number(value):
        try:
            return float(value)
        except OverflowError:
            return _SLOW
    if schema is int and isinstance(value, int) and not isinstance(value, bool):
        return value
    if typing.get_origin(schema) is list and typing.get_args(schema) == (float,):
        if isinstance(value, list) and all(map(_is_number, value)):
            items = value
        elif _is_number(value) and isinstance(old, list):
            items = [value] * len(old)          # broadcast, as set_value does
        else:
            return _SLOW
        try:
            return [float(v) for v in items]
        except OverflowError:
            return _SLOW
    return _SLOW


def _walk_object(scenario: Scenario, keys: KeyPath):
    """(parent node, field type, current value) of a key path in a Scenario, or None."""
    node, schema = scenario, Scenario
    for k in keys[:-1]:
        schema = _unwrap_optional(schema)
        if is_dataclass(schema):
            schema, node = _hints(schema)[k], getattr(node, k)
        else:
            (schema,) = typing.get_args(schema)
            node = node[k]
        if node is None:
            return None
    schema, last = _unwrap_optional(schema), keys[-1]
    if is_dataclass(schema):
        return node, _hints(schema)[last], getattr(node, last)
    (item,) = typing.get_args(schema)
    return node, item, node[last]


def _apply_object(scenario: Scenario, assignments: list[Assignment]) -> bool:
    """Apply the assignments to a Scenario in place; False if one needs the YAML loading."""
    for keys, op, value in assignments:
        found = _walk_object(scenario, keys)
        if found is None:
            return False
        node, schema, old = found
        if op == "scale":
            if not _numeric(old):
                return False
            value = _scaled(old, value)
        new = _coerce(schema, old, value)
        if new is _SLOW:
            return False
        if isinstance(keys[-1], int):
            node[keys[-1]] = new
        else:
            setattr(node, keys[-1], new)
    return True


def _apply_dict(data: dict, assignments: list[Assignment], where: str) -> None:
    for keys, op, value in assignments:
        if op == "scale":
            old = get_value(data, keys)
            if not _numeric(old):
                raise StudyError(f"{where}: scale_uniform needs a numeric value at "
                                 f"{'.'.join(map(str, keys))}, got {old!r}")
            value = _scaled(old, value)
        set_value(data, keys, value)


def _read(scenario: Scenario, keys: KeyPath, spec):
    """The value at ``keys`` in the scenario; for a variant, the fields it names."""
    if isinstance(spec, dict):
        return {k: _read(scenario, keys + (k,), v) for k, v in spec.items()}
    node = scenario
    for k in keys:
        node = node[k] if isinstance(k, int) else getattr(node, k, None)
        if node is None:
            return None
    if is_dataclass(node):
        return dataclasses.asdict(node)
    return copy.deepcopy(node)


class _Builder:
    """Builds and validates the scenario of one case from the base (see the module's
    docstring)."""

    def __init__(self, study: Study, base_yaml: str | None = None, where: str = "base",
                 cache: dict | None = None):
        from pydrake.common.yaml import yaml_load

        # The reachability check's results, shared by the base and every case built from it
        # (through the YAML loading too): a geometry is checked once per study.
        self.cache: dict = {} if cache is None else cache
        try:
            if base_yaml is not None:      # an empty text is refused, never the paper's
                self.base = load_scenario(data=base_yaml, cache=self.cache)
            else:
                self.base = load_scenario(cache=self.cache)
        except ScenarioError as exc:
            raise StudyError(f"{where}: {exc}") from None
        self.base_dict = yaml_load(data=dump_scenario(self.base))
        self.t_end = study.t_end

    def build(self, assignments: list[Assignment], where: str
              ) -> tuple[Scenario, str | None]:
        """The validated scenario (and its YAML when it went through the YAML loading)."""
        from drake_coop.experiment.ticks import check_run_size
        from drake_coop.scenario.validation import validate

        scenario = copy.deepcopy(self.base)
        text = None
        try:
            if _apply_object(scenario, assignments):
                validate(scenario, cache=self.cache)
            else:
                from pydrake.common.yaml import yaml_dump

                data = copy.deepcopy(self.base_dict)
                _apply_dict(data, assignments, where)
                scenario = load_scenario(data=yaml_dump(data), cache=self.cache)
                text = dump_scenario(scenario)
            check_run_size(scenario, self.t_end)
        except ScenarioError as exc:
            error = StudyError(f"{where}: {exc}")
            error.detail = str(exc)
            raise error from None
        return scenario, text


#: Per-joint lists whose empty default means "zero on every joint" (same physics).
_JOINT_LISTS = re.compile(r"^robots\.(\*|\d+)\.model_error\.coulomb_friction\.")


def _fill_joint_lists(builder: "_Builder", paths: list[str]) -> None:
    """Give a per-joint list that a study path reaches into its arm's length.

    ``model_error.coulomb_friction`` defaults to ``[]`` (no friction, any number of joints); a
    path such as ``robots.*.model_error.coulomb_friction.*`` would match no element of it. For
    the robots such a path names, an empty list becomes ``n`` zeros (``n`` the arm's joint
    count from its model): the same physics, and elements for the path to set or draw.
    """
    wanted = [p for p in paths if _JOINT_LISTS.match(p)]
    if not wanted:
        return
    from drake_coop.scenario.model_check import check_models

    joints = check_models(builder.base)
    for i, robot in enumerate(builder.base.robots):
        named = any(_JOINT_LISTS.match(p).group(1) in ("*", str(i)) for p in wanted)
        if named and not robot.model_error.coulomb_friction:
            robot.model_error.coulomb_friction = [0.0] * joints[i]
            entry = builder.base_dict["robots"][i].setdefault("model_error", {})
            entry["coulomb_friction"] = [0.0] * joints[i]


def _samples(study: Study, base: dict) -> list[list[Assignment]]:
    """Monte Carlo draws per sample as assignments (one empty sample: no Monte Carlo)."""
    mc = study.monte_carlo
    if mc is None:
        return [[]]
    targets = [(p, resolve(base, p.path, f"monte_carlo.perturb.{p.path}")) for p in mc.perturb]
    for p, matches in targets:
        if p.distribution == "scale_uniform":
            for keys in matches:
                if not _numeric(get_value(base, keys)):
                    raise StudyError(f"monte_carlo.perturb.{p.path}: scale_uniform needs a "
                                     f"numeric base value, got {get_value(base, keys)!r}")
    rng = np.random.default_rng(mc.seed)
    samples = []
    for _ in range(mc.n):
        values: list[Assignment] = []
        for p, matches in targets:
            for keys in matches:
                if p.distribution == "scale_uniform":
                    values.append((keys, "scale", float(rng.uniform(p.a, p.b))))
                else:
                    values.append((keys, "set", draw(p, None, rng)))
        samples.append(values)
    return samples


def _label(params: dict) -> str:
    text = ", ".join(f"{k}={v!r}" for k, v in params.items())
    return text if len(text) <= 200 else text[:200] + "…"


def expand(study: Study, *, max_cases: int = MAX_CASES,
           max_cases_option: str | None = "--max-cases", first: int | None = None,
           cache: dict | None = None) -> list[Case]:
    """Every case of ``study``, each scenario validated, in order (grid outer, samples inner).

    Parameters
    ----------
    study : Study
        The study.
    max_cases : int
        Refuse a study of more cases (computed before expanding it).
    max_cases_option : str or None
        The command-line option that raises the bound, named in the message (None: a command
        without one, such as ``stability``).
    first : int or None
        Only the first ``first`` cases (``study --cases N``); None: all of them.
    cache : dict or None
        The reachability checks' results (:func:`~drake_coop.scenario.validation.validate`'s
        ``cache``), shared by every base and case and filled here: each geometry is checked
        once; a resume passes what its folder stored
        (:meth:`~drake_coop.studies.folder.StudyFolder.stored_reach`) and checks nothing
        again. None: a cache of this call only.

    Raises
    ------
    StudyError
        Too many cases, a bad path (``grid.robots.0.gains.k_x: no such field …``) or a value
        the scenario rejects (``grid.control_period: control_period must be > 0, got -1``),
        before any run.
    """
    n_cases, points, samples_n = study_size(study)
    if min(n_cases, n_cases if first is None else first) > max_cases:
        raise StudyError(f"the study has {n_cases} cases ({points} grid points × {samples_n} "
                         f"samples), more than {max_cases}; shrink the grid or monte_carlo.n"
                         + (f", or raise the bound on purpose with {max_cases_option}"
                            if max_cases_option else ""))
    labels = study.grid.get(BASE_AXIS) or [None]
    for label in labels:
        if label is not None and label not in study.bases:
            raise StudyError(f"grid.{BASE_AXIS} = {_short(label)}: not one of the study's "
                             "base files (a study with a base axis is read by load_study)")
    cache = {} if cache is None else cache
    builders = {label: _Builder(study, study.bases[label] if label is not None
                                else study.base_yaml,
                                "base" if label is None else f"grid.{BASE_AXIS} = {label!r}",
                                cache)
                for label in labels}
    scenario_paths = [path for path in study.grid if path != BASE_AXIS]
    paths = scenario_paths + ([p.path for p in study.monte_carlo.perturb]
                              if study.monte_carlo is not None else [])
    targets: dict = {}
    for label, builder in builders.items():
        _fill_joint_lists(builder, paths)
        on = "" if label is None else f" (on base {label!r})"
        try:
            targets[label] = {path: resolve(builder.base_dict, path, f"grid.{path}")
                              for path in scenario_paths}
        except StudyError as exc:
            raise StudyError(f"{exc}{on}") from None
    # Each value alone on the base first, so that a bad value is named as the grid gives it.
    # A value refused alone may still be valid with the other keys' values (control_period
    # with plant.time_step): only a case, a combination, that fails is an error, named by
    # that value when it fails for the same reason, by the case otherwise.
    alone: dict[tuple, StudyError] = {}
    for label, builder in builders.items():
        on = "" if label is None else f" (on base {label!r})"
        for path in scenario_paths:
            for value in study.grid[path]:
                marker = json.dumps(value, sort_keys=True, default=repr)
                if (label, path, marker) in alone:
                    continue
                try:
                    builder.build([(keys, "set", value) for keys in targets[label][path]],
                                  f"grid.{path} = {value!r}{on}")
                    alone[(label, path, marker)] = None
                except StudyError as exc:
                    if len(study.grid) == 1 and not study.monte_carlo:
                        raise
                    alone[(label, path, marker)] = exc
    samples, mc_paths = {}, {}
    for label, builder in builders.items():
        try:
            samples[label] = _samples(study, builder.base_dict)
        except StudyError as exc:
            raise StudyError(f"{exc}{'' if label is None else f' (on base {label!r})'}") \
                from None
        first_sample = samples[label][0]
        mc_paths[label] = list(dict.fromkeys(k for k, _, _ in first_sample))
    cases = []
    keys_order = list(study.grid)
    for point in itertools.product(*(study.grid[k] for k in keys_order)):
        grid_params = dict(zip(keys_order, point))
        label = grid_params.get(BASE_AXIS)
        builder = builders[label]
        grid_assign = [(keys, "set", value) for path, value in grid_params.items()
                       if path != BASE_AXIS for keys in targets[label][path]]
        for s, draws in enumerate(samples[label]):
            if first is not None and len(cases) >= first:
                break
            params = dict(grid_params)
            if study.monte_carlo is not None:
                params["sample"] = s
            try:
                scenario, text = builder.build(grid_assign + draws,
                                               f"case {len(cases)} ({_label(params)})")
            except StudyError as exc:
                for path, value in grid_params.items():
                    if path == BASE_AXIS:
                        continue
                    first_error = alone[(label, path, json.dumps(value, sort_keys=True,
                                                                 default=repr))]
                    if first_error is not None and first_error.detail == exc.detail:
                        raise first_error from None
                raise
            values = {}
            for path, spec in grid_params.items():
                if path == BASE_AXIS:
                    values[path] = label
                    continue
                read = [_read(scenario, keys, spec) for keys in targets[label][path]]
                same = all(json.dumps(r, sort_keys=True) == json.dumps(read[0], sort_keys=True)
                           for r in read)
                values[path] = read[0] if same else read
            if study.monte_carlo is not None:
                values["sample"] = s
                for keys in mc_paths[label]:
                    values[".".join(map(str, keys))] = _read(scenario, keys, None)
            cases.append(Case(index=len(cases), params=params, values=values,
                              scenario_yaml=text, scenario=scenario,
                              hash=case_hash(scenario, study.t_end)))
    return cases
