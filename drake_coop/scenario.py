"""Scenario: every number of an experiment, as typed dataclasses loaded from YAML.

A scenario is the single source of truth of a run: the plant (time step, object mode), the
two robots (model, base pose, constraint plane, home point, gains), the task of Section IV of
the paper (phase times, circle (28), force profile (29)) and the simulation guards.
``scenarios/paper.yaml`` holds the paper's experiment; :func:`default_scenario` returns the
same numbers from code.

Loading goes through :func:`pydrake.common.yaml.yaml_load_typed` (unknown keys and wrong types
are rejected there) and then :func:`validate`, which checks ranges and consistency. Every
problem is reported as a :class:`ScenarioError` whose message names the field and what is
allowed.
"""


import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

OBJECT_MODES = ("planes", "rigid", "contact", "none")
VELOCITY_SOURCES = ("observer", "measured", "difference")
FORCE_SOURCES = ("observer", "sensor", "none")
ARM_MODELS = ("crs_a465", "crs_a255")


class ScenarioError(ValueError):
    """A scenario field is missing, of the wrong type, or out of its allowed range."""


@dataclass
class Gains:
    """Gains of the controller (13) and observers (15)-(16), (22) of one robot.

    Attributes
    ----------
    Lambda : float
        k of the paper's ``Lambda = k I`` (1/s): the gain of q̃ in q̇_r (4) and of z in (8).
    K_R : list[float]
        Diagonal of ``K_R`` (N·m·s/rad), the velocity-error gain of (13).
    k_d : float
        Observer gain of (15)-(16) (1/s).
    k_F : float
        Gain of the force integral ΔF̃ in (13) (dimensionless).
    xi : float
        ``xi`` of (4) (m×m, here scalar), weight of ΔF̃ in the reference velocity.
    zeta : float
        ``zeta`` of (13), weight of Δλ̃ (dimensionless).
    beta : float
        ``beta`` of (4), position-constraint gain (1/s). Not given by the paper.
    """

    Lambda: float = 35.0
    K_R: list[float] = field(default_factory=lambda: [120.0, 120.0, 120.0])
    k_d: float = 40.0
    k_F: float = 0.05
    xi: float = 1e-5
    zeta: float = 1e-3
    beta: float = 10.0


@dataclass
class Encoders:
    """Joint-position sensors of one robot (:class:`drake_coop.sensing.encoders.Encoders`).

    The reading at tick ``k`` is ``δ round((q(t_{k-d}) + w_{k-d}) / δ)`` with ``δ = 2π /
    counts_per_rev`` (no rounding when ``counts_per_rev`` is null), ``w`` white Gaussian noise
    and ``d = delay_samples``. Defaults: an ideal sensor (the exact ``q(t_k)``).

    Attributes
    ----------
    counts_per_rev : int or None
        Resolution in counts per joint revolution (>= 1; for an incremental encoder on the motor
        behind a gear of ratio N: motor counts × N). Null: no quantization.
    noise_std : float
        Standard deviation of the additive white noise ``w`` (rad, >= 0).
    delay_samples : int
        Delay ``d`` in whole samples ``h`` (>= 0).
    seed : int
        Seed of the noise (>= 0); the noise is a deterministic function of (seed, robot, tick,
        joint), so runs are reproducible.
    """

    counts_per_rev: Optional[int] = None
    noise_std: float = 0.0
    delay_samples: int = 0
    seed: int = 0


@dataclass
class ForceSensorModel:
    """A wrist force/torque sensor measuring the squeeze λ, sampled at ``h``
    (:class:`drake_coop.sensing.force_sensor.FTSensor`).

    ``λ_s(k) = y(k) + bias + v_k`` with ``y`` the first-order low-pass
    ``y(k) = y(k-1) + α (λ(t_k^-) − y(k-1))``, ``α = 1 − exp(−2π f_c h)`` (``α = 1`` without
    cutoff), ``λ(t_k^-)`` the true squeeze just before the tick and ``v`` white Gaussian noise.
    Used by the controller only with ``force_source: sensor``; always logged as
    ``lambda_sensor``.

    Attributes
    ----------
    noise_std : float
        Standard deviation of ``v`` (N, >= 0).
    bias : float
        Constant offset along the contact normal, i.e. on λ (N).
    cutoff_hz : float or None
        Cutoff ``f_c`` of the low-pass (Hz), ``0 < f_c < 1/(2h)`` (Nyquist). Null: no filter.
    seed : int
        Seed of the noise (>= 0).
    """

    noise_std: float = 0.0
    bias: float = 0.0
    cutoff_hz: Optional[float] = None
    seed: int = 0


@dataclass
class Actuators:
    """The motors of one robot (``robotN_actuators``, a Drake ``Saturation``).

    Attributes
    ----------
    torque_limits : list[float] or None
        Per-joint limits ``|τ_j| <= τ_max,j`` (N·m at the joint, > 0), one per joint; the
        applied (saturated) torque is logged as ``tau``, the commanded one as ``tau_cmd``.
        Null: unlimited.
    """

    torque_limits: Optional[list[float]] = None


@dataclass
class ModelError:
    """What the controller's model gets wrong (:mod:`drake_coop.sensing.model_error`).

    The controller's model is the URDF of the simulated arm (or ``controller_model``) with
    every link's mass multiplied by ``mass_scale``, every link's rotational inertia and every
    rotor inertia by ``inertia_scale`` and every joint damping by ``damping_scale``. The
    simulated arm additionally carries ``payload_mass`` and suffers Coulomb friction, both
    unknown to the controller. Defaults: an exact model.

    Attributes
    ----------
    mass_scale, inertia_scale, damping_scale : float
        Scales of the controller's link masses, inertias (links and rotors) and joint damping
        (> 0).
    payload_mass : float
        A point mass (kg, >= 0) welded to the simulated arm's tool flange (the origin of the
        force sensor's body, ``L_forearm + L_flange`` from the elbow, on the wrist side of the
        force sensor, so the sensor does not weigh it).
    coulomb_friction : list[float]
        Coulomb friction torque of each simulated joint (N·m, >= 0), ``−f_c tanh(q̇/v_s)``
        with ``v_s = 0.01 rad/s``.
    """

    mass_scale: float = 1.0
    inertia_scale: float = 1.0
    damping_scale: float = 1.0
    payload_mass: float = 0.0
    coulomb_friction: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])


@dataclass
class Robot:
    """One arm ("finger") of the cooperative system.

    Attributes
    ----------
    name : str
        Model-instance and subsystem prefix (``robot1``, ``robot2``).
    model : str
        ``crs_a465`` or ``crs_a255`` (file ``urdf/<model>_3dof.urdf``).
    controller_model : str
        URDF file (relative to ``urdf/`` or absolute) of the controller's own model of the arm;
        empty means the same URDF as the simulated arm (exact model knowledge).
    base_xyz : list[float]
        Position of the robot's base in the palm frame (m).
    base_yaw_deg : float
        Rotation of the base about the palm z axis (degrees).
    plane_b : float
        ``b_i`` of the constraint ``x_i = b_i`` (m): the x coordinate of the contact point.
    normal_sign : float
        x component (±1) of the object's outward normal at this contact. With
        ``phi_i = normal_sign * (x_i - b_i)`` a positive λ squeezes the object.
    home : list[float]
        Cartesian start and end point of the end effector (m, palm frame).
    gains : Gains
        The robot's controller and observer gains.
    velocity_source : str
        ``observer`` (the paper's scheme: the velocity observer (15)–(16)), ``measured`` (a
        baseline: the true joint velocities) or ``difference`` (the backward difference of the
        encoder signal at ``h``, optionally low-passed).
    difference_cutoff_hz : float or None
        ``difference`` only: cutoff of a first-order low-pass of the difference (Hz),
        ``0 < f < 1/(2h)``; null: the raw difference.
    force_source : str
        ``observer`` (the paper's (22)), ``sensor`` (the F/T sensor model's λ in (13) and (6))
        or ``none`` (``λ̂ := λ_d``, ``ΔF̃ ≡ 0``: the implicit force control of reference [9]).
    encoders : Encoders
        The joint-position sensors.
    force_sensor : ForceSensorModel
        The wrist F/T sensor model.
    actuators : Actuators
        Torque limits.
    model_error : ModelError
        The controller's model error, payload and joint friction of the simulated arm.
    """

    name: str = "robot1"
    model: str = "crs_a465"
    controller_model: str = ""
    base_xyz: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    base_yaw_deg: float = 0.0
    plane_b: float = 0.6
    normal_sign: float = -1.0
    home: list[float] = field(default_factory=lambda: [0.5, 0.0, 0.6])
    gains: Gains = field(default_factory=Gains)
    velocity_source: str = "observer"
    difference_cutoff_hz: Optional[float] = None
    force_source: str = "observer"
    encoders: Encoders = field(default_factory=Encoders)
    force_sensor: ForceSensorModel = field(default_factory=ForceSensorModel)
    actuators: Actuators = field(default_factory=Actuators)
    model_error: ModelError = field(default_factory=ModelError)


@dataclass
class PlantSettings:
    """The simulated cooperative plant.

    Attributes
    ----------
    time_step : float
        Discrete step of the MultibodyPlant (s); must divide the control period.
    object_mode : str
        ``planes`` (the paper's model), ``rigid``, ``contact`` or ``none``.
    object_mass : float
        Mass of the carried object in ``rigid`` and ``contact`` modes (kg).
    friction : float
        Coulomb friction coefficient between pads and box (``contact``).
    """

    time_step: float = 0.001
    object_mode: str = "planes"
    object_mass: float = 0.5
    friction: float = 1.0


@dataclass
class Task:
    """The experiment of Section IV: phases, paths (28) and force profile (29).

    Phases: free motion ``[0, t_grasp)`` (home → pre-grasp → grasp), lift
    ``[t_grasp, t_circle_start)``, circle ``[t_circle_start, t_circle_end)``, put-down
    ``[t_circle_end, t_release)``, return ``[t_release, t_end]``.

    Attributes
    ----------
    t_grasp, t_circle_start, t_circle_end, t_release, t_end : float
        Phase boundaries (s). The paper: 15, 25, 65, 75, 90.
    t_pregrasp : float
        End of the approach to the pre-grasp point (s); also the return's retreat time is
        ``t_release + (t_grasp - t_pregrasp)``.
    pregrasp_distance : float
        Distance of the pre-grasp point from the grasp point along the outward normal (m).
    circle_top_z : float
        z of the circle's start point, 0.635 m in (28).
    circle_radius : float
        Radius of the circle (28), 0.05 m.
    lift_height : float
        Height of the lift from the grasp point to the circle's start (m).
    force_mean, force_amplitude : float
        32 N and 18 N of (29).
    force_omega : float
        Angular frequency of (29), 3π/40 rad/s.
    """

    t_pregrasp: float = 10.0
    t_grasp: float = 15.0
    t_circle_start: float = 25.0
    t_circle_end: float = 65.0
    t_release: float = 75.0
    t_end: float = 90.0
    pregrasp_distance: float = 0.05
    circle_top_z: float = 0.635
    circle_radius: float = 0.05
    lift_height: float = 0.1
    force_mean: float = 32.0
    force_amplitude: float = 18.0
    force_omega: float = 3.0 * math.pi / 40.0


@dataclass
class Guards:
    """Divergence guards of the simulation.

    Attributes
    ----------
    max_force : float
        Bound on |λ̂| and on the measured force (N); beyond it the run stops.
    joint_limit_margin_deg : float
        A joint passing its URDF limit by more than this stops the run (degrees).
    check_period : float
        How often the guards are evaluated (s of simulated time).
    """

    max_force: float = 500.0
    joint_limit_margin_deg: float = 0.0
    check_period: float = 0.09


@dataclass
class Scenario:
    """A complete experiment.

    Attributes
    ----------
    control_period : float
        Sampling time h of the controllers and observers (s), 9 ms in the paper.
    plant : PlantSettings
    robots : list[Robot]
        Exactly two robots; robot 1 on the left (normal_sign = -1), robot 2 on the right.
    task : Task
    guards : Guards
    """

    control_period: float = 0.009
    plant: PlantSettings = field(default_factory=PlantSettings)
    robots: list[Robot] = field(default_factory=list)
    task: Task = field(default_factory=Task)
    guards: Guards = field(default_factory=Guards)


def paper_robots() -> list[Robot]:
    """The two robots of Section IV with the paper's gains (β is ours)."""
    return [
        Robot(
            name="robot1",
            model="crs_a465",
            base_xyz=[0.0, 0.0, 0.0],
            base_yaw_deg=0.0,
            plane_b=0.6,
            normal_sign=-1.0,
            home=[0.5, 0.0, 0.6],
            gains=Gains(Lambda=35.0, K_R=[120.0] * 3, k_d=40.0, k_F=0.05, xi=1e-5, zeta=1e-3,
                        beta=10.0),
        ),
        Robot(
            name="robot2",
            model="crs_a255",
            base_xyz=[1.16, 0.0, 0.0],
            base_yaw_deg=180.0,
            plane_b=0.8192,
            normal_sign=1.0,
            home=[0.9, 0.0, 0.6],
            gains=Gains(Lambda=26.0, K_R=[100.0] * 3, k_d=40.0, k_F=0.05, xi=1e-5, zeta=1e-3,
                        beta=10.0),
        ),
    ]


def default_scenario() -> Scenario:
    """The paper's experiment (the numbers of ``scenarios/paper.yaml``)."""
    return Scenario(robots=paper_robots())


# --------------------------------------------------------------------------- timing


def aligned_periods(control_period: float, time_step: float) -> tuple[float, float]:
    """Control period ``h`` and plant step ``dt`` adjusted so that their event times coincide.

    Drake schedules a periodic event at ``k * period`` (floating point). With ``h = 0.009`` and
    ``dt = 0.001``, ``k * 0.009`` and ``(9 k) * 0.001`` differ by one rounding now and then, and
    the simulator takes spurious ~1e-17 s steps between the plant's step and the controller's
    tick (drake issue 15021) — with the plant stepping *before* the controller reads its state.
    Rounding ``dt`` to ``53 − ceil(log2 N)`` significant bits (a relative change below 1e-14)
    makes ``h = N dt`` exact, and then ``k h`` and ``(N k) dt`` are the same real number rounded
    once: every control tick falls exactly on a plant step.

    Returns
    -------
    (h, dt) : tuple[float, float]
        With ``h == N * dt`` exactly, ``N = round(control_period / time_step)``.
    """
    N = int(round(control_period / time_step))
    if N == 1:
        return float(control_period), float(control_period)
    bits = 53 - math.ceil(math.log2(N))
    _, exponent = math.frexp(time_step)
    scale = 2.0 ** (bits - exponent)
    dt = round(time_step * scale) / scale
    return N * dt, dt


# --------------------------------------------------------------------------- loading


def load_scenario(path: str | Path | None = None, *, data: str | None = None) -> Scenario:
    """Load and validate a scenario from a YAML file (or a YAML string).

    Parameters
    ----------
    path : str or Path, optional
        YAML file. ``None`` with ``data=None`` gives :func:`default_scenario`.
    data : str, optional
        YAML text instead of a file.

    Returns
    -------
    Scenario
        The validated scenario.

    Raises
    ------
    ScenarioError
        With a one-line message naming the offending field and what is allowed.
    """
    from pydrake.common.yaml import yaml_load_typed

    if path is None and data is None:
        scenario = default_scenario()
    else:
        if path is not None:
            path = Path(path)
            if not path.is_file():
                raise ScenarioError(f"scenario file not found: {path}")
            data = path.read_text()
        _check_structure(_load_untyped(data), Scenario, "")
        try:
            scenario = yaml_load_typed(
                schema=Scenario, data=data, allow_schema_with_no_yaml=True
            )
        except Exception as exc:  # yaml_load_typed raises plain RuntimeError/TypeError
            raise ScenarioError(_yaml_message(exc)) from None
        if not scenario.robots:
            scenario.robots = paper_robots()
    validate(scenario)
    return scenario


def _load_untyped(data: str):
    from pydrake.common.yaml import yaml_load

    try:
        return yaml_load(data=data)
    except Exception as exc:
        raise ScenarioError(f"invalid YAML: {' '.join(str(exc).split())}") from None


def _check_structure(data, schema, path: str) -> None:
    """Unknown keys and wrong types, reported with the field's dotted path."""
    import typing

    where = path or "scenario"
    if dataclasses.is_dataclass(schema):
        if data is None:
            return
        if not isinstance(data, dict):
            raise ScenarioError(f"{where} must be a mapping of fields, got {data!r}")
        hints = typing.get_type_hints(schema)
        for key, value in data.items():
            if key not in hints:
                allowed = ", ".join(hints)
                raise ScenarioError(f"{path + '.' if path else ''}{key} is not a known field "
                                    f"of {where}; allowed: {allowed}")
            _check_structure(value, hints[key], f"{path + '.' if path else ''}{key}")
        return
    origin = typing.get_origin(schema)
    if origin is typing.Union:   # Optional[X]: null or an X
        if data is None:
            return
        (inner,) = [a for a in typing.get_args(schema) if a is not type(None)]
        _check_structure(data, inner, path)
        return
    if origin is list:
        if not isinstance(data, list):
            raise ScenarioError(f"{where} must be a list, got {data!r}")
        (item,) = typing.get_args(schema)
        for i, value in enumerate(data):
            _check_structure(value, item, f"{path}[{i}]")
    elif schema is float:
        if isinstance(data, bool) or not isinstance(data, (int, float)):
            raise ScenarioError(f"{where} must be a number, got {data!r}")
    elif schema is int:
        if isinstance(data, bool) or not isinstance(data, int):
            raise ScenarioError(f"{where} must be a whole number, got {data!r}")
    elif schema is str:
        if not isinstance(data, str):
            raise ScenarioError(f"{where} must be a string, got {data!r}")


def _yaml_message(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return f"invalid scenario: {text}"


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as YAML text (round-trips through :func:`load_scenario`)."""
    from pydrake.common.yaml import yaml_dump_typed

    return yaml_dump_typed(scenario)


# --------------------------------------------------------------------------- validation


def _finite(value: float, name: str) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise ScenarioError(f"{name} must be a finite number, got {value!r}")


def _positive(value: float, name: str) -> None:
    _finite(value, name)
    if value <= 0:
        raise ScenarioError(f"{name} must be > 0, got {value!r}")


def _vector(value: list[float], n: int, name: str) -> None:
    if len(value) != n:
        raise ScenarioError(f"{name} must have {n} entries, got {len(value)}")
    for i, v in enumerate(value):
        _finite(v, f"{name}[{i}]")


def _is_multiple(period: float, step: float) -> bool:
    ratio = period / step
    return abs(ratio - round(ratio)) < 1e-9 * max(1.0, ratio)


def validate(scenario: Scenario) -> None:
    """Check ranges and consistency of a scenario.

    Raises
    ------
    ScenarioError
        On the first problem found, naming the field and the allowed values.
    """
    _positive(scenario.control_period, "control_period")
    if scenario.control_period > 0.1:
        raise ScenarioError(
            f"control_period must be in (0, 0.1] s, got {scenario.control_period}")

    p = scenario.plant
    _positive(p.time_step, "plant.time_step")
    if p.time_step > scenario.control_period * (1 + 1e-12):
        raise ScenarioError(
            f"plant.time_step ({p.time_step}) must not exceed control_period "
            f"({scenario.control_period})")
    if not _is_multiple(scenario.control_period, p.time_step):
        raise ScenarioError(
            f"control_period ({scenario.control_period}) must be an integer multiple of "
            f"plant.time_step ({p.time_step}); e.g. 0.001, 0.003, 0.0045 or 0.009 for h = 0.009")
    if p.object_mode not in OBJECT_MODES:
        raise ScenarioError(
            f"plant.object_mode must be one of {', '.join(OBJECT_MODES)}, got {p.object_mode!r}")
    _positive(p.object_mass, "plant.object_mass")
    if p.object_mass > 20:
        raise ScenarioError(f"plant.object_mass must be in (0, 20] kg, got {p.object_mass}")
    _positive(p.friction, "plant.friction")

    if len(scenario.robots) != 2:
        raise ScenarioError(f"robots must list exactly 2 robots, got {len(scenario.robots)}")
    names = [r.name for r in scenario.robots]
    if len(set(names)) != 2:
        raise ScenarioError(f"robots[].name must be distinct, got {names}")
    for i, r in enumerate(scenario.robots):
        where = f"robots[{i}]"
        if not r.name.isidentifier():
            raise ScenarioError(f"{where}.name must be an identifier, got {r.name!r}")
        if r.model not in ARM_MODELS:
            raise ScenarioError(
                f"{where}.model must be one of {', '.join(ARM_MODELS)}, got {r.model!r}")
        _vector(r.base_xyz, 3, f"{where}.base_xyz")
        _finite(r.base_yaw_deg, f"{where}.base_yaw_deg")
        _finite(r.plane_b, f"{where}.plane_b")
        if r.normal_sign not in (-1.0, 1.0):
            raise ScenarioError(f"{where}.normal_sign must be -1 or 1, got {r.normal_sign}")
        _vector(r.home, 3, f"{where}.home")
        _validate_sensing(r, where, scenario.control_period)
        g = r.gains
        for name in ("Lambda", "k_d", "k_F", "xi", "zeta", "beta"):
            _positive(getattr(g, name), f"{where}.gains.{name}")
        _vector(g.K_R, 3, f"{where}.gains.K_R")
        for j, k in enumerate(g.K_R):
            _positive(k, f"{where}.gains.K_R[{j}]")
    if scenario.robots[0].normal_sign == scenario.robots[1].normal_sign:
        raise ScenarioError("robots[].normal_sign must differ (one contact on each side)")

    t = scenario.task
    for f in dataclasses.fields(Task):
        _finite(getattr(t, f.name), f"task.{f.name}")
    times = ["t_pregrasp", "t_grasp", "t_circle_start", "t_circle_end", "t_release", "t_end"]
    prev_name, prev = "0", 0.0
    for name in times:
        value = getattr(t, name)
        if value <= prev:
            raise ScenarioError(f"task.{name} must be > {prev_name} ({prev}), got {value}")
        prev_name, prev = f"task.{name}", value
    if t.t_release + (t.t_grasp - t.t_pregrasp) >= t.t_end:
        raise ScenarioError(
            "task.t_end must leave time for the retreat: t_end > t_release + "
            f"(t_grasp - t_pregrasp) = {t.t_release + t.t_grasp - t.t_pregrasp}")
    for name in ("pregrasp_distance", "circle_radius", "lift_height"):
        _positive(getattr(t, name), f"task.{name}")
    if t.force_mean < 0 or t.force_amplitude < 0 or t.force_omega < 0:
        raise ScenarioError("task.force_mean, force_amplitude, force_omega must be >= 0")
    if t.force_amplitude > t.force_mean:
        raise ScenarioError(
            f"task.force_amplitude ({t.force_amplitude}) must not exceed task.force_mean "
            f"({t.force_mean}): the squeeze force must stay >= 0")

    gd = scenario.guards
    _positive(gd.max_force, "guards.max_force")
    _finite(gd.joint_limit_margin_deg, "guards.joint_limit_margin_deg")
    if gd.joint_limit_margin_deg < 0:
        raise ScenarioError("guards.joint_limit_margin_deg must be >= 0")
    _positive(gd.check_period, "guards.check_period")

    # Reachability of every Cartesian target (imported late: arms imports this module).
    from drake_coop.references import check_reachable

    check_reachable(scenario)


# --------------------------------------------------------------------------- sensing


def _whole(value, name: str, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ScenarioError(f"{name} must be a whole number >= {minimum}, got {value!r}")


def _non_negative(value: float, name: str) -> None:
    _finite(value, name)
    if value < 0:
        raise ScenarioError(f"{name} must be >= 0, got {value!r}")


def _cutoff(value: float | None, name: str, h: float) -> None:
    """A low-pass cutoff: null or ``0 < f < 1/(2h)`` (the Nyquist frequency of sampling h)."""
    if value is None:
        return
    _finite(value, name)
    nyquist = 1.0 / (2.0 * h)
    if not 0.0 < value < nyquist:
        raise ScenarioError(f"{name} must be null or in (0, {nyquist:g}) Hz (below the "
                            f"Nyquist frequency 1/(2h) for h = {h:g} s), got {value!r}")


def _validate_sensing(robot: Robot, where: str, h: float) -> None:
    """Sources, sensors, actuators and model error of one robot (issue 7).

    Raises
    ------
    ScenarioError
        Naming the field (``where`` is e.g. ``robots[0]``) and what is allowed.
    """
    if robot.velocity_source not in VELOCITY_SOURCES:
        raise ScenarioError(
            f"{where}.velocity_source must be one of {', '.join(VELOCITY_SOURCES)}, got "
            f"{robot.velocity_source!r}")
    if robot.force_source not in FORCE_SOURCES:
        raise ScenarioError(
            f"{where}.force_source must be one of {', '.join(FORCE_SOURCES)}, got "
            f"{robot.force_source!r}")
    _cutoff(robot.difference_cutoff_hz, f"{where}.difference_cutoff_hz", h)
    if robot.difference_cutoff_hz is not None and robot.velocity_source != "difference":
        raise ScenarioError(f"{where}.difference_cutoff_hz applies to velocity_source: "
                            f"difference only; set it to null or use difference")
    e = robot.encoders
    if e.counts_per_rev is not None:
        _whole(e.counts_per_rev, f"{where}.encoders.counts_per_rev", 1)
    _non_negative(e.noise_std, f"{where}.encoders.noise_std")
    _whole(e.delay_samples, f"{where}.encoders.delay_samples", 0)
    _whole(e.seed, f"{where}.encoders.seed", 0)
    f = robot.force_sensor
    _non_negative(f.noise_std, f"{where}.force_sensor.noise_std")
    _finite(f.bias, f"{where}.force_sensor.bias")
    _cutoff(f.cutoff_hz, f"{where}.force_sensor.cutoff_hz", h)
    _whole(f.seed, f"{where}.force_sensor.seed", 0)
    limits = robot.actuators.torque_limits
    if limits is not None:
        _vector(limits, 3, f"{where}.actuators.torque_limits")
        for j, value in enumerate(limits):
            _positive(value, f"{where}.actuators.torque_limits[{j}]")
    m = robot.model_error
    for name in ("mass_scale", "inertia_scale", "damping_scale"):
        _positive(getattr(m, name), f"{where}.model_error.{name}")
    _non_negative(m.payload_mass, f"{where}.model_error.payload_mass")
    _vector(m.coulomb_friction, 3, f"{where}.model_error.coulomb_friction")
    for j, value in enumerate(m.coulomb_friction):
        _non_negative(value, f"{where}.model_error.coulomb_friction[{j}]")
