"""A scenario's typed dataclasses: every number of an experiment, and the paper's own.

A scenario is the single source of truth of a run: the plant (time step, object mode), the
robots (``l >= 2``; model, frames, base pose, constraint planes, home point, gains), the task of Section IV of
the paper (phase times, circle (28), force profile (29)) and the simulation guards.
``scenarios/paper.yaml`` holds the paper's experiment, the one source of its numbers:
:func:`~drake_coop.scenario.loading.default_scenario` and ``paper_robots`` read it. The dataclass defaults below are
what a field takes when a scenario file leaves it out (the paper's robot 1 and task; a test
pins them to ``paper.yaml``). Loading is in :mod:`drake_coop.scenario.loading`, the ranges and rules
in :mod:`drake_coop.scenario.validation`. This module imports only the leaves
:mod:`drake_coop.scenario.bounds` (for the one-line message of :class:`ScenarioError`) and
:mod:`drake_coop.scenario.driver` (a robot's LCM driver section) and
:mod:`drake_coop.scenario.cell` (the ``serve`` processes' start and liveness section).
"""

import math
from dataclasses import dataclass, field
from typing import Optional

from drake_coop.control.deprecation import moved
from drake_coop.control.params import Gains
from drake_coop.scenario.bounds import one_line
from drake_coop.scenario.cell import CellSettings
from drake_coop.scenario.driver import Driver

#: Names this module no longer holds (found here until the removal date of
#: :mod:`drake_coop.control.deprecation`).
_MOVED = {**dict.fromkeys(("FORCE_SOURCES", "VELOCITY_SOURCES"), "drake_coop.control.params"),
          **dict.fromkeys(("DRIVER_KINDS", "SAFE_COMMANDS", "GRAVITY_CONVENTIONS", "TIME_BASES"),
                          "drake_coop.scenario.driver")}

OBJECT_MODES = ("planes", "rigid", "contact", "none")
#: What the controllers know of the held object (``object_model.mode``).
OBJECT_MODEL_MODES = ("none", "known", "estimated")
#: Where the desired squeeze comes from (``object_model.squeeze``).
SQUEEZE_SOURCES = ("profile", "friction")
#: The point each arm controls with an object model (``object_model.control_point``).
CONTROL_POINTS = ("auto", "centre", "contact")
#: The shipped arm models (``urdf/<file>``); a robot's ``model`` may also be a ``.urdf`` path.
SHIPPED_ARMS = {"crs_a465": "crs_a465_3dof.urdf", "crs_a255": "crs_a255_3dof.urdf",
                "coop6": "coop6_6dof.urdf"}
ARM_MODELS = tuple(SHIPPED_ARMS)


class ScenarioError(ValueError):
    """A scenario field is missing, of the wrong type, or out of its allowed range.

    The message is always one line of at most 300 characters.

    Parameters
    ----------
    message : str
        Naming the field and what is allowed (folded onto one line).
    """

    def __init__(self, message: str):
        super().__init__(one_line(message))


@dataclass
class Encoders:
    r"""Joint-position sensors of one robot (:class:`drake_coop.sensing.encoders.Encoders`).

    The reading at tick ``k`` is :math:`δ · \operatorname{round}((q(t_{k-d}) + w_{k-d}) / δ)`
    with ``δ = 2π / counts_per_rev`` (no rounding when ``counts_per_rev`` is null), ``w`` white
    Gaussian noise and ``d = delay_samples``. Defaults: an ideal sensor (the exact ``q(t_k)``).

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


#: Distributions of the sampling jitter (:class:`Timing`).
JITTER_DISTRIBUTIONS = ("none", "uniform", "exponential")


@dataclass
class Timing:
    """Timing realism of one robot's digital controller (:mod:`drake_coop.sensing.latency`).

    The torque ``τ(k)`` computed from ``q(t_k)`` is applied from ``t_k + d + ℓ_k`` (on the
    plant's step grid: from the first plant step at or after it) until the next torque takes
    over; before that the previous torque ``τ(k−1)`` stays on. Defaults: no delay, no jitter
    (the paper's zero-order hold, and no extra block in the diagram).

    Attributes
    ----------
    computation_delay : float
        ``d`` (s, ``0 <= d <= control_period``): the computation time of a tick.
    jitter : str
        Distribution of the lateness ``ℓ_k >= 0`` of each tick: ``none``, ``uniform``
        (``U(0, jitter_scale)``) or ``exponential`` (mean ``jitter_scale``, cut at
        ``control_period − d``).
    jitter_scale : float
        Its scale (s, >= 0; > 0 with a distribution, 0 with ``none``).
    seed : int
        Seed of the lateness (>= 0); ``ℓ_k`` is a deterministic function of (seed, robot, k).
    prediction_horizon : float or None
        Delay compensation (:mod:`drake_coop.control.delay`): the controller predicts its
        inputs over this horizon ``p`` (s, ``0 < p <= control_period``) with its own model and
        the torque on the arm. None (the default): off, the paper's block.
    """

    computation_delay: float = 0.0
    jitter: str = "none"
    jitter_scale: float = 0.0
    seed: int = 0
    prediction_horizon: Optional[float] = None


@dataclass
class ModelError:
    """What the controller's model gets wrong (:mod:`drake_coop.plant.model_error`).

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
        with ``v_s = 0.01 rad/s``; empty: none.
    """

    mass_scale: float = 1.0
    inertia_scale: float = 1.0
    damping_scale: float = 1.0
    payload_mass: float = 0.0
    coulomb_friction: list[float] = field(default_factory=list)


@dataclass
class Tool:
    """The tool mounted on an arm from a description package: a wrist F/T sensor and a
    spherical pad (:mod:`drake_coop.scenario.description`).

    The arm's URDF gets two links and two fixed joints: ``force_sensor`` welded to ``flange``
    by ``flange_sensor_weld`` at ``sensor_xyz`` / ``sensor_rpy_deg`` (the F/T sensor frame, in
    the flange frame), and ``pad`` (a sphere of ``pad_radius``, compliant-hydroelastic like the
    shipped arms' pads) welded to the sensor by ``sensor_pad_weld`` at ``pad_xyz`` (in the sensor
    frame). The pad's centre is the end-effector point (``ee_frame: pad``); the ground-truth
    wrist sensor weighs the sensor and the pad (``sensor_joint: flange_sensor_weld``).

    Attributes
    ----------
    flange : str
        The link the sensor is mounted on (a Panda's ``panda_hand``, a UR5's ``tool0``).
    sensor_xyz : list[float]
        Origin of the sensor frame in the flange frame (m).
    sensor_rpy_deg : list[float]
        Orientation of the sensor frame in the flange frame (roll, pitch, yaw, degrees).
    pad_xyz : list[float]
        Centre of the pad in the sensor frame (m).
    pad_radius : float
        Radius of the spherical pad (m).
    sensor_mass, pad_mass : float
        Masses of the sensor (a solid cylinder of radius 0.035 m, 0.03 m long) and of the pad
        (a solid sphere) (kg).
    """

    flange: str = ""
    sensor_xyz: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    sensor_rpy_deg: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    pad_xyz: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.045])
    pad_radius: float = 0.015
    sensor_mass: float = 0.2
    pad_mass: float = 0.02


@dataclass
class Robot:
    """One arm ("finger") of the cooperative system.

    Attributes
    ----------
    name : str
        Model-instance and subsystem prefix (``robot1``, ``robot2``).
    model : str
        A shipped arm (``crs_a465``, ``crs_a255``: 3 joints; ``coop6``: 6 joints), the path
        of a ``.urdf`` file (absolute, beside the scenario file, or in ``urdf/``), or a
        ``package://`` URL, e.g. ``package://example-robot-data/robots/panda_description/urdf/
        panda.urdf`` (the ``robots`` extra; see :mod:`drake_coop.scenario.description`).
    controller_model : str
        URDF file (relative to ``urdf/`` or absolute) of the controller's own model of the arm;
        empty means the same URDF as the simulated arm (exact model knowledge).
    base_frame, ee_frame : str
        Frames of the URDF: the one welded at the base pose, and the end effector whose origin
        is the contact point ``x_i`` of the constraints (2).
    sensor_joint : str
        The fixed joint between the last link and the wrist force sensor; the bodies outboard
        of it (sensor, pad) are weighed by the ground-truth force sensor.
    base_xyz : list[float]
        Position of the robot's base in the palm frame (m).
    base_yaw_deg : float
        Rotation of the base about the palm z axis (degrees).
    contact_xy : list[float]
        ``(x, y)`` of the contact point at the grasp (m, palm frame); its z is the task's
        ``circle_top_z − lift_height``.
    normals : list[list[float]]
        The object's outward normals at this contact, one row per constraint (``m_i`` rows,
        ``1 <= m_i <= min(n_i, 3)``, linearly independent; normalized when loaded). The
        constraint (2) is ``φ_i(q) = N_i (x_i(q) − c_i)``, ``c_i`` the contact point: each row
        a plane through the contact point, and a positive ``λ`` squeezes the object.
    force_weights : list[float]
        ``λ_d,i(t) = w_i f(t)`` with ``f`` the profile (29): one weight per constraint row.
    ee_rpy_deg : list[float] or None
        Orientation of the end-effector frame held along the task (roll, pitch, yaw in degrees,
        palm frame): required for 6-joint arms (their reference is position and orientation),
        null for 3-joint arms (position only).
    q_seed : list[float] or None
        Initial guess of Drake's inverse kinematics for the home point (arms without a closed
        form); null: zeros.
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
        or ``none`` (``λ̂ := λ_d``, ``ΔF̃ ≡ 0``: the implicit force control of reference [9]),
        or ``momentum`` (the generalized-momentum observer's ``J⁺ᵀ τ̂_ext``, gain
        ``gains.momentum_gain``).
    anti_windup : str or None
        ``force_source: sensor`` or ``momentum`` only: ``conditional`` holds the force
        integral (6) at ticks whose commanded torque exceeds ``actuators.torque_limits``
        (required) at some joint (:mod:`drake_coop.control.anti_windup`); ``back_calculation``
        drives it back by the torque the actuators did not apply, mapped into the
        constraint's force space, at the rate ``anti_windup_gain``; null (the default): the
        paper's (6).
    anti_windup_gain : float or None
        ``anti_windup: back_calculation`` only (required there): the tracking rate ``K_aw``,
        1/s, in ``(0, 1/h]``; null otherwise.
    encoders : Encoders
        The joint-position sensors.
    force_sensor : ForceSensorModel
        The wrist F/T sensor model.
    actuators : Actuators
        Torque limits.
    model_error : ModelError
        The controller's model error, payload and joint friction of the simulated arm.
    timing : Timing
        Computation delay and sampling jitter of the robot's controller.
    locked_joints : dict[str, float]
        Joints of the model held fixed at the given position (rad or m), e.g. a Panda's two
        finger joints: each becomes a fixed joint of the arm's URDF
        (:mod:`drake_coop.scenario.description`). Empty: none.
    tool : Tool or None
        The F/T sensor and pad mounted on ``tool.flange`` (an arm from a description package
        has neither); null: the model has its own ``sensor_joint`` and ``ee_frame``.
    q_nominal : list[float] or None
        Redundant arms (more joints than task coordinates): the posture ``q_nom`` the reference's
        null-space objective pulls towards (:meth:`~drake_coop.kinematics.drake_arm.
        DrakeArmKinematics.redundant_reference`); null: the middle of the joint limits.
    nullspace_gain : float
        Redundant arms: the gain ``K_n`` (1/s) of that objective.
    driver : Driver or None
        The arm's LCM driver (``drake-coop serve`` / ``sim-driver`` only); null: a Panda
        driver with :class:`Driver`'s defaults.
    """

    name: str = "robot1"
    model: str = "crs_a465"
    controller_model: str = ""
    base_frame: str = "base_link"
    ee_frame: str = "pad"
    sensor_joint: str = "flange_sensor_weld"
    base_xyz: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    base_yaw_deg: float = 0.0
    contact_xy: list[float] = field(default_factory=lambda: [0.6, 0.0])
    normals: list[list[float]] = field(default_factory=lambda: [[-1.0, 0.0, 0.0]])
    force_weights: list[float] = field(default_factory=lambda: [1.0])
    ee_rpy_deg: Optional[list[float]] = None
    q_seed: Optional[list[float]] = None
    home: list[float] = field(default_factory=lambda: [0.5, 0.0, 0.6])
    gains: Gains = field(default_factory=Gains)
    velocity_source: str = "observer"
    difference_cutoff_hz: Optional[float] = None
    force_source: str = "observer"
    anti_windup: Optional[str] = None
    anti_windup_gain: Optional[float] = None
    encoders: Encoders = field(default_factory=Encoders)
    force_sensor: ForceSensorModel = field(default_factory=ForceSensorModel)
    actuators: Actuators = field(default_factory=Actuators)
    model_error: ModelError = field(default_factory=ModelError)
    timing: Timing = field(default_factory=Timing)
    locked_joints: dict[str, float] = field(default_factory=dict)
    tool: Optional[Tool] = None
    q_nominal: Optional[list[float]] = None
    nullspace_gain: float = 1.0
    driver: Optional[Driver] = None


@dataclass
class PlantSettings:
    """The simulated cooperative plant.

    Attributes
    ----------
    time_step : float
        Discrete step of the MultibodyPlant (s); must divide the control period.
    object_mode : str
        ``planes`` (the paper's model), ``rigid``, ``contact`` or ``none``. ``rigid`` and
        ``contact`` hold one object between two robots facing along x (a box); ``contact``
        also between three or more robots with horizontal normals (a prism with one face per
        pad, :func:`~drake_coop.plant.prism.prism_section`).
    object_mass : float
        Mass of the carried object in ``rigid`` and ``contact`` modes (kg).
    friction : float
        Coulomb friction coefficient between pads and box (``contact``).
    stand_clearance : float
        How far the stand is lowered while the box is carried around the circle (``contact``,
        m; from the circle's start, when the box is ``lift_height`` up, to its end, back for
        the put-down). The circle (28) passes through the grasp pose at its lowest point, so
        at 0 (the default, the original run) the carried box brushes its stand there
        (43–46 s); ``scenarios/contact.yaml`` uses 10 mm (``scenarios/contact_brush.yaml``: 0).
    pad_modulus : float or None
        Hydroelastic modulus of both pads (``contact``, Pa); None (the default) keeps the arm
        models' own (5 MPa in the shipped URDFs).
    """

    time_step: float = 0.001
    object_mode: str = "planes"
    object_mass: float = 0.5
    friction: float = 1.0
    stand_clearance: float = 0.0
    pad_modulus: Optional[float] = None


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
        Radius of the circle (28), 0.05 m; 0: the object stays at the circle's start.
    circle_axes : list[list[float]]
        ``[u, v]``: the circle (28) is ``c + R sin θ u + R (cos θ − 1) v`` from its start point
        ``c``; the paper's ``u = e_y``, ``v = e_z``. Unit and orthogonal, or one of them zero (a
        straight back-and-forth along the other). Every direction the object moves along while
        held (z for the lift, ``u``, ``v``) must lie in every robot's constraint planes.
    lift_height : float
        Height of the lift from the grasp point to the circle's start (m); 0: no lift (e.g.
        a point held in place, ``m_i = 3``).
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
    circle_axes: list[list[float]] = field(
        default_factory=lambda: [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    lift_height: float = 0.1
    force_mean: float = 32.0
    force_amplitude: float = 18.0
    force_omega: float = 3.0 * math.pi / 40.0


@dataclass
class Guards:
    """Divergence and failure guards of the simulation.

    The first three stop a diverging run (``status: diverged``); the others a run that
    failed its task (``status: failed``), checked on the plant's truth
    (:mod:`drake_coop.experiment.failure`).

    Attributes
    ----------
    max_force : float
        Bound on ``|λ̂|`` and on the measured force (N); beyond it the run stops.
    joint_limit_margin_deg : float
        A joint passing its URDF limit by more than this stops the run (degrees).
    check_period : float
        How often the guards are evaluated (s of simulated time).
    max_pad_error : float
        Bound on each pad's distance from its desired path ``‖x − x_d‖`` (m), the whole run.
    max_squeeze_error : float
        Bound on ``‖λ − λ_d‖`` (N) while the object is held (from 0.5 s after the grasp).
    max_object_tilt_deg : float
        Bound on the held box's tilt since the grasp (degrees; ``contact`` mode).
    max_object_position_error : float
        Bound on the held box's distance from its path (m; ``contact`` mode).
    grasp_lost : bool
        Whether a pad letting go of the box off its stand fails the run (``contact`` mode).
    """

    max_force: float = 500.0
    joint_limit_margin_deg: float = 0.0
    check_period: float = 0.09
    max_pad_error: float = 0.02
    max_squeeze_error: float = 20.0
    max_object_tilt_deg: float = 10.0
    max_object_position_error: float = 0.02
    grasp_lost: bool = True


@dataclass
class ObjectModelSettings:
    """What the controllers know of the held object (:mod:`drake_coop.control.object`).

    Attributes
    ----------
    mode : str
        ``none`` (the paper's control: no object model, the default), ``known`` (each arm's
        feedforward uses the true object) or ``estimated`` (each arm estimates its share of
        the mass online, from ``prior_mass_factor`` times its true share).
    mass : float, optional
        The object's mass the controllers are given in ``known`` mode (kg); default the
        plant's ``object_mass`` (the truth). Refused with any other mode (which ignores it).
    prior_mass_factor : float
        ``estimated``: the prior is this times the true mass (1.5: +50 %).
    prior_std_factor : float
        ``estimated``: the prior's standard deviation as a fraction of the prior.
    forgetting : float
        ``estimated``: the RLS forgetting factor ``ρ`` (per tick).
    squeeze : str
        ``profile`` (the task's force profile (29)) or ``friction`` (the least squeeze that
        holds the object in the friction cone along the desired path, times ``margin``).
    mu : float, optional
        The friction coefficient the controllers assume (default ``plant.friction``).
    margin : float
        ``friction``: the squeeze's safety factor (>= 1); in ``contact`` mode also the
        feedforward's: it passes the object at most ``μ λ_d / margin`` across the normal.
    squeeze_min : float
        ``friction``: the least squeeze (N) whatever the load.
    contact_stiffness : float, optional
        ``a`` of the contact's law ``λ = a δᵖ`` (N/mᵖ) for the compliant-contact reference
        offset; default (None): derived from the plant with an object model (``contact`` mode:
        ``π E_pad`` of a hydroelastic sphere on a rigid face, 1.57e7 N/m² for the shipped
        pads; rigid otherwise); 0: none.
    contact_exponent : float
        ``p`` of that law (2 for a hydroelastic sphere, 1 for a linear spring).
    shared : bool
        ``false`` (the default: decentralized, the arms exchange nothing; the squeeze is
        fixed before the run from the mass the controllers start from) or ``true``: one
        shared block, ``object_state_estimator``
        (:class:`~drake_coop.control.object.ObjectStateEstimator`), reads every arm's mass
        share and chooses the squeeze online from the estimated total load (needs
        ``squeeze: friction``).
    squeeze_rate : float
        ``shared``: the fastest fall of the online squeeze (N/s; it rises at up to 20 N/s).
    control_point : str
        The point of the pad each arm controls: ``centre`` (the pad's centre E, the paper's
        end-effector point), ``contact`` (the pad's *material* contact point: fixed in the pad
        body at its radius from the centre along the inward normal at the grasp, so the box,
        stuck to it by friction, follows its path even when the pad turns; needs an object
        model, ``contact`` mode and an arm whose reference can follow it: a 3-joint arm, or
        one that holds its pad's orientation, six or more joints with ``ee_rpy_deg``) or
        ``auto`` (the default: ``contact`` where it applies, ``centre`` otherwise; the
        paper's control, ``mode: none``, is always ``centre``). Per arm, decided by
        :func:`~drake_coop.experiment.object_blocks.pad_point_control`.
    couple : bool, optional
        Whether each arm's feedforward carries its part of the squeeze's couple (the pads'
        normal forces act through their centres; offset across the normal, they make a couple
        the pads' tangential forces must carry, :mod:`drake_coop.control.couple`):
        true, false, or null (the default: true when the arms follow their pads' contact
        points, whose centres then end at different heights); two robots only.
    """

    mode: str = "none"
    mass: Optional[float] = None
    prior_mass_factor: float = 1.5
    prior_std_factor: float = 0.5
    forgetting: float = 0.995
    squeeze: str = "profile"
    mu: Optional[float] = None
    margin: float = 1.5
    squeeze_min: float = 2.0
    contact_stiffness: Optional[float] = None
    contact_exponent: float = 2.0
    shared: bool = False
    squeeze_rate: float = 1.0
    control_point: str = "auto"
    couple: Optional[bool] = None


@dataclass
class Scenario:
    """A complete experiment.

    Attributes
    ----------
    control_period : float
        Sampling time h of the controllers and observers (s), 9 ms in the paper.
    plant : PlantSettings
        The simulated plant (time step, contact, object mode).
    robots : list[Robot]
        ``l >= 2`` robots (the paper: robot 1 on the left, normal −x; robot 2 on the right).
    task : Task
        The task: its phases, path and desired force (28)–(29).
    guards : Guards
        The run's divergence guards.
    object_model : ObjectModelSettings
        What the controllers know of the held object (default: nothing, the paper's).
    cell : CellSettings or None
        How the ``drake-coop serve`` processes of a cell start and watch each other (null:
        :class:`CellSettings`' defaults); unused by simulated runs.
    """

    control_period: float = 0.009
    plant: PlantSettings = field(default_factory=PlantSettings)
    robots: list[Robot] = field(default_factory=list)
    task: Task = field(default_factory=Task)
    guards: Guards = field(default_factory=Guards)
    object_model: ObjectModelSettings = field(default_factory=ObjectModelSettings)
    cell: Optional[CellSettings] = None


# --------------------------------------------------------------------------- timing


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
