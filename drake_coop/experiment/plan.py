"""One resolved plan of a run: its time grid, tick indices, grasp height and arms.

Computed by :func:`plan_run` once per simulated run, the only input below the planning
floor (the builders take their section of it; the stability map and the benchmark plan too):

* ``h``, ``dt`` — control period and plant step, aligned so that every tick is a plant step
  (:func:`~drake_coop.experiment.ticks.time_grid`, by
  :func:`~drake_coop.control.timing.aligned_periods`);
* ``k_grasp``, ``k_release`` — the first held and the first released control tick
  (``⌈t_grasp/h⌉``, ``⌈t_release/h⌉``): the only instants where the plant changes;
* ``k_end`` — the last tick of the run (``min(t_end, task.t_end)``);
* ``z_grasp`` — the contact points' height at the grasp (``circle_top_z − lift_height``);
* ``robots`` — per robot a :class:`RobotPlan`, everything decided from the scenario for that
  arm: its :class:`~drake_coop.plant.arms.Arm` (base, constraints, kinematics), the
  controller's model, the pad's geometry and stiffness (read once, by Drake's parser), the
  control point, the load's mass share, ``λ_d``, the references; ``arms`` are their arms;
* ``object`` — the controllers' object model (:class:`ObjectPlan`), None without one;
* ``clocks`` — per robot the :class:`~drake_coop.control.timing.Clock` its controller side
  ticks on (its computer's clock, :meth:`RunPlan.with_clocks`), None for the run's grid.

Every rule of the ``object_model`` section (``auto`` and ``null`` values) is decided here, once;
the builders read the plan, never the rule again. What is expensive (the pads' files, the
controller's model, the references) is resolved on first use and kept.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from drake_coop.control.deprecation import moved
from drake_coop.experiment.squeeze import friction_squeeze
from drake_coop.experiment.ticks import _run_end, grasp_ticks, num_ticks_until, time_grid

#: Moved names, found here until :mod:`drake_coop.control.deprecation`'s removal date.
_MOVED = {**dict.fromkeys(("GRASP_RAMP", "grasp_ramp"), "drake_coop.experiment.squeeze"),
          **dict.fromkeys(("MAX_PLANT_STEPS", "MAX_TICKS", "check_run_size", "run_size"),
                          "drake_coop.experiment.ticks")}
from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Robot, Scenario, Task


@dataclass(frozen=True)
class Pad:
    """A pad's collision geometry in its arm's model file (the end-effector link's first
    collision geometry): its sphere's ``radius`` (m) and its ``drake:hydroelastic_modulus``
    (Pa), each None when the model has none.

    Attributes
    ----------
    radius : float or None
        The sphere's radius, m.
    modulus : float or None
        The hydroelastic modulus, Pa.
    """

    radius: float | None
    modulus: float | None


def read_pad(urdf: str | Path, ee_frame: str) -> Pad:
    """The :class:`Pad` of the link ``ee_frame`` of the model ``urdf``, parsed by Drake.

    Only a link's own geometry counts (an ``ee_frame`` that is a frame on a link has none).

    Parameters
    ----------
    urdf : str or Path
        The model file.
    ee_frame : str
        The end-effector link.
    """
    from pydrake.geometry import SceneGraph, Sphere
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    plant, scene_graph = MultibodyPlant(0.0), SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    (instance,) = Parser(plant, scene_graph).AddModels(str(urdf))
    if not plant.HasBodyNamed(ee_frame, instance):
        return Pad(None, None)
    ids = plant.GetCollisionGeometriesForBody(plant.GetBodyByName(ee_frame, instance))
    if not ids:
        return Pad(None, None)
    inspector = scene_graph.model_inspector()
    shape = inspector.GetShape(ids[0])
    radius = float(shape.radius()) if isinstance(shape, Sphere) else None
    modulus = None
    for gid in ids:
        props = inspector.GetProximityProperties(gid)
        if props is not None and props.HasProperty("hydroelastic", "hydroelastic_modulus"):
            modulus = float(props.GetProperty("hydroelastic", "hydroelastic_modulus"))
            break
    return Pad(radius, modulus)


@dataclass(frozen=True)
class ControlPoint:
    """Robot ``i``'s pad's material contact point, which its references follow across the
    normal (:func:`~drake_coop.experiment.references.contact_point_reference`).

    Attributes
    ----------
    offset : ndarray, shape (3,)
        The point in the pad's frame, from its centre (the kinematics' ``offset``):
        ``ρ R_WP(q_g)ᵀ n``, ``ρ`` the pad's radius, ``n`` the unit inward normal, ``q_g``
        the posture with the pad's centre at the contact point of the grasp (the point on
        the undeformed surface that touches the box there).
    shift : ndarray, shape (3,)
        ``ρ n`` (world): the point's desired path is the centre's plus this constant vector
        (along the normal, so across it the two paths are the same).
    normal : ndarray, shape (3,)
        The unit outward normal ``N_1`` of the constraint (the squeeze's direction).
    """

    offset: np.ndarray
    shift: np.ndarray
    normal: np.ndarray


def grasp_object(scenario: Scenario, mass: float):
    """The object as the grasp sees it, with ``mass`` (kg): grasp points at the robots'
    contact points (``contact_xy``, at a common height), inward normals ``−N_i`` (first row),
    centre of mass at the points' midpoint (an
    :class:`~drake_coop.control.object.ObjectModel`).

    Parameters
    ----------
    scenario : Scenario
        The scenario (its robots' contact points and normals).
    mass : float
        The object's mass, kg.
    """
    from drake_coop.control.object import ObjectModel

    points = np.array([[r.contact_xy[0], r.contact_xy[1], 0.0] for r in scenario.robots])
    normals = -np.array([np.asarray(r.normals[0], dtype=float) for r in scenario.robots])
    return ObjectModel(mass=mass, com=points.mean(axis=0), grasp_points=points,
                       grasp_normals=normals)


class ObjectPlan:
    """The controllers' object model (``object_model.mode`` known or estimated).

    Parameters
    ----------
    scenario : Scenario
        The scenario (its ``object_model``, robots and plant).

    Attributes
    ----------
    mass : float
        The mass the controllers start from: the truth (or ``object_model.mass``) when
        ``known``, ``prior_mass_factor`` times the truth when ``estimated``.
    model : ObjectModel
        Grasp points at the robots' contact points (``contact_xy``, at a common height),
        inward normals ``−N_i`` (first row), centre of mass at the points' midpoint.
    shares : ndarray
        Each arm's share of ``mass`` (:func:`~drake_coop.control.object.mass_shares`).
    mu : float
        The grasp's friction (``object_model.mu``, else ``plant.friction``).
    """

    def __init__(self, scenario: Scenario):
        from drake_coop.control.object import mass_shares

        om = scenario.object_model
        truth = float(scenario.plant.object_mass)
        if om.mode == "estimated":
            self.mass = om.prior_mass_factor * truth
        else:
            self.mass = float(om.mass) if om.mass is not None else truth
        self.model = grasp_object(scenario, self.mass)
        self.shares = np.asarray(mass_shares(self.model), dtype=float)
        self.mu = om.mu if om.mu is not None else scenario.plant.friction
        #: Whether the controllers estimate the mass (``object_model.mode: estimated``).
        self.estimated = om.mode == "estimated"


class RobotPlan:
    """What one robot's run is, decided from the scenario (see the module's docstring).

    Parameters
    ----------
    run : RunPlan
        The run's plan this robot belongs to.
    index : int
        The robot's index.
    arm : Arm
        Its resolved arm.

    Attributes
    ----------
    index : int
        The robot's index in the scenario.
    robot : Robot
        The robot's scenario entry.
    arm : Arm
        Its resolved arm (kinematics, base pose, constraint).
    """

    def __init__(self, run: "RunPlan", index: int, arm: Arm):
        self._run = run
        self.index = index
        self.robot: Robot = run.scenario.robots[index]
        self.arm = arm

    @property
    def run(self) -> "RunPlan":
        """The run's plan this robot belongs to."""
        return self._run

    @property
    def name(self) -> str:
        """The robot's name."""
        return self.robot.name

    @property
    def task(self) -> Task:
        """The run's task (the paths)."""
        return self._run.scenario.task

    @property
    def object_settings(self):
        """The scenario's ``object_model`` section."""
        return self._run.scenario.object_model

    @property
    def object(self) -> "ObjectPlan | None":
        """The run's :class:`ObjectPlan` (None without an object model)."""
        return self._run.object

    @property
    def object_mode(self) -> str:
        """The plant's ``object_mode``."""
        return self._run.scenario.plant.object_mode

    @property
    def clock(self):
        """The :class:`~drake_coop.control.timing.Clock` its controller side ticks on
        (:meth:`RunPlan.with_clocks`), None for the run's grid."""
        clocks = self._run.clocks
        return None if clocks is None else clocks[self.index]

    @cached_property
    def pad(self) -> Pad:
        """The pad's sphere and modulus in the simulated arm's model file (read once)."""
        return read_pad(self.arm.urdf_path, self.robot.ee_frame)

    @cached_property
    def controller_model(self):
        """The controller's :class:`~drake_coop.control.arm_model.ArmModel` (the controller's
        URDF with the robot's ``model_error`` scales, built once)."""
        from drake_coop.plant.model_error import controller_arm_model

        return controller_arm_model(self.arm, self.robot.model_error)

    @cached_property
    def stiffness(self):
        """The compliant-contact model of the pad (``object_model.contact_stiffness``; by
        default, with an object model in ``contact`` mode, Drake's hydroelastic sphere of
        radius ``r`` pressed on a rigid face, ``λ = π E (δ² − 2δ³/(3r))`` exactly
        (ContactStiffness's ``radius``; ``π E δ²`` to first order in ``δ/r``), from the pad's
        hydroelastic modulus ``E``: ``plant.pad_modulus``, else the arm's model file's); None
        for a rigid contact."""
        from drake_coop.control.object import ContactStiffness

        scenario = self._run.scenario
        om = scenario.object_model
        if om.contact_stiffness is not None:
            return (ContactStiffness(om.contact_stiffness, om.contact_exponent)
                    if om.contact_stiffness > 0 else None)
        if om.mode == "none" or scenario.plant.object_mode != "contact":
            return None
        E = (scenario.plant.pad_modulus if scenario.plant.pad_modulus is not None
             else self.pad.modulus)
        # The sphere's exact law (ContactStiffness's radius), a = π E.
        return None if E is None else ContactStiffness(np.pi * E, 2.0, radius=self.pad.radius)

    def _at_radius(self) -> np.ndarray:
        """``ρ n``: the pad's radius along the unit inward normal ``n = −N_1 / |N_1|``."""
        n = -np.asarray(self.robot.normals[0], dtype=float)
        return self.pad.radius * n / np.linalg.norm(n)

    @cached_property
    def pad_point_control(self) -> str:
        """What the robot's references hold of its pad: ``pose``, ``contact`` or ``centre``.

        The one rule behind ``object_model.control_point``. ``centre`` (the pad's centre E,
        the paper's end-effector point) without an object model, outside the ``contact``
        mode, for a pad without a spherical collision geometry or with ``control_point:
        centre``; otherwise (``auto`` or ``contact``) what the arm can do,
        :func:`~drake_coop.kinematics.pose_task.pad_control`: ``pose`` on an arm whose task
        holds its pad's orientation (six or more joints and ``ee_rpy_deg``: the material
        point then moves with the centre), ``contact`` on a 3-joint arm (the references
        follow the pad's material contact point across the normal, closed form or Drake's
        kinematics), ``centre`` on a redundant arm with a position-only task (validation
        refuses ``control_point: contact`` there)."""
        from drake_coop.kinematics.pose_task import pad_control

        scenario = self._run.scenario
        om = scenario.object_model
        if (om.control_point == "centre" or om.mode == "none"
                or scenario.plant.object_mode != "contact" or self.pad.radius is None):
            return "centre"
        return pad_control(self.arm.kinematics)

    @cached_property
    def control_point(self) -> ControlPoint | None:
        """The pad's :class:`ControlPoint`, None when the arm controls its pad's centre
        (:attr:`pad_point_control`).

        The offset is ``ρ R(q_g)ᵀ n``: ``R(q_g)`` the pad's orientation at the posture with
        its centre at the grasp's contact point (the closed-form or Drake's inverse
        kinematics of a 3-joint arm), or the orientation ``R_d`` the pose task holds. The two
        pads' shifts are opposite (equal radii, opposite normals): the midpoint of the
        points' desired paths is the midpoint of the centres', the object's desired path."""
        kind = self.pad_point_control
        if kind == "centre":
            return None
        shift = self._at_radius()
        n = -np.asarray(self.robot.normals[0], dtype=float)
        kin = self.arm.kinematics
        if kind == "pose":
            R_g = np.asarray(kin.R_d.matrix())
        elif hasattr(kin, "pad_rotation"):
            R_g = kin.pad_rotation(kin.ik(self.arm.c))
        else:
            R_g = kin.rotation(kin.joint_positions(self.arm.c)[0])
        return ControlPoint(offset=R_g.T @ shift, shift=shift,
                            normal=-n / np.linalg.norm(n))

    @cached_property
    def contact_offset(self) -> np.ndarray | None:
        """Where the object's force acts on the pad, from its centre E: in ``contact`` mode
        the pad's surface along the inward normal (``ρ n``, ``ρ`` its sphere's radius: where
        the pad touches the box's face whatever the pad's orientation, also when the
        references follow the pad's material contact point); None (at E) in ``rigid`` mode,
        whose ball constraint holds E itself."""
        if self._run.scenario.plant.object_mode != "contact" or self.pad.radius is None:
            return None
        return self._at_radius()

    @property
    def mass_share(self) -> float | None:
        """The arm's share of the controllers' object mass (None without an object model)."""
        obj = self._run.object
        return None if obj is None else float(obj.shares[self.index])

    @cached_property
    def layout(self):
        """The rows of the robot's reference, ``[q_d, q̇_d, q̈_d, λ_d, held]``
        (:class:`~drake_coop.control.reference_layout.ReferenceLayout` of its joints and
        constraint rows)."""
        from drake_coop.control.reference_layout import ReferenceLayout

        return ReferenceLayout(self.arm.kinematics.n, self.arm.m)

    @cached_property
    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The robot's reference at every control tick, computed once: tick times ``t`` (K,),
        rows ``r`` (K, :attr:`layout` size); the run's own
        (:func:`~drake_coop.experiment.references.reference_samples`, to the plan's ``t_end``)
        or the given trajectory's breaks and values (:meth:`RunPlan.with_references`)."""
        given = self._run.references
        if given is not None:
            traj = given[self.index]
            t = np.asarray(traj.get_segment_times(), dtype=float)
            return t, np.asarray(traj.vector_values(t), dtype=float).T
        from drake_coop.experiment.references import reference_samples

        return reference_samples(self)

    @cached_property
    def reference(self):
        """The robot's reference trajectory, computed once: :attr:`samples` as a first-order
        hold (at a tick exactly that tick's sample), or the one given
        (:meth:`RunPlan.with_references`)."""
        given = self._run.references
        if given is not None:
            return given[self.index]
        from pydrake.trajectories import PiecewisePolynomial

        t, r = self.samples
        return PiecewisePolynomial.FirstOrderHold(t, r.T)

    def lambda_d(self, t: np.ndarray) -> np.ndarray:
        """``λ_d`` at the times ``t`` (K, m): the force weights times the squeeze (29), or the
        friction squeeze (``object_model.squeeze: friction``).

        Parameters
        ----------
        t : numpy.ndarray
            The times (K,), s.

        Returns
        -------
        numpy.ndarray
            ``λ_d`` (K, m), N.
        """
        return (self._run.squeeze(t)[:, None]
                * np.asarray(self.robot.force_weights, dtype=float))


@dataclass(frozen=True)
class RunPlan:
    """The resolved numbers of one run (see the module's docstring).

    Attributes
    ----------
    scenario : Scenario
        The scenario.
    h : float
        The control period, s.
    dt : float
        The plant step, s.
    t_end : float
        The run's end, s.
    k_end : int
        The last tick.
    k_grasp, k_release : int
        The first held and the first released tick.
    z_grasp : float
        The grasp height, m.
    arms : tuple of Arm
        One resolved arm per robot.
    references : tuple of Trajectory or None
        One trajectory per robot instead of the scenario's (e.g. a constant posture for
        Theorem 1), set by :meth:`with_references`; None for :attr:`RobotPlan.reference`.
    clocks : tuple of (Clock or None) or None
        One per robot: the clock its controller side ticks on (:meth:`with_clocks`); None:
        every robot on the run's grid.
    """

    scenario: Scenario
    h: float
    dt: float
    t_end: float
    k_end: int
    k_grasp: int
    k_release: int
    z_grasp: float
    arms: tuple[Arm, ...]
    references: tuple | None = None
    clocks: tuple | None = None

    def with_clocks(self, clocks) -> "RunPlan":
        """The same run with each robot's controller side on its own clock.

        A robot's clock moves every periodic event of its control block (sources,
        controller, predictor) and of its F/T sensor model; its encoders, its computation
        delay and the object layer stay on the run's grid, so a clock is refused with any of
        them.

        Parameters
        ----------
        clocks : sequence of (Clock or None)
            One per robot, in the scenario's order
            (:class:`~drake_coop.control.timing.Clock`; None: the run's grid).

        Returns
        -------
        RunPlan
            The new plan.

        Raises
        ------
        ValueError
            Not one entry per robot, or a clock on a robot with sampled encoders, a
            computation delay or jitter, or in a run with an object model (naming the field).
        TypeError
            An entry neither a Clock nor None.
        """
        from drake_coop.control.timing import Clock

        clocks = tuple(clocks)
        if len(clocks) != len(self.arms):
            raise ValueError(f"clocks: one entry per robot ({len(self.arms)}), got "
                             f"{len(clocks)}")
        for i, (robot, clock) in enumerate(zip(self.scenario.robots, clocks)):
            if clock is None:
                continue
            if not isinstance(clock, Clock):
                raise TypeError(f"clocks[{i}]: a Clock or None is required, got "
                                f"{type(clock).__name__}")
            e, t = robot.encoders, robot.timing
            if (e.noise_std or e.delay_samples or e.counts_per_rev is not None
                    or t.computation_delay > 0.0 or t.jitter != "none"):
                raise ValueError(f"clocks[{i}]: robot {robot.name} must have ideal encoders "
                                 "and no computation delay or jitter (neither follows its "
                                 "clock)")
            if self.scenario.object_model.mode != "none":
                raise ValueError(f"clocks[{i}]: object_model.mode must be none (the object "
                                 "layer does not follow the arm's clock)")
        return replace(self, clocks=clocks)

    def with_references(self, trajectories) -> "RunPlan":
        """The same run following ``trajectories`` instead of the scenario's references.

        Parameters
        ----------
        trajectories : sequence of Trajectory
            One per robot, in the scenario's order: rows ``[q_d, q̇_d, q̈_d, λ_d, held]`` of
            each robot's :attr:`RobotPlan.layout`.

        Returns
        -------
        RunPlan
            The new plan (its robots resolved again on first use).

        Raises
        ------
        ValueError
            Not one trajectory per robot, or rows other than its robot's layout.
        """
        trajectories = tuple(trajectories)
        if len(trajectories) != len(self.arms):
            raise ValueError(f"references: one trajectory per robot ({len(self.arms)}), got "
                             f"{len(trajectories)}")
        plan = replace(self, references=trajectories)
        for robot, traj in zip(plan.robots, trajectories):
            if traj.rows() != robot.layout.size:
                raise ValueError(f"references[{robot.index}] ({robot.name}): "
                                 f"{robot.layout.size} rows [q_d, qdot_d, qddot_d, lambda_d, "
                                 f"held] expected, got {traj.rows()}")
        return plan

    @cached_property
    def robots(self) -> tuple[RobotPlan, ...]:
        """Each robot's :class:`RobotPlan`."""
        return tuple(RobotPlan(self, i, arm) for i, arm in enumerate(self.arms))

    @cached_property
    def object(self) -> ObjectPlan | None:
        """The controllers' object model, None with ``object_model.mode: none``."""
        return None if self.scenario.object_model.mode == "none" else ObjectPlan(self.scenario)

    @property
    def shared(self) -> bool:
        """Whether the run has the shared object-state block (``object_model.shared``)."""
        return self.object is not None and bool(self.scenario.object_model.shared)

    @cached_property
    def controls_contact_point(self) -> bool:
        """Whether every arm follows its pad's material contact point
        (:attr:`RobotPlan.pad_point_control` ``pose`` or ``contact``) instead of its pad's
        centre."""
        return all(r.pad_point_control != "centre" for r in self.robots)

    @cached_property
    def uses_couple(self) -> bool:
        """Whether the feedforward carries the squeeze's couple (``object_model.couple``:
        true, or null when the arms follow their pads' material contact points, whose
        centres then leave the same height); two robots only."""
        om = self.scenario.object_model
        if om.mode == "none" or len(self.scenario.robots) != 2 or om.couple is False:
            return False
        return om.couple is True or self.controls_contact_point

    @cached_property
    def compression_exponent(self) -> float:
        """``p`` of the pads' contact law ``λ = a δᵖ`` (:attr:`RobotPlan.stiffness`; the
        largest over the robots), 1 when no pad is compliant: the squeeze's grasp ramp
        :func:`grasp_ramp` is raised to it, so that every pad's compression ``δ(λ_d)`` rises
        as the quintic itself."""
        exponents = [r.stiffness.exponent for r in self.robots if r.stiffness is not None]
        return max(exponents, default=1.0)

    def squeeze(self, t: np.ndarray) -> np.ndarray:
        """The squeeze at the times ``t`` (K,).

        Without an object model, the task's profile (29) (the paper's). With one:
        ``object_model.squeeze: friction``, the friction squeeze (:func:`friction_squeeze`:
        the least squeeze holding the object model's load in every friction cone along the
        path, times ``margin``, brought in by :func:`grasp_ramp` raised to the pads' law's
        exponent ``p``, :attr:`compression_exponent`); ``profile`` in the ``contact`` mode (a
        grasp held by friction), the profile but never below that friction squeeze,
        ``λ_d(t) = max(λ₂₉(t), λ_hold(t) σ(τ)ᵖ)``.

        The task's path lifts the object from the grasp on while (29) rises from zero over the
        whole lift: until the squeeze holds the weight, the lifted object slides down its pads
        (two UR5s: 0.43 mm, kept for the whole carry); the floor holds it from the ramp's end
        on. The ramp raised to ``p`` presses each pad in along the quintic itself
        (``δ(λ_hold σᵖ) = δ(λ_hold) σ`` on a law ``λ = a δᵖ``: zero rate at the grasp), where a
        linear rise from zero is a compression ``δ ∝ √t`` of infinite rate that the pads cannot
        follow: while the squeeze is still near zero they move along the face and slide on
        it. The rigid and ``planes`` modes keep (29).

        Parameters
        ----------
        t : numpy.ndarray
            The times (K,), s.

        Returns
        -------
        numpy.ndarray
            The squeeze (K,), N (a new array; computed once per distinct ``t`` and plan:
            every robot's ``λ_d`` samples the same ticks).
        """
        times = np.asarray(t, dtype=float)
        key = (times.shape, times.tobytes())
        if key not in self._squeezes:
            self._squeezes[key] = self._squeeze(t)
        return self._squeezes[key].copy()

    @cached_property
    def _squeezes(self) -> dict:
        return {}

    def _squeeze(self, t) -> np.ndarray:
        from drake_coop.scenario.task_path import force_reference

        profile = force_reference(self.scenario.task, t)
        if self.object is None:
            return profile
        p = self.compression_exponent
        if self.scenario.object_model.squeeze == "friction":
            return friction_squeeze(self.scenario, self.object, t, exponent=p)
        if self.scenario.plant.object_mode != "contact":
            return profile
        return np.maximum(profile, friction_squeeze(self.scenario, self.object, t, exponent=p))

    @property
    def switches(self) -> dict[int, bool]:
        """Ticks where the grasp switches on (True) and off (False), within the run."""
        return {k: held for k, held in ((self.k_grasp, True), (self.k_release, False))
                if k < self.k_end}

    @property
    def stops(self) -> list[int]:
        """Where the runner stops the simulation: where the plant changes, and the end."""
        return sorted({*self.switches, self.k_end})


def plan_run(scenario: Scenario, t_end: float | None = None) -> RunPlan:
    """The plan of a run of ``scenario`` to ``min(t_end, task.t_end)``.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario.
    t_end : float or None
        The run's end, s; None for the task's.
    """
    h, dt = time_grid(scenario)
    task = scenario.task
    T = _run_end(scenario, t_end)
    k_grasp, k_release = grasp_ticks(task, h)
    return RunPlan(scenario=scenario, h=h, dt=dt, t_end=T, k_end=num_ticks_until(T, h),
                   k_grasp=k_grasp, k_release=k_release,
                   z_grasp=task.circle_top_z - task.lift_height,
                   arms=tuple(Arm(r, task) for r in scenario.robots))


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
