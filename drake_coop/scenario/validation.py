"""Validating a scenario: every number against its range, the choices, the cross-field rules.

:func:`validate` checks every number against its range in :data:`BOUNDS`
(:mod:`drake_coop.scenario.bounds`), lists against :data:`LENGTHS`, then the choices, the
cross-field rules, reachability and the model files (the last two import the plant's
kinematics late, so that this package imports nothing outside it at import time).
"""

import math

from drake_coop.scenario.bounds import Bound, check_numbers, show
from drake_coop.scenario.schema import (
    ARM_MODELS,
    JITTER_DISTRIBUTIONS,
    OBJECT_MODEL_MODES,
    CONTROL_POINTS,
    OBJECT_MODES,
    SQUEEZE_SOURCES,
    Robot,
    Scenario,
    ScenarioError,
)
from drake_coop.scenario.driver import DRIVER_KINDS, GRAVITY_CONVENTIONS, SAFE_COMMANDS, TIME_BASES

_POS = dict(lo_open=True)
#: Allowed range of every number of a scenario, by dotted field (``[]``: any index). A new
#: ``float`` or ``list[float]`` field gets its entry here (``tests/scenario/test_validation.py``
#: checks that every numeric field has one); :func:`validate` then checks it, and the message
#: states the bound.
BOUNDS: dict[str, Bound] = {
    "control_period": Bound(1e-4, 0.1, "s"),
    "plant.time_step": Bound(1e-5, 0.1, "s"),
    "plant.object_mass": Bound(0.0, 20.0, "kg", **_POS),
    "plant.friction": Bound(0.0, 5.0, "", **_POS),
    "plant.stand_clearance": Bound(0.0, 0.05, "m"),
    "plant.pad_modulus": Bound(1e5, 1e9, "Pa"),
    "robots[].base_xyz[]": Bound(-5.0, 5.0, "m"),
    "robots[].base_yaw_deg": Bound(-360.0, 360.0, "deg"),
    "robots[].contact_xy[]": Bound(-5.0, 5.0, "m"),
    "robots[].normals[][]": Bound(-1.0, 1.0),
    "robots[].force_weights[]": Bound(-10.0, 10.0),
    "robots[].ee_rpy_deg[]": Bound(-360.0, 360.0, "deg"),
    "robots[].q_seed[]": Bound(-10.0, 10.0, "rad"),
    "robots[].gains.xi_matrix[][]": Bound(-1.0, 1.0),
    "robots[].home[]": Bound(-5.0, 5.0, "m"),
    "robots[].gains.Lambda": Bound(0.0, 1e3, "1/s", **_POS),
    "robots[].gains.K_R[]": Bound(0.0, 1e4, "N·m·s/rad", **_POS),
    "robots[].gains.k_d": Bound(0.0, 1e4, "1/s", **_POS),
    "robots[].gains.k_F": Bound(0.0, 100.0, "", **_POS),
    "robots[].gains.xi": Bound(0.0, 1.0, "", **_POS),
    "robots[].gains.zeta": Bound(0.0, 100.0, "", **_POS),
    "robots[].gains.beta": Bound(0.0, 1e3, "1/s", **_POS),
    "robots[].gains.momentum_gain": Bound(0.0, 1e4, "1/s", **_POS),
    "robots[].difference_cutoff_hz": Bound(0.0, 1e6, "Hz", **_POS),
    "robots[].anti_windup_gain": Bound(0.0, 1e6, "1/s", **_POS),
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
    "robots[].timing.computation_delay": Bound(0.0, 0.1, "s"),
    "robots[].timing.jitter_scale": Bound(0.0, 0.1, "s"),
    "robots[].timing.seed": Bound(0, 2**63 - 1),
    "robots[].timing.prediction_horizon": Bound(0.0, 0.1, "s", **_POS),
    "robots[].tool.sensor_xyz[]": Bound(-1.0, 1.0, "m"),
    "robots[].tool.sensor_rpy_deg[]": Bound(-360.0, 360.0, "deg"),
    "robots[].tool.pad_xyz[]": Bound(-1.0, 1.0, "m"),
    "robots[].tool.pad_radius": Bound(0.001, 0.1, "m"),
    "robots[].tool.sensor_mass": Bound(0.0, 10.0, "kg", **_POS),
    "robots[].tool.pad_mass": Bound(0.0, 10.0, "kg", **_POS),
    "robots[].q_nominal[]": Bound(-10.0, 10.0, "rad"),
    "robots[].nullspace_gain": Bound(0.0, 100.0, "1/s", **_POS),
    "robots[].driver.num_joints": Bound(1, 64, "joints"),
    "robots[].driver.rate_hz": Bound(1.0, 1e5, "Hz"),
    "robots[].driver.torque_limits[]": Bound(0.0, 1e4, "N·m", **_POS),
    "robots[].driver.max_status_age": Bound(0.0, 10.0, "s", **_POS),
    "robots[].driver.command_timeout": Bound(0.0, 10.0, "s", **_POS),
    "robots[].driver.clock_phase": Bound(0.0, 1.0, "s"),
    "robots[].driver.clock_drift": Bound(-1e-3, 1e-3, ""),
    "robots[].driver.damping[]": Bound(0.0, 1e4, "N·m·s/rad", **_POS),
    **{f"task.{name}": Bound(0.0, 1e4, "s", **_POS) for name in (
        "t_pregrasp", "t_grasp", "t_circle_start", "t_circle_end", "t_release", "t_end")},
    "task.pregrasp_distance": Bound(0.0, 1.0, "m", **_POS),
    "task.circle_top_z": Bound(-5.0, 5.0, "m"),
    "task.circle_radius": Bound(0.0, 1.0, "m"),
    "task.circle_axes[][]": Bound(-1.0, 1.0),
    "task.lift_height": Bound(0.0, 1.0, "m"),
    "task.force_mean": Bound(0.0, 1e3, "N"),
    "task.force_amplitude": Bound(0.0, 1e3, "N"),
    "task.force_omega": Bound(0.0, 100.0, "rad/s"),
    "object_model.mass": Bound(0.0, 100.0, "kg", **_POS),
    "object_model.prior_mass_factor": Bound(0.0, 10.0, "", **_POS),
    "object_model.prior_std_factor": Bound(0.0, 10.0, "", **_POS),
    "object_model.forgetting": Bound(0.5, 1.0, "", **_POS),
    "object_model.mu": Bound(0.0, 5.0, "", **_POS),
    "object_model.margin": Bound(1.0, 10.0, ""),
    "object_model.squeeze_min": Bound(0.0, 1e3, "N"),
    "object_model.contact_stiffness": Bound(0.0, 1e12, "N/m^p"),
    "object_model.contact_exponent": Bound(1.0, 3.0, ""),
    "object_model.squeeze_rate": Bound(0.0, 1e4, "N/s", **_POS),
    "guards.max_force": Bound(0.0, 1e5, "N", **_POS),
    "guards.joint_limit_margin_deg": Bound(0.0, 180.0, "deg"),
    "guards.check_period": Bound(0.0, 100.0, "s", **_POS),
    "cell.start_max_offset": Bound(0.0, 3.2, "rad", **_POS),
    "cell.start_max_speed": Bound(0.0, 10.0, "rad/s", **_POS),
    "cell.start_ramp": Bound(0.0, 10.0, "s"),
    # 3 at least: in lockstep a partner's heartbeat can trail by 2 ticks (CellWatch.beat)
    "cell.partner_silence_ticks": Bound(3, 1000, "ticks"),
    "guards.max_pad_error": Bound(0.0, 10.0, "m", **_POS),
    "guards.max_squeeze_error": Bound(0.0, 1e5, "N", **_POS),
    "guards.max_object_tilt_deg": Bound(0.0, 180.0, "deg", **_POS),
    "guards.max_object_position_error": Bound(0.0, 10.0, "m", **_POS),
}
#: Length of every list of numbers.
#: Lists whose length depends on the arm (``n_i`` joints, ``m_i`` constraints) are checked by
#: :func:`_validate_dimensions` once the model files are read.
LENGTHS: dict[str, int] = {"robots[].base_xyz": 3, "robots[].home": 3,
                           "robots[].contact_xy": 2, "robots[].normals[]": 3,
                           "robots[].ee_rpy_deg": 3, "task.circle_axes": 2,
                           "robots[].tool.sensor_xyz": 3, "robots[].tool.sensor_rpy_deg": 3,
                           "robots[].tool.pad_xyz": 3,
                           "task.circle_axes[]": 3}
#: At most this many robots in one scenario (as many as a run folder holds, results.logs).
MAX_ROBOTS = 8


def _is_multiple(period: float, step: float) -> bool:
    ratio = period / step
    return abs(ratio - round(ratio)) < 1e-9 * max(1.0, ratio)


def _choice(value: object, allowed: tuple[str, ...], name: str) -> None:
    if value not in allowed:
        raise ScenarioError(f"{name} must be one of {', '.join(allowed)}, got {show(value)}")


def validate(scenario: Scenario, *, cache: dict | None = None) -> None:
    """Check ranges and consistency of a scenario.

    In order: every number finite and within its :data:`BOUNDS` (lists of their
    :data:`LENGTHS`), the choices (modes, models, names), the cross-field rules (periods,
    phase order, force profile), the reachability of every target and the model files.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its relative model paths are resolved in place).
    cache : dict, optional
        Results of the reachability check (the costly part: every target of the path through
        each arm's kinematics) by :func:`reach_inputs`, shared between calls on scenarios that
        differ elsewhere (a study's cases). The outcome is that of an uncached call.

    Raises
    ------
    ScenarioError
        On the first problem found, naming the field and the allowed values.
    """
    if not 2 <= len(scenario.robots) <= MAX_ROBOTS:
        raise ScenarioError(f"robots must list 2 to {MAX_ROBOTS} robots (the paper's l >= 2 "
                            f"fingers), got {len(scenario.robots)}")
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
    _choice(scenario.object_model.mode, OBJECT_MODEL_MODES, "object_model.mode")
    _choice(scenario.object_model.squeeze, SQUEEZE_SOURCES, "object_model.squeeze")
    if scenario.object_model.mode != "none" and p.object_mode not in ("rigid", "contact"):
        raise ScenarioError(f"object_model.mode: {scenario.object_model.mode} needs a held "
                            f"object (plant.object_mode rigid or contact), got "
                            f"{show(p.object_mode)}")
    if scenario.object_model.mass is not None and scenario.object_model.mode != "known":
        raise ScenarioError(f"object_model.mass: only mode known gives the controllers a "
                            f"mass; mode {show(scenario.object_model.mode)} ignores it "
                            f"(remove it, or use mode known)")
    if scenario.object_model.squeeze == "friction" and scenario.object_model.mode == "none":
        raise ScenarioError("object_model.squeeze: friction needs object_model.mode known or "
                            "estimated (the controllers must know the object's load)")
    if not isinstance(scenario.object_model.shared, bool):
        raise ScenarioError(f"object_model.shared must be true or false, got "
                            f"{show(scenario.object_model.shared)}")
    if scenario.object_model.shared and scenario.object_model.squeeze != "friction":
        raise ScenarioError("object_model.shared: true needs object_model.squeeze: friction "
                            "(and mode known or estimated): the shared block chooses the "
                            "squeeze online from the estimated load")
    _choice(scenario.object_model.control_point, CONTROL_POINTS, "object_model.control_point")
    if scenario.object_model.couple not in (None, True, False):
        raise ScenarioError(f"object_model.couple: true, false or null is required, got "
                            f"{show(scenario.object_model.couple)}")
    if scenario.object_model.control_point == "contact":
        if scenario.object_model.mode == "none" or p.object_mode != "contact":
            raise ScenarioError("object_model.control_point: contact needs object_model.mode "
                                "known or estimated and plant.object_mode contact (a pad held "
                                "by friction)")

    names = [r.name for r in scenario.robots]
    for i, r in enumerate(scenario.robots):
        where = f"robots[{i}]"
        if not (isinstance(r.name, str) and r.name.isidentifier() and len(r.name) <= 40):
            raise ScenarioError(f"{where}.name must be an identifier of at most 40 characters, "
                                f"got {show(r.name)}")
        if r.model not in ARM_MODELS and not (isinstance(r.model, str)
                                               and r.model.lower().endswith(".urdf")):
            raise ScenarioError(f"{where}.model must be one of {', '.join(ARM_MODELS)} or the "
                                f"path of a .urdf file, got {show(r.model)}")
        for key in ("base_frame", "ee_frame", "sensor_joint"):
            value = getattr(r, key)
            if not (isinstance(value, str) and 0 < len(value) <= 100):
                raise ScenarioError(f"{where}.{key} must be a name of 1 to 100 characters, "
                                    f"got {show(value)}")
        _validate_description(r, where)
        _validate_sensing(r, where, scenario.control_period)
    if len(set(names)) != len(names):
        raise ScenarioError(f"robots[].name must be distinct, got {show(names)}")
    _validate_two_sided(scenario)
    _validate_drivers(scenario)
    _validate_failure_guards(scenario)

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

    # Imported late: NumPy, the model files and the arms' kinematics are needed only here,
    # not to import the package.
    from drake_coop.scenario.arm_check import check_axes, check_dimensions
    from drake_coop.scenario.model_check import check_models
    from drake_coop.scenario.reach import check_reachable

    for i, (robot, n) in enumerate(zip(scenario.robots, check_models(scenario))):
        check_dimensions(robot, n, f"robots[{i}]")
        _validate_driver_joints(robot, n, f"robots[{i}]")
    check_axes(scenario)
    if scenario.object_model.control_point == "contact":
        from drake_coop.kinematics.pose_task import pad_control
        from drake_coop.scenario.reach import robot_kinematics

        for i, r in enumerate(scenario.robots):
            if pad_control(robot_kinematics(r)) == "centre":
                raise ScenarioError(
                    f"object_model.control_point: contact needs arms whose references can "
                    f"follow the pad's material point: robots[{i}] ({r.name}) is redundant "
                    f"with a position-only task (give it ee_rpy_deg); use centre or auto")
    if cache is None:
        check_reachable(scenario)
        return
    key = ("reach", reach_inputs(scenario))
    if key not in cache:
        try:
            check_reachable(scenario)
            cache[key] = None
        except ScenarioError as exc:
            cache[key] = str(exc)
    if cache[key] is not None:
        raise ScenarioError(cache[key])


def _validate_failure_guards(scenario: Scenario) -> None:
    """``guards.grasp_lost`` a boolean (the numbers' ranges are in :data:`BOUNDS`)."""
    if not isinstance(scenario.guards.grasp_lost, bool):
        raise ScenarioError(f"guards.grasp_lost must be true or false, got "
                            f"{show(scenario.guards.grasp_lost)}")


def driver_channels(robot: Robot) -> tuple[str, str]:
    """``(status, command)`` channels of a robot's driver (the defaults for an empty name).

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    d = robot.driver
    status = d.status_channel if d is not None and d.status_channel else f"PANDA_STATUS_{robot.name}"
    command = (d.command_channel if d is not None and d.command_channel
               else f"PANDA_COMMAND_{robot.name}")
    return status, command


def _validate_drivers(scenario: Scenario) -> None:
    """Each robot's ``driver``: its kind, safe command, rate against ``control_period`` and
    channels (non-empty names, all distinct in the scenario)."""
    seen: dict[str, str] = {}
    for i, r in enumerate(scenario.robots):
        where = f"robots[{i}].driver"
        d = r.driver
        if d is not None:
            _choice(d.kind, DRIVER_KINDS, f"{where}.kind")
            _choice(d.safe_command, SAFE_COMMANDS, f"{where}.safe_command")
            _choice(d.time_base, TIME_BASES, f"{where}.time_base")
            _choice(d.gravity, GRAVITY_CONVENTIONS, f"{where}.gravity")
            if d.safe_command == "zero_torque" and d.gravity == "robot_adds":
                raise ScenarioError(f"{where}.safe_command: zero_torque would send -g(q) to a "
                                    "robot that adds its own gravity (gravity: robot_adds), "
                                    "and the arm would fall; use hold")
            if not _is_multiple(scenario.control_period, 1.0 / d.rate_hz):
                raise ScenarioError(f"{where}.rate_hz ({d.rate_hz}) must make control_period "
                                    f"({scenario.control_period}) a whole number of cycles")
            if d.clock_phase >= 1.0 / d.rate_hz:
                raise ScenarioError(f"{where}.clock_phase must be < one driver cycle "
                                    f"(1/rate_hz = {1.0 / d.rate_hz:g} s), got "
                                    f"{show(d.clock_phase)}")
            for key in ("status_channel", "command_channel"):
                value = getattr(d, key)
                if not isinstance(value, str) or len(value) > 100 or not value.isprintable():
                    raise ScenarioError(f"{where}.{key} must be a channel name of at most "
                                        f"100 printable characters, got {show(value)}")
        for key, channel in zip(("status_channel", "command_channel"), driver_channels(r)):
            if channel in seen:
                raise ScenarioError(f"{where}.{key} {show(channel)} is already used by "
                                    f"{seen[channel]}: every driver channel must be distinct")
            seen[channel] = f"{where}.{key}"


def _validate_driver_joints(robot: Robot, n: int, where: str) -> None:
    """The driver's joint count and torque limits against the arm's ``n``."""
    d = robot.driver
    if d is None:
        return
    if d.num_joints is not None and d.num_joints != n:
        raise ScenarioError(f"{where}.driver.num_joints is {d.num_joints} but the arm "
                            f"{show(robot.model)} has {n} joints")
    if d.torque_limits is not None and len(d.torque_limits) != n:
        raise ScenarioError(f"{where}.driver.torque_limits must list {n} limits (one per "
                            f"joint), got {len(d.torque_limits)}")
    if d.damping is not None and len(d.damping) != n:
        raise ScenarioError(f"{where}.driver.damping must list {n} gains (one per joint), "
                            f"got {len(d.damping)}")


def reach_inputs(scenario: Scenario) -> str:
    """The text of everything the reachability check reads: the task and each robot's model,
    frames, base pose, contact point, normals, orientation reference, IK seed and home
    (:mod:`drake_coop.scenario.reach`, :mod:`drake_coop.scenario.task_path`); a cache key.

    Parameters
    ----------
    scenario : Scenario
        The scenario whose task and robots are written out.
    """
    import dataclasses

    return repr((dataclasses.asdict(scenario.task), [
        (r.name, r.model, r.controller_model, r.base_frame, r.ee_frame, r.base_xyz,
         r.base_yaw_deg, r.contact_xy, r.normals, r.ee_rpy_deg, r.q_seed, r.home,
         sorted(r.locked_joints.items()), r.tool, r.q_nominal, r.nullspace_gain)
        for r in scenario.robots]))


def _validate_two_sided(scenario: Scenario) -> None:
    """``rigid`` and ``contact`` hold one object between two arms facing along x; ``contact``
    also between ``l ≥ 3`` arms with one horizontal normal each (the prism of
    :func:`~drake_coop.plant.prism.prism_section`, which checks that they enclose it)."""
    mode = scenario.plant.object_mode
    if mode not in ("rigid", "contact"):
        return
    robots = scenario.robots
    signs = [r.normals[0][0] if len(r.normals) == 1 and len(r.normals[0]) == 3 else 0.0
             for r in robots]
    horizontal = all(len(r.normals) == 1 and len(r.normals[0]) == 3
                     and float(r.normals[0][2]) == 0.0
                     and math.hypot(float(r.normals[0][0]), float(r.normals[0][1])) > 0.0
                     for r in robots)
    if mode == "contact" and len(robots) >= 3:
        if not horizontal:
            raise ScenarioError("plant.object_mode contact with 3 or more robots needs one "
                                "horizontal normal [x, y, 0] per robot (the prism's faces)")
        # The squeezes lambda w_i along the inward normals must be an internal force (no net
        # force, no net moment), or the squeeze alone would push the object off its path.
        w = [float(r.force_weights[0]) for r in robots]
        n = [[float(v) / math.hypot(*map(float, r.normals[0][:2])) for v in r.normals[0][:2]]
             for r in robots]
        fx = sum(wi * ni[0] for wi, ni in zip(w, n))
        fy = sum(wi * ni[1] for wi, ni in zip(w, n))
        mz = sum(wi * (float(r.contact_xy[0]) * ni[1] - float(r.contact_xy[1]) * ni[0])
                 for wi, ni, r in zip(w, n, robots))
        reach = max(math.hypot(*map(float, r.contact_xy)) for r in robots) or 1.0
        if max(abs(fx), abs(fy), abs(mz) / reach) > 1e-6 * sum(abs(wi) for wi in w):
            raise ScenarioError("robots[*].normals, force_weights: with 3 or more robots in "
                                "plant.object_mode contact the squeezes force_weights[0] N_i "
                                "must balance (sum of w_i N_i = 0 and no moment about z)")
    elif len(robots) != 2 or sorted(signs) != [-1.0, 1.0] or any(
            list(map(float, r.normals[0][1:])) != [0.0, 0.0] for r in robots):
        raise ScenarioError(f"plant.object_mode {mode} holds one object between exactly 2 "
                            "robots with normals [-1, 0, 0] and [1, 0, 0]"
                            + (" or 3 or more robots with horizontal normals"
                               if mode == "contact" else "")
                            + "; use planes for other grasps")
    if mode == "contact" and any(r.model not in ("crs_a465", "crs_a255") and r.tool is None
                                 for r in robots):
        raise ScenarioError("plant.object_mode contact needs the shipped arms crs_a465 / "
                            "crs_a255 or arms with a tool (their spherical pads)")


def _validate_description(robot: Robot, where: str) -> None:
    """The fields of an arm from a description package (:mod:`drake_coop.scenario.description`):
    locked joints' positions finite, a tool's flange named; the model file checks the names."""
    import math

    for name, value in robot.locked_joints.items():
        if not (isinstance(value, (int, float)) and math.isfinite(value)):
            raise ScenarioError(f"{where}.locked_joints[{name}] must be a finite position, "
                                f"got {show(value)}")
    if robot.tool is not None and not (isinstance(robot.tool.flange, str)
                                       and 0 < len(robot.tool.flange) <= 100):
        raise ScenarioError(f"{where}.tool.flange must name the link the tool is mounted on "
                            f"(1 to 100 characters), got {show(robot.tool.flange)}")


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
    """Sources and the cutoffs of one robot's sensing; the numbers' ranges are in
    :data:`BOUNDS`.

    Raises
    ------
    ScenarioError
        Naming the field (``where`` is e.g. ``robots[0]``) and what is allowed.
    """
    from drake_coop.control import registry

    for kind, field in registry.SELECTING_FIELD.items():
        _choice(getattr(robot, field), registry.names(kind), f"{where}.{field}")
    chosen = registry.selected(robot)
    for entry in chosen:        # each source checks its own options (the registry answers)
        try:
            entry.check(robot, h)
        except ValueError as exc:
            raise ScenarioError(f"{where}.{exc}") from None
    # An option null by default applies only to the sources that declare it.
    for entry in registry.SOURCES:
        for option in entry.options:
            if entry in chosen or option in {o for c in chosen for o in c.options}:
                continue
            if _read_path(robot, option) is not None and _default_is_none(robot, option):
                field = registry.SELECTING_FIELD[entry.kind]
                users = [s.name for s in registry.SOURCES if option in s.options]
                raise ScenarioError(f"{where}.{option} applies to {field}: "
                                    f"{' or '.join(users)} only; set it to null or use "
                                    f"{' or '.join(users)}")
    _cutoff(robot.force_sensor.cutoff_hz, f"{where}.force_sensor.cutoff_hz", h)
    _validate_timing(robot, f"{where}.timing", h)


def _read_path(entry, path: str):
    """The value at the dotted ``path`` inside a scenario entry."""
    for key in path.split("."):
        entry = getattr(entry, key)
    return entry


def _default_is_none(entry, path: str) -> bool:
    """Whether the field at the dotted ``path`` inside a dataclass entry is null by default."""
    import dataclasses

    *parents, last = path.split(".")
    for key in parents:
        entry = getattr(entry, key)
    field = {f.name: f for f in dataclasses.fields(entry)}[last]
    return field.default is None


def _validate_timing(robot: Robot, where: str, h: float) -> None:
    """Computation delay within the period, a known jitter distribution with a scale that
    keeps a uniform lateness within the period too (:mod:`drake_coop.sensing.latency`)."""
    t = robot.timing
    _choice(t.jitter, JITTER_DISTRIBUTIONS, f"{where}.jitter")
    if t.computation_delay > h * (1 + 1e-9):
        raise ScenarioError(f"{where}.computation_delay must be <= control_period = {h:g} s "
                            f"(a tick's torque is applied before the next tick's), got "
                            f"{show(t.computation_delay)}")
    if t.prediction_horizon is not None and t.prediction_horizon > h * (1 + 1e-9):
        raise ScenarioError(f"{where}.prediction_horizon must be <= control_period = {h:g} s "
                            f"(or null: no delay compensation), got "
                            f"{show(t.prediction_horizon)}")
    if t.jitter == "none" and t.jitter_scale != 0.0:
        raise ScenarioError(f"{where}.jitter_scale applies to a jitter distribution only; set "
                            f"it to 0 or choose jitter: uniform or exponential")
    if t.jitter != "none" and not t.jitter_scale > 0.0:
        raise ScenarioError(f"{where}.jitter_scale must be > 0 s with jitter: {t.jitter}, got "
                            f"{show(t.jitter_scale)}")
    if t.jitter == "uniform" and t.computation_delay + t.jitter_scale > h * (1 + 1e-9):
        raise ScenarioError(f"{where}.jitter_scale: computation_delay + jitter_scale must be <= "
                            f"control_period = {h:g} s for uniform jitter, got "
                            f"{show(t.computation_delay + t.jitter_scale)}")
