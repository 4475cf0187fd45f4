"""Where the package's data lives: the arm models (URDF) and the shipped scenarios (YAML).

The top-level ``urdf/`` and ``scenarios/`` folders of the repository are the one source. A
wheel carries copies of them as package data (``drake_coop/data/urdf``,
``drake_coop/data/scenarios``, mapped in ``pyproject.toml``), so an installed package finds
them next to its modules; a source checkout (editable install, ``PYTHONPATH``) reads the
top-level folders directly. Everything that needs a model or a shipped scenario asks this
module.

Lookup order of a data folder ``kind`` (``urdf`` or ``scenarios``):

1. ``$DRAKE_COOP_URDF_DIR`` (models only), as before;
2. the installed package data ``drake_coop/data/<kind>`` (wheel installs);
3. the checkout's ``<repo>/<kind>`` (editable installs and ``PYTHONPATH`` runs).
"""

from __future__ import annotations

import os
from importlib import resources as _resources
from pathlib import Path
from typing import TYPE_CHECKING

from drake_coop.scenario.schema import SHIPPED_ARMS, Robot, ScenarioError

if TYPE_CHECKING:
    from drake_coop.scenario.schema import Scenario

__all__ = ["data_dir", "urdf_dir", "PACKAGE_SCHEME", "resolve_package_url", "model_urdf_path", "controller_urdf_path", "scenarios_dir",
           "shipped_scenarios", "scenario_summary",
           "find_scenario", "default_scenario_path", "resolve_models", "model_beside",
           "MODEL_FIELDS"]

#: A file each data folder must hold (tells a real folder from a stray one).
_MARKERS = {"urdf": "crs_a465_3dof.urdf", "scenarios": "paper.yaml"}


def data_dir(kind: str) -> Path:
    """The folder of the package's ``urdf`` or ``scenarios`` data.

    Parameters
    ----------
    kind : str
        ``"urdf"`` or ``"scenarios"``.

    Returns
    -------
    Path
        The installed package data if present, else the source checkout's top-level folder.

    Raises
    ------
    FileNotFoundError
        Neither exists (a broken installation); the message says where it looked.
    """
    marker = _MARKERS[kind]
    packaged = Path(str(_resources.files("drake_coop") / "data" / kind))
    checkout = Path(__file__).resolve().parents[2] / kind
    for folder in (packaged, checkout):
        if (folder / marker).is_file():
            return folder
    raise FileNotFoundError(f"drake_coop's {kind} folder is missing (looked for {marker} in "
                            f"{packaged} and {checkout}); reinstall the package")


def urdf_dir() -> Path:
    """The folder of the robot models: ``$DRAKE_COOP_URDF_DIR`` if set, else the shipped one.
    """
    env = os.environ.get("DRAKE_COOP_URDF_DIR")
    return Path(env) if env else data_dir("urdf")


#: The URL scheme of Drake's package paths (``package://<package>/<path in the package>``).
PACKAGE_SCHEME = "package://"


def resolve_package_url(url: str, field: str = "model") -> Path:
    """The file a ``package://`` URL names, found by Drake's
    :class:`~pydrake.multibody.parsing.PackageMap`.

    The map knows Drake's own packages and every package on ``ROS_PACKAGE_PATH``. A package
    that Drake downloads on first use (``drake_models``) is fetched then, and fails on a machine
    without network access.

    Parameters
    ----------
    url : str
        The ``package://`` URL.
    field : str
        The scenario field naming it, for messages.

    Raises
    ------
    ScenarioError
        ``"<field>: <url>: <why>"``: an unknown package (the known ones are listed), a download
        that failed, or a file missing inside the package.
    """
    from pydrake.multibody.parsing import PackageMap

    from drake_coop.control.arm_plant import DESCRIPTION_PACKAGES, add_description_packages

    package = url[len(PACKAGE_SCHEME):].split("/", 1)[0]
    packages = PackageMap()
    packages.PopulateFromRosPackagePath()
    add_description_packages(packages)
    if package in DESCRIPTION_PACKAGES and not packages.Contains(package):
        from drake_coop.scenario.description import ROBOTS_EXTRA

        raise ScenarioError(f"{field}: {url}: the package {package!r} is not installed; "
                            f"install the robots extra: {ROBOTS_EXTRA}")
    if not package or not packages.Contains(package):
        known = ", ".join(sorted(packages.GetPackageNames()))
        raise ScenarioError(f"{field}: {url}: unknown package {package!r} (Drake knows {known}; "
                            "add yours to ROS_PACKAGE_PATH or give the .urdf file's path)")
    import logging

    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.WARNING)      # Drake logs each download attempt at INFO
    try:
        path = Path(packages.ResolveUrl(url))
    except RuntimeError as error:
        text = " ".join(str(error).split())
        why = (f"Drake could not download the package {package!r}, which it fetches on first "
               "use; give the .urdf file's path" if "download" in text
               else text.removeprefix("error: ")[:200])
        raise ScenarioError(f"{field}: {url} could not be resolved: {why}") from None
    finally:
        drake_log.setLevel(level)
    return path


def _model_path(value: str, field: str, robot: Robot | None = None) -> Path:
    """A ``.urdf`` path (absolute or relative to :func:`urdf_dir`) or a ``package://`` URL;
    with the robot's ``locked_joints`` or ``tool``, or from a package, the URDF prepared from it
    (:func:`drake_coop.scenario.description.prepared_urdf`)."""
    if value.startswith(PACKAGE_SCHEME):
        source = resolve_package_url(value, field)
    else:
        p = Path(value).expanduser()
        source = p if p.is_absolute() else urdf_dir() / p
    if robot is None:
        return source
    from drake_coop.scenario.description import needs_preparation, prepared_urdf

    if not needs_preparation(robot, value):
        return source
    from drake_coop.control.arm_plant import DESCRIPTION_PACKAGES

    package = value[len(PACKAGE_SCHEME):].split("/", 1)[0] if value.startswith(
        PACKAGE_SCHEME) else ""
    return prepared_urdf(robot, source, field,
                         resolve=lambda url: resolve_package_url(url, field),
                         from_package=package in DESCRIPTION_PACKAGES)


def model_urdf_path(robot: Robot, field: str = "model") -> Path:
    """The simulated arm's URDF: a shipped model by name, else the ``.urdf`` path (absolute or
    relative to :func:`urdf_dir`) or ``package://`` URL (:func:`resolve_package_url`).

    ``field`` names the scenario field in error messages.

    Parameters
    ----------
    robot : Robot
        The robot.
    field : str
        The scenario field, for messages.
    """
    if robot.model in SHIPPED_ARMS:
        return _model_path(SHIPPED_ARMS[robot.model], field, robot)
    return _model_path(robot.model, field, robot)


def controller_urdf_path(robot: Robot, field: str = "controller_model") -> Path:
    """The controller's own model of the arm (defaults to the simulated one); a path or a
    ``package://`` URL as for :func:`model_urdf_path`.

    Parameters
    ----------
    robot : Robot
        The robot.
    field : str
        The scenario field, for messages.
    """
    if not robot.controller_model:
        return model_urdf_path(robot)
    return _model_path(robot.controller_model, field, robot)


def scenarios_dir() -> Path:
    """The folder of the shipped scenarios (``paper.yaml`` and its variants).
    """
    return data_dir("scenarios")


def default_scenario_path() -> Path:
    """The shipped ``paper.yaml``: the default scenario of ``drake-coop run``.
    """
    return scenarios_dir() / "paper.yaml"


def shipped_scenarios() -> dict[str, Path]:
    """The shipped scenarios by name (file stem), sorted by name.
    """
    return {p.stem: p for p in sorted(scenarios_dir().glob("*.yaml"))}


def scenario_summary(path: Path) -> str:
    """The first sentence of a scenario file's leading comment block, whole (it may span
    several ``#`` lines; empty if the file starts with no comment).

    Parameters
    ----------
    path : Path
        The scenario file.
    """
    words: list[str] = []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if not line.startswith("#") or not line.lstrip("#").strip():
            break
        words += line.lstrip("#").split()
        sentence = " ".join(words)
        end = next((i for i in range(len(sentence)) if sentence[i] == "."
                    and (i + 1 == len(sentence) or sentence[i + 1] == " ")), None)
        if end is not None:
            return sentence[:end + 1]
    return " ".join(words)


def find_scenario(name_or_path: str | Path) -> Path:
    """A scenario file from a path, or from the name of a shipped scenario.

    An existing file wins; otherwise ``paper`` or ``paper.yaml`` names a shipped scenario.

    Parameters
    ----------
    name_or_path : str or Path
        A path or a shipped scenario's name.

    Raises
    ------
    ScenarioError
        Neither a file nor a shipped scenario (the message lists the shipped names).
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = shipped_scenarios()
    stem = path.name[:-5] if path.name.endswith(".yaml") else path.name
    if path.parent == Path(".") and stem in shipped:
        return shipped[stem]
    raise ScenarioError(f"scenario file not found: {path} (shipped scenarios: "
                        f"{', '.join(shipped)})")


def resolve_models(scenario: Scenario, base_dir: Path | None = None) -> None:
    """Make a relative ``model`` / ``controller_model`` path found beside the scenario file
    absolute.

    The arms look relative model paths up in :func:`urdf_dir` (the shipped models); a file
    beside the scenario file (``base_dir``) wins and is rewritten as an absolute path, so that
    a run's saved ``scenario.yaml`` still finds it. The files themselves are checked by
    :func:`drake_coop.scenario.model_check.check_models` when the scenario is validated.

    Parameters
    ----------
    scenario : Scenario
        The scenario (changed in place).
    base_dir : Path or None
        The scenario file's folder; None changes nothing.
    """
    if base_dir is None:
        return
    for robot in scenario.robots:
        for name in MODEL_FIELDS:
            beside = model_beside(getattr(robot, name), base_dir)
            if beside is not None:
                setattr(robot, name, beside)


#: A robot's fields naming a URDF (:func:`resolve_models`, :func:`model_beside`).
MODEL_FIELDS = ("model", "controller_model")


def model_beside(value, base_dir: Path) -> str | None:
    """The absolute path of a robot's relative ``model`` / ``controller_model`` URDF when it
    lies in ``base_dir`` (the scenario file's folder), else None (not a relative ``.urdf``
    path, a ``package://`` URL, or no such file there): the rule of :func:`resolve_models`,
    also for a scenario's untyped data (a study's base file).

    Parameters
    ----------
    value : object
        A robot's ``model`` or ``controller_model`` value.
    base_dir : Path
        The scenario file's folder.

    Returns
    -------
    str or None
        The absolute path, or None.
    """
    if not (isinstance(value, str) and value and value.lower().endswith(".urdf")
            and not value.startswith(PACKAGE_SCHEME)
            and not Path(value).expanduser().is_absolute()):
        return None
    beside = Path(base_dir) / Path(value).expanduser()
    return str(beside.resolve()) if beside.is_file() else None
