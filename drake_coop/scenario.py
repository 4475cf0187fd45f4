"""Scenario: every number of an experiment, as typed dataclasses loaded from YAML.

A scenario is the single source of truth of a run: the plant (time step, object mode), the
two robots (model, base pose, constraint plane, home point, gains), the task of Section IV of
the paper (phase times, circle (28), force profile (29)) and the simulation guards.
``scenarios/paper.yaml`` holds the paper's experiment; :func:`default_scenario` returns the
same numbers from code.

Loading reads the file as bytes with a size limit and parses it with bounded aliases and no
duplicate keys (:mod:`drake_coop.safe_yaml`), checks its structure (unknown keys, wrong types,
``null`` sections), fills the dataclasses with :func:`pydrake.common.yaml.yaml_load_typed` and
then runs :func:`validate`: every number against its range in :data:`BOUNDS`
(:mod:`drake_coop.bounds`), the cross-field rules, reachability and the model files. Every
problem is reported as a :class:`ScenarioError` whose one-line message (at most 300
characters) names the field and what is allowed.
"""


import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from drake_coop.bounds import Bound, check_numbers, one_line, optional_of, show

OBJECT_MODES = ("planes", "rigid", "contact", "none")
VELOCITY_SOURCES = ("observer", "measured", "difference")
FORCE_SOURCES = ("observer", "sensor", "none")
ARM_MODELS = ("crs_a465", "crs_a255")


class ScenarioError(ValueError):
    """A scenario field is missing, of the wrong type, or out of its allowed range.

    The message is always one line of at most 300 characters.
    """

    def __init__(self, message: str):
        super().__init__(one_line(message))


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


# --------------------------------------------------------------------------- ranges

_POS = dict(lo_open=True)
#: Allowed range of every number of a scenario, by dotted field (``[]``: any index). A new
#: ``float`` or ``list[float]`` field gets its entry here (``tests/test_scenario_bounds.py``
#: checks that every numeric field has one); :func:`validate` then checks it, and the message
#: states the bound.
BOUNDS: dict[str, Bound] = {
    "control_period": Bound(1e-4, 0.1, "s"),
    "plant.time_step": Bound(1e-5, 0.1, "s"),
    "plant.object_mass": Bound(0.0, 20.0, "kg", **_POS),
    "plant.friction": Bound(0.0, 5.0, "", **_POS),
    "robots[].base_xyz[]": Bound(-5.0, 5.0, "m"),
    "robots[].base_yaw_deg": Bound(-360.0, 360.0, "deg"),
    "robots[].plane_b": Bound(-5.0, 5.0, "m"),
    "robots[].normal_sign": Bound(-1.0, 1.0),
    "robots[].home[]": Bound(-5.0, 5.0, "m"),
    "robots[].gains.Lambda": Bound(0.0, 1e3, "1/s", **_POS),
    "robots[].gains.K_R[]": Bound(0.0, 1e4, "N·m·s/rad", **_POS),
    "robots[].gains.k_d": Bound(0.0, 1e4, "1/s", **_POS),
    "robots[].gains.k_F": Bound(0.0, 100.0, "", **_POS),
    "robots[].gains.xi": Bound(0.0, 1.0, "", **_POS),
    "robots[].gains.zeta": Bound(0.0, 100.0, "", **_POS),
    "robots[].gains.beta": Bound(0.0, 1e3, "1/s", **_POS),
    "robots[].difference_cutoff_hz": Bound(0.0, 1e6, "Hz", **_POS),
    "robots[].encoders.counts_per_rev": Bound(1, 1e12, "counts"),
    "robots[].encoders.noise_std": Bound(0.0, 1.0, "rad"),
    "robots[].encoders.delay_samples": Bound(0, 1000, "samples"),
    "robots[].encoders.seed": Bound(0, 2**63 - 1),
    "robots[].force_sensor.noise_std": Bound(0.0, 1e3, "N"),
    "robots[].force_sensor.bias": Bound(-1e3, 1e3, "N"),
    "robots[].force_sensor.cutoff_hz": Bound(0.0, 1e6, "Hz", **_POS),
    "robots[].force_sensor.seed": Bound(0, 2**63 - 1),
    "robots[].actuators.torque_limits[]": Bound(0.0, 1e4, "N·m", **_POS),
    "robots[].model_error.mass_scale": Bound(0.0, 100.0, "", **_POS),
    "robots[].model_error.inertia_scale": Bound(0.0, 100.0, "", **_POS),
    "robots[].model_error.damping_scale": Bound(0.0, 100.0, "", **_POS),
    "robots[].model_error.payload_mass": Bound(0.0, 20.0, "kg"),
    "robots[].model_error.coulomb_friction[]": Bound(0.0, 1e3, "N·m"),
    **{f"task.{name}": Bound(0.0, 1e4, "s", **_POS) for name in (
        "t_pregrasp", "t_grasp", "t_circle_start", "t_circle_end", "t_release", "t_end")},
    "task.pregrasp_distance": Bound(0.0, 1.0, "m", **_POS),
    "task.circle_top_z": Bound(-5.0, 5.0, "m"),
    "task.circle_radius": Bound(0.0, 1.0, "m", **_POS),
    "task.lift_height": Bound(0.0, 1.0, "m", **_POS),
    "task.force_mean": Bound(0.0, 1e3, "N"),
    "task.force_amplitude": Bound(0.0, 1e3, "N"),
    "task.force_omega": Bound(0.0, 100.0, "rad/s"),
    "guards.max_force": Bound(0.0, 1e5, "N", **_POS),
    "guards.joint_limit_margin_deg": Bound(0.0, 180.0, "deg"),
    "guards.check_period": Bound(0.0, 100.0, "s", **_POS),
}
#: Length of every list of numbers.
LENGTHS: dict[str, int] = {"robots[].base_xyz": 3, "robots[].home": 3,
                           "robots[].gains.K_R": 3, "robots[].actuators.torque_limits": 3,
                           "robots[].model_error.coulomb_friction": 3}

#: Largest run (control ticks of ``h``, and plant steps) accepted: the references and the
#: logs cost about 5 kB per tick (1 GB at the limit), a plant step about 50 µs.
MAX_TICKS = 200_000
MAX_PLANT_STEPS = 20_000_000


def run_size(scenario: Scenario, t_end: float | None = None) -> tuple[int, int]:
    """Control ticks and plant steps of a run to ``min(t_end, task.t_end)``."""
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    T = scenario.task.t_end if t_end is None else min(t_end, scenario.task.t_end)
    return int(T / h) + 1, int(T / dt)


def check_run_size(scenario: Scenario, t_end: float | None = None) -> None:
    """Refuse a run whose work (ticks, plant steps) exceeds :data:`MAX_TICKS` or
    :data:`MAX_PLANT_STEPS`, before anything is built.

    Raises
    ------
    ScenarioError
        Naming ``task.t_end`` and the period, with the limit.
    """
    ticks, steps = run_size(scenario, t_end)
    if ticks > MAX_TICKS:
        raise ScenarioError(
            f"task.t_end / control_period gives {ticks} control ticks, at most {MAX_TICKS} "
            f"(memory of the references and logs); shorten task.t_end or use --t-end")
    if steps > MAX_PLANT_STEPS:
        raise ScenarioError(
            f"task.t_end / plant.time_step gives {steps} plant steps, at most "
            f"{MAX_PLANT_STEPS}; shorten task.t_end, use --t-end or a larger plant.time_step")


# --------------------------------------------------------------------------- loading


def load_scenario(path: str | Path | None = None, *, data: str | None = None) -> Scenario:
    """Load and validate a scenario from a YAML file (or a YAML string).

    Parameters
    ----------
    path : str or Path, optional
        YAML file (UTF-8, at most :data:`drake_coop.safe_yaml.MAX_BYTES`). ``None`` with
        ``data=None`` loads the shipped ``paper.yaml`` (the numbers of
        :func:`default_scenario`). A relative ``controller_model`` is looked up beside the
        file first (:func:`drake_coop.resources.resolve_models`), then among the shipped models.
    data : str, optional
        YAML text instead of a file.

    Returns
    -------
    Scenario
        The validated scenario. Without a ``robots`` key, the paper's two robots.

    Raises
    ------
    ScenarioError
        With a one-line message naming the offending field and what is allowed.
    """
    from pydrake.common.yaml import yaml_load_typed

    from drake_coop.resources import default_scenario_path, resolve_models
    from drake_coop.safe_yaml import MAX_BYTES, YamlInputError, read_text_file

    if path is None and data is None:
        return load_scenario(default_scenario_path())   # the shipped paper.yaml
    else:
        try:
            if path is not None:
                data = read_text_file(path)
            elif len(data) > MAX_BYTES:
                raise YamlInputError(f"scenario text is longer than {MAX_BYTES} characters")
        except YamlInputError as exc:
            raise ScenarioError(str(exc)) from None
        untyped = _load_untyped(data)
        if untyped is None:
            raise ScenarioError("the scenario is empty: it must be a mapping of fields "
                                f"({', '.join(f.name for f in dataclasses.fields(Scenario))})")
        _check_structure(untyped, Scenario, "")
        try:
            scenario = yaml_load_typed(
                schema=Scenario, data=data, allow_schema_with_no_yaml=True
            )
        except Exception as exc:  # yaml_load_typed raises plain RuntimeError/TypeError
            raise ScenarioError(_yaml_message(exc)) from None
        if "robots" not in untyped:
            scenario.robots = paper_robots()
    resolve_models(scenario, Path(path).resolve().parent if path is not None else Path.cwd())
    validate(scenario)
    return scenario


def _load_untyped(data: str):
    """The YAML document as plain data, with bounded aliases and no duplicate keys."""
    from drake_coop.safe_yaml import YamlInputError, load_untrusted

    try:
        return load_untrusted(data)
    except YamlInputError as exc:
        raise ScenarioError(str(exc)) from None


def _check_structure(data, schema, path: str) -> None:
    """Unknown keys, wrong types and ``null`` sections, reported with the field's dotted path."""
    import typing

    where = path or "scenario"
    if optional_of(schema) is not schema:       # X | None: null allowed
        if data is None:
            return
        schema = optional_of(schema)
    if dataclasses.is_dataclass(schema):
        hints = typing.get_type_hints(schema)
        if not isinstance(data, dict):
            raise ScenarioError(f"{where} must be a mapping of fields ({', '.join(hints)}), "
                                f"got {show(data)}")
        for key, value in data.items():
            if key not in hints:
                allowed = ", ".join(hints)
                key_text = one_line(key if isinstance(key, str) else show(key), 60)
                raise ScenarioError(f"{path + '.' if path else ''}{key_text} is not a known "
                                    f"field of {where}; allowed: {allowed}")
            _check_structure(value, hints[key], f"{path + '.' if path else ''}{key}")
        return
    origin = typing.get_origin(schema)
    if origin is list:
        if not isinstance(data, list):
            raise ScenarioError(f"{where} must be a list, got {show(data)}")
        (item,) = typing.get_args(schema)
        for i, value in enumerate(data):
            _check_structure(value, item, f"{path}[{i}]")
    elif schema is float:
        # As yaml_load_typed: ints and floats, and strings that Python's float() reads
        # (YAML 1.1 reads '1e-3' as a string). The range is checked by validate().
        if isinstance(data, bool) or not isinstance(data, (int, float, str)):
            raise ScenarioError(f"{where} must be a number, got {show(data)}")
        try:
            float(data)
        except OverflowError:
            raise ScenarioError(f"{where} must be a finite number, got {show(data)}") from None
        except ValueError:
            raise ScenarioError(f"{where} must be a number, got {show(data)}") from None
    elif schema is int:
        if isinstance(data, bool) or not (isinstance(data, int) or (
                isinstance(data, float) and data.is_integer())):
            raise ScenarioError(f"{where} must be an integer, got {show(data)}")
    elif schema is str:
        if not isinstance(data, str):
            raise ScenarioError(f"{where} must be a string, got {show(data)}")


def _yaml_message(exc: Exception) -> str:
    return f"invalid scenario: {one_line(exc, 200)}"


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as YAML text (round-trips through :func:`load_scenario`)."""
    from pydrake.common.yaml import yaml_dump_typed

    return yaml_dump_typed(scenario)


# --------------------------------------------------------------------------- validation


def _is_multiple(period: float, step: float) -> bool:
    ratio = period / step
    return abs(ratio - round(ratio)) < 1e-9 * max(1.0, ratio)


def _choice(value: object, allowed: tuple[str, ...], name: str) -> None:
    if value not in allowed:
        raise ScenarioError(f"{name} must be one of {', '.join(allowed)}, got {show(value)}")


def validate(scenario: Scenario) -> None:
    """Check ranges and consistency of a scenario.

    In order: every number finite and within its :data:`BOUNDS` (lists of their
    :data:`LENGTHS`), the choices (modes, models, names), the cross-field rules (periods,
    phase order, force profile), the reachability of every target and the model files.

    Raises
    ------
    ScenarioError
        On the first problem found, naming the field and the allowed values.
    """
    if len(scenario.robots) != 2:
        raise ScenarioError(f"robots must list exactly 2 robots, got {len(scenario.robots)}")
    check_numbers(scenario, BOUNDS, LENGTHS, error=ScenarioError)

    p = scenario.plant
    if p.time_step > scenario.control_period * (1 + 1e-12):
        raise ScenarioError(
            f"plant.time_step ({p.time_step}) must not exceed control_period "
            f"({scenario.control_period})")
    if not _is_multiple(scenario.control_period, p.time_step):
        raise ScenarioError(
            f"control_period ({scenario.control_period}) must be an integer multiple of "
            f"plant.time_step ({p.time_step}); e.g. 0.001, 0.003, 0.0045 or 0.009 for h = 0.009")
    _choice(p.object_mode, OBJECT_MODES, "plant.object_mode")

    names = [r.name for r in scenario.robots]
    for i, r in enumerate(scenario.robots):
        where = f"robots[{i}]"
        if not (isinstance(r.name, str) and r.name.isidentifier() and len(r.name) <= 40):
            raise ScenarioError(f"{where}.name must be an identifier of at most 40 characters, "
                                f"got {show(r.name)}")
        _choice(r.model, ARM_MODELS, f"{where}.model")
        if r.normal_sign not in (-1.0, 1.0):
            raise ScenarioError(f"{where}.normal_sign must be -1 or 1, got {show(r.normal_sign)}")
        _validate_sensing(r, where, scenario.control_period)
    if len(set(names)) != 2:
        raise ScenarioError(f"robots[].name must be distinct, got {show(names)}")
    if scenario.robots[0].normal_sign == scenario.robots[1].normal_sign:
        raise ScenarioError("robots[].normal_sign must differ (one contact on each side)")

    t = scenario.task
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
    if t.force_amplitude > t.force_mean:
        raise ScenarioError(
            f"task.force_amplitude ({t.force_amplitude}) must not exceed task.force_mean "
            f"({t.force_mean}): the squeeze force must stay >= 0")

    # Imported late: arms imports this module.
    from drake_coop.model_check import check_models
    from drake_coop.references import check_reachable

    check_reachable(scenario)
    check_models(scenario)


# --------------------------------------------------------------------------- sensing


def _cutoff(value: float | None, name: str, h: float) -> None:
    """A low-pass cutoff: null or ``0 < f < 1/(2h)`` (the Nyquist frequency of sampling h)."""
    if value is None:
        return
    nyquist = 1.0 / (2.0 * h)
    if not 0.0 < value < nyquist:
        raise ScenarioError(f"{name} must be null or in (0, {nyquist:g}) Hz (below the "
                            f"Nyquist frequency 1/(2h) for h = {h:g} s), got {show(value)}")


def _validate_sensing(robot: Robot, where: str, h: float) -> None:
    """Sources and the cutoffs of one robot's sensing (issue 7); the numbers' ranges are in
    :data:`BOUNDS`.

    Raises
    ------
    ScenarioError
        Naming the field (``where`` is e.g. ``robots[0]``) and what is allowed.
    """
    _choice(robot.velocity_source, VELOCITY_SOURCES, f"{where}.velocity_source")
    _choice(robot.force_source, FORCE_SOURCES, f"{where}.force_source")
    _cutoff(robot.difference_cutoff_hz, f"{where}.difference_cutoff_hz", h)
    if robot.difference_cutoff_hz is not None and robot.velocity_source != "difference":
        raise ScenarioError(f"{where}.difference_cutoff_hz applies to velocity_source: "
                            f"difference only; set it to null or use difference")
    _cutoff(robot.force_sensor.cutoff_hz, f"{where}.force_sensor.cutoff_hz", h)
