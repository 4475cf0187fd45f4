"""The cooperative plant: both arms and the object in one discrete MultibodyPlant (SAP).

The world frame *is* the paper's palm frame: origin at the base of the A465 (robot 1), x axis
towards the A255 (robot 2). Object modes (``PlantSettings.object_mode``):

``planes`` (default, the paper's model exactly)
    End effector i is held on its ``m_i`` planes ``N_i (x − c_i) = 0`` and free along their
    common tangent directions: per arm, a light "slider" body on ``3 − m_i`` prismatic joints
    along an orthonormal tangent basis (gravity off) hangs from an anchor welded to the world,
    and ``AddBallConstraint`` ties the end-effector point to it (``m_i = 3``: to the anchor
    itself, a point held in place). The constraint force is along the normals only (up to the
    slider's negligible inertia). The paper: ``N_i = ±e_x``, prismatic y and z joints.
``rigid``
    One rigid object (``object_mass``) with its contact faces ``b_2 − b_1 = 0.2192 m`` apart,
    moving in y–z at fixed x on prismatic joints, ball-constrained to both end effectors: the
    arms carry it together and feel each other through it.
``contact``
    A box on a stand, held by friction at the two hydroelastic pads (see :mod:`drake_coop.plant.grasp`).
``none``
    Free arms.

The constraints exist only while the object is held: :meth:`CoopPlant.set_held` switches them
on (moving the sliders/object onto the end effectors first) and off, between simulation
segments. While released, the slider/object joints are locked.

Ground-truth force sensing is in :mod:`drake_coop.plant.wrist` (the reaction of the weld
between the last link and the force-sensor body, less the sensor and pad's own weight and
inertia); the controllers never read it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, Sequence

import numpy as np
from pydrake.geometry import Box, SceneGraph
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import (
    Joint,
    ModelInstanceIndex,
    MultibodyConstraintId,
    PrismaticJoint,
    RigidBody,
    SpatialInertia,
    UnitInertia,
)
from pydrake.systems.framework import Context, DiagramBuilder

from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Scenario

if TYPE_CHECKING:
    from drake_coop.plant.grasp import ContactObject


class _PlantSection(Protocol):
    """What the plant is built from: the part of a run's plan
    (:class:`~drake_coop.experiment.plan.RunPlan`, a layer above, which has these) the plant
    reads, in the manner of Drake's ``ApplyMultibodyPlantConfig(config, builder)``.

    Attributes
    ----------
    scenario : Scenario
        The scenario (its ``plant`` section, task and robots).
    dt : float
        The plant step on the run's time grid, s.
    arms : sequence of Arm
        The resolved arms, one per robot.
    """

    scenario: Scenario
    dt: float
    arms: Sequence[Arm]

#: Mass of the planes-mode sliders and of the object carriage (kg): negligible against the
#: end effectors but large enough for a well-conditioned SAP problem.
LIGHT_MASS = 1e-3


@dataclass
class ArmHandles:
    """One arm inside the cooperative plant.

    Attributes
    ----------
    arm : Arm
        The robot's resolved description.
    instance : ModelInstanceIndex
        Its model instance in the plant.
    ee_body : RigidBody
        The end-effector (pad) body.
    sensor_weld : Joint
        The weld joint of the wrist force sensor (its reaction is the measured force).
    sensor_bodies : list of RigidBody
        The bodies the sensor carries (outboard of the weld).
    """

    arm: Arm
    instance: ModelInstanceIndex
    ee_body: RigidBody
    sensor_weld: Joint
    sensor_bodies: list[RigidBody]


@dataclass
class CoopPlant:
    """The cooperative plant and what the rest of the package needs to reach in it.

    Attributes
    ----------
    plant, scene_graph
        The MultibodyPlant (discrete, SAP) and its SceneGraph.
    arms : list[ArmHandles]
        One per robot, in the scenario's order.
    mode : str
        The object mode.
    constraint_ids : list
        Ball constraints (one per arm in ``planes`` and ``rigid``), inactive by default.
    slider_joints : list[list[PrismaticJoint]]
        Per constraint body: its prismatic joints (planes: one per tangent direction of each
        arm; rigid: y and z of the object).
    slider_axes : list[ndarray]
        Per constraint body: the joints' unit axes (rows, palm frame).
    slider_bodies : list[RigidBody]
        The bodies the end effectors are tied to (planes: one per arm; rigid: the object).
    object_body : RigidBody or None
        The carried object (``rigid`` and ``contact``).
    grasp : ContactObject or None
        The ``contact`` mode's box and stand (None in the other modes).
    """

    plant: MultibodyPlant
    scene_graph: SceneGraph
    arms: list[ArmHandles]
    mode: str
    constraint_ids: list[MultibodyConstraintId] = field(default_factory=list)
    slider_joints: list[list[PrismaticJoint]] = field(default_factory=list)
    slider_axes: list[np.ndarray] = field(default_factory=list)
    slider_bodies: list[RigidBody] = field(default_factory=list)
    object_body: RigidBody | None = None
    grasp: ContactObject | None = None    # the contact mode's box and stand

    # ------------------------------------------------------------------ state helpers
    def arm_positions(self, context: Context, i: int) -> np.ndarray:
        """The joint positions of arm i from a plant context.

        Parameters
        ----------
        context : Context
            The plant's context.
        i : int
            The arm's index.
        """
        return self.plant.GetPositions(context, self.arms[i].instance)

    def set_arm_state(self, context: Context, i: int, q: np.ndarray,
                      v: np.ndarray | None = None) -> None:
        """Set joint positions (and velocities, default zero) of arm i.

        Parameters
        ----------
        context : Context
            The plant's context.
        i : int
            The arm's index.
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray or None
            Joint velocities (n,), rad/s; None for zero.
        """
        inst = self.arms[i].instance
        self.plant.SetPositions(context, inst, q)
        self.plant.SetVelocities(context, inst, np.zeros(len(q)) if v is None else v)

    def ee_position(self, context: Context, i: int) -> np.ndarray:
        """End-effector point of arm i in the palm frame.

        Parameters
        ----------
        context : Context
            The plant's context.
        i : int
            The arm's index.

        Returns
        -------
        numpy.ndarray
            The point (3,), m.
        """
        return self.plant.EvalBodyPoseInWorld(context, self.arms[i].ee_body).translation()

    def ee_velocity(self, context: Context, i: int) -> np.ndarray:
        """Translational velocity of the end-effector point of arm i.

        Parameters
        ----------
        context : Context
            The plant's context.
        i : int
            The arm's index.

        Returns
        -------
        numpy.ndarray
            The velocity (3,), m/s, palm frame.
        """
        return self.plant.EvalBodySpatialVelocityInWorld(
            context, self.arms[i].ee_body).translational()

    def is_held(self, context: Context) -> bool:
        """Whether the grasp constraints are active.

        Parameters
        ----------
        context : Context
            The plant's context.
        """
        return bool(self.constraint_ids) and self.plant.GetConstraintActiveStatus(
            context, self.constraint_ids[0])

    def set_held(self, context: Context, held: bool) -> None:
        """Switch the grasp on (sliders/object moved onto the end effectors) or off.

        In ``planes`` and ``rigid`` modes this activates/deactivates the ball constraints and
        unlocks/locks the slider joints; in ``contact`` and ``none`` modes it does nothing (the
        grasp is physical or absent).

        Parameters
        ----------
        context : Context
            The plant's context.
        held : bool
            On or off.
        """
        if not self.constraint_ids:
            return
        plant = self.plant
        if held:
            p = [self.ee_position(context, i) for i in range(len(self.arms))]
            v = [self.ee_velocity(context, i) for i in range(len(self.arms))]
            if self.mode == "planes":
                targets = list(zip(p, v))
            else:  # rigid: one object between both end effectors
                targets = [(0.5 * (p[0] + p[1]), 0.5 * (v[0] + v[1]))]
            for joints, axes, (pos, vel) in zip(self.slider_joints, self.slider_axes, targets):
                for joint, axis in zip(joints, axes):
                    joint.Unlock(context)
                    joint.set_translation(context, axis @ pos)
                    joint.set_translation_rate(context, axis @ vel)
        else:
            for joints in self.slider_joints:
                for joint in joints:
                    joint.set_translation_rate(context, 0.0)
                    joint.Lock(context)
        for cid in self.constraint_ids:
            plant.SetConstraintActiveStatus(context, cid, held)


def _light_inertia(mass: float = LIGHT_MASS, radius: float = 0.01) -> SpatialInertia:
    return SpatialInertia(mass, np.zeros(3), UnitInertia.SolidSphere(radius))


def tangent_basis(N: np.ndarray) -> np.ndarray:
    """Orthonormal basis (rows) of the directions orthogonal to the normals ``N`` (rows).

    Gram–Schmidt over ``e_x, e_y, e_z`` in that order, so that for ``N = ±e_x`` the basis is
    exactly ``e_y, e_z`` (the paper's slider joints).

    Parameters
    ----------
    N : numpy.ndarray
        The constraint normals (m, 3) or (3,).

    Returns
    -------
    numpy.ndarray
        The tangent directions (3 − m, 3), unit rows.
    """
    N = np.atleast_2d(np.asarray(N, dtype=float))
    normals = list(np.linalg.qr(N.T)[0].T)       # orthonormal rows spanning the normals
    tangents: list[np.ndarray] = []
    for e in np.eye(3):
        t = e - sum(((b @ e) * b for b in normals + tangents), np.zeros(3))
        if np.linalg.norm(t) > 0.5:
            tangents.append(t / np.linalg.norm(t))
    return np.array(tangents).reshape(-1, 3)


def _add_slider(plant: MultibodyPlant, name: str, p_anchor: np.ndarray, axes: np.ndarray,
                body_inertia: SpatialInertia, instance: ModelInstanceIndex
                ) -> tuple[RigidBody, list[PrismaticJoint]]:
    """A body moving along ``axes`` (rows, 0 to 2 of them) from an anchor welded at
    ``p_anchor``: anchor → carriage … → body, one prismatic joint per axis (none: the body is
    the anchor, fixed)."""
    anchor = plant.AddRigidBody(f"{name}_anchor", instance, _light_inertia())
    plant.WeldFrames(plant.world_frame(), anchor.body_frame(), RigidTransform(p_anchor))
    if len(axes) == 0:
        return anchor, []
    frames = [anchor]
    for k in range(len(axes) - 1):
        frames.append(plant.AddRigidBody(f"{name}_carriage{'' if k == 0 else k}", instance,
                                         _light_inertia()))
    body = plant.AddRigidBody(f"{name}", instance, body_inertia)
    frames.append(body)
    paper = len(axes) == 2 and np.array_equal(axes, np.eye(3)[1:])
    joints = []
    for k, axis in enumerate(axes):
        label = "yz"[k] if paper else f"t{k}"
        joints.append(plant.AddJoint(PrismaticJoint(
            f"{name}_{label}", frames[k].body_frame(), frames[k + 1].body_frame(), axis)))
    return body, joints


def add_arms(plant: MultibodyPlant, scene_graph: SceneGraph | None,
             arms: Sequence[Arm]) -> list[ArmHandles]:
    """Parse every arm, weld its base frame at its pose in the palm frame.

    Parameters
    ----------
    plant : MultibodyPlant
        The plant (not finalized).
    scene_graph : SceneGraph or None
        Its scene graph, for the arms' geometry.
    arms : sequence of Arm
        The run's resolved arms (:attr:`RunPlan.arms
        <drake_coop.experiment.plan.RunPlan.arms>`), one per robot, each with its robot's
        entry (model instances are prefixed with the robot's name).

    Returns
    -------
    list of ArmHandles
        One per arm, in order.
    """
    handles = []
    for arm in arms:
        parser = Parser(plant, scene_graph, model_name_prefix=arm.robot.name)
        (instance,) = parser.AddModels(str(arm.urdf_path))
        X_WB = RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base)
        plant.WeldFrames(plant.world_frame(),
                         plant.GetFrameByName(arm.base_frame, instance), X_WB)
        weld = plant.GetJointByName(arm.sensor_joint, instance)
        handles.append(ArmHandles(
            arm=arm,
            instance=instance,
            ee_body=plant.GetFrameByName(arm.ee_frame, instance).body(),
            sensor_weld=weld,
            sensor_bodies=[],    # filled after Finalize (the bodies outboard of the weld)
        ))
    return handles


def _outboard_bodies(plant: MultibodyPlant, weld: Joint) -> list[RigidBody]:
    """The bodies the wrist sensor carries: the weld's child and every body outboard of it
    (through any joint, welds included), in body-index order."""
    children: dict[int, list[RigidBody]] = {}
    for j in plant.GetJointIndices(weld.model_instance()):
        joint = plant.get_joint(j)
        children.setdefault(int(joint.parent_body().index()), []).append(joint.child_body())
    found, stack = [], [weld.child_body()]
    while stack:
        body = stack.pop()
        found.append(body)
        stack.extend(children.get(int(body.index()), []))
    return sorted(found, key=lambda b: int(b.index()))


def build_plant(builder: DiagramBuilder, plan: _PlantSection) -> CoopPlant:
    """Add the cooperative plant (with its SceneGraph) to ``builder``, from the run's plan.

    Parameters
    ----------
    builder : DiagramBuilder
        The builder the plant and its scene graph are added to.
    plan : RunPlan
        The run's plan (a :class:`~drake_coop.experiment.plan.RunPlan`): its plant step ``dt`` on the run's time grid
        (:func:`drake_coop.experiment.ticks.time_grid`: a multiple of it is exactly the
        control period), its resolved arms (one :class:`~drake_coop.plant.arms.Arm` per
        robot, shared with the run) and its scenario's ``plant`` section (object mode, object
        mass, friction) and task.

    Returns
    -------
    CoopPlant
        Finalized plant with handles to arms, constraints and object.
    """
    scenario = plan.scenario
    settings = scenario.plant
    time_step = plan.dt
    config = MultibodyPlantConfig(
        time_step=time_step,
        discrete_contact_approximation="sap",
        contact_model="hydroelastic_with_fallback" if settings.object_mode == "contact"
        else "point",
    )
    plant, scene_graph = AddMultibodyPlant(config, builder)
    plant.set_name("plant")
    scene_graph.set_name("scene_graph")
    # Live (not sampled) output ports. With sampled ports (the default in Drake 1.51) the
    # plant's step is an unrestricted update that runs *before* the controllers' discrete
    # updates at the same instant, so a controller ticking with the plant would read the state
    # one plant step ahead. Live ports make the step a discrete update, simultaneous with the
    # controllers' (all read x(t_k)); the force sensor then reports the forces of the step
    # that starts at t_k, under the torque τ(k) of that tick.
    plant.SetUseSampledOutputPorts(False)
    arms = add_arms(plant, scene_graph, plan.arms)
    from drake_coop.plant.model_error import add_payload  # the unmodelled payloads

    for h, robot in zip(arms, scenario.robots):
        add_payload(plant, h.instance, robot.model_error.payload_mass, robot.sensor_joint)
    coop = CoopPlant(plant=plant, scene_graph=scene_graph, arms=arms,
                     mode=settings.object_mode)

    mode = settings.object_mode
    if mode == "planes":
        for h in arms:
            inst = plant.AddModelInstance(f"{h.arm.name}_plane")
            axes = tangent_basis(h.arm.N)
            # The anchor: the contact point less its tangent part (for the paper (b, 0, 0)).
            p_anchor = h.arm.c - axes.T @ (axes @ h.arm.c)
            body, joints = _add_slider(plant, f"{h.arm.name}_plane_slider", p_anchor, axes,
                                       _light_inertia(), inst)
            plant.set_gravity_enabled(inst, False)
            coop.slider_bodies.append(body)
            coop.slider_joints.append(joints)
            coop.slider_axes.append(axes)
            # A translucent picture of each plane, for the 3D replay.
            anchor = plant.GetBodyByName(f"{h.arm.name}_plane_slider_anchor", inst)
            for j, normal in enumerate(h.arm.N):
                R = RotationMatrix.MakeFromOneVector(normal, 0)
                plant.RegisterVisualGeometry(
                    anchor, RigidTransform(R, np.array([0.0, 0.0, scenario.task.circle_top_z
                                                        - scenario.task.circle_radius])),
                    Box(0.002, 0.3, 0.3), f"{h.arm.name}_plane{'' if j == 0 else j}",
                    np.array([0.3, 0.6, 1.0, 0.25]))
            coop.constraint_ids.append(plant.AddBallConstraint(
                h.ee_body, np.zeros(3), body, np.zeros(3)))
    elif mode == "rigid":
        inst = plant.AddModelInstance("object")
        b1, b2 = (h.arm.b for h in arms)
        xc = 0.5 * (b1 + b2)
        width = abs(b2 - b1)
        m = settings.object_mass
        inertia = SpatialInertia(m, np.zeros(3), UnitInertia.SolidBox(width, 0.08, 0.08))
        axes = np.eye(3)[1:]
        body, joints = _add_slider(plant, "object", np.array([xc, 0.0, 0.0]), axes, inertia,
                                   inst)
        plant.RegisterVisualGeometry(body, RigidTransform(), Box(width - 0.03, 0.08, 0.08),
                                     "object_visual", np.array([0.8, 0.6, 0.2, 1.0]))
        coop.object_body = body
        coop.slider_bodies.append(body)
        coop.slider_joints.append(joints)
        coop.slider_axes.append(axes)
        for h in arms:
            p_OP = np.array([h.arm.b - xc, 0.0, 0.0])
            coop.constraint_ids.append(plant.AddBallConstraint(h.ee_body, np.zeros(3), body, p_OP))
    elif mode == "contact":
        from drake_coop.plant.grasp import add_contact_object

        coop.grasp = add_contact_object(plant, scene_graph, scenario)
        coop.object_body = coop.grasp.box
    plant.Finalize()
    for h in arms:
        h.sensor_bodies = _outboard_bodies(plant, h.sensor_weld)
    return coop


def initialize_plant_context(coop: CoopPlant, context: Context, q0: list[np.ndarray],
                             z_grasp: float) -> None:
    """Arms at rest at ``q0``, constraints off, sliders/object locked at the contact points
    (the paper: y = 0 at the grasp height).

    Parameters
    ----------
    coop : CoopPlant
        The plant.
    context : Context
        The plant's context.
    q0 : list of numpy.ndarray
        Each arm's initial joint positions (n,), rad.
    z_grasp : float
        The grasp height, m (palm frame).
    """
    plant = coop.plant
    for i, q in enumerate(q0):
        coop.set_arm_state(context, i, q)
    if coop.mode == "planes":
        points = [h.arm.c for h in coop.arms]
    else:
        points = [np.array([0.0, 0.0, z_grasp])] * len(coop.slider_joints)
    for joints, axes, p in zip(coop.slider_joints, coop.slider_axes, points):
        for j, axis in zip(joints, axes):
            j.set_translation(context, axis @ p)
            j.set_translation_rate(context, 0.0)
            j.Lock(context)
    for cid in coop.constraint_ids:
        plant.SetConstraintActiveStatus(context, cid, False)
    if coop.grasp is not None:
        coop.grasp.initialize(plant, context)
