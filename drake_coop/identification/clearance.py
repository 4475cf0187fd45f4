"""Before an excitation is driven over the wire: no contact between two arms, or between an arm
and the stand, the object or the floor, along every arm's planned motion — checked with
Drake's geometry (a ``SceneGraph``'s point-pair penetration query).

The check plant holds the scenario's arms where the run welds them (with their own proximity
geometry: the pads) and, in ``contact`` mode, the object, its stand and the floor
(:func:`~drake_coop.plant.grasp.add_contact_object`). The description packages' collision
meshes are ``.stl``, which Drake 1.51 does not read as collision geometry
(:mod:`~drake_coop.scenario.description`), so every moving link also gets a **capsule**
along its kinematic chain: from the link's origin to each child joint's origin, of radius
:data:`LINK_RADIUS` (the skeleton of the arm, thickened; a coarse stand-in for the links'
shape, on the safe side for thin links, short of it for bulky ones). Pairs within one arm are
not checked (adjacent links overlap by construction), nor the floor against the capsule of an
arm's first moving link (it starts at the base, which stands on the floor).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from pydrake.geometry import Capsule, ProximityProperties
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.framework import DiagramBuilder

__all__ = ["LINK_RADIUS", "SAMPLE_PERIOD", "first_contact"]

#: The capsules' radius, m.
LINK_RADIUS = 0.04
#: The planned motion is checked every this long, s.
SAMPLE_PERIOD = 0.02


def _segment_pose(p: np.ndarray) -> tuple[RigidTransform, float]:
    """The pose (in the parent link's frame) and length of a capsule from the origin to ``p``."""
    length = float(np.linalg.norm(p))
    R = RotationMatrix.MakeFromOneVector(p / length, 2)
    return RigidTransform(R, 0.5 * p), length


def _build(scenario, radius: float):
    from drake_coop.plant.arms import Arm
    from drake_coop.plant.cooperative import add_arms

    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(time_step=0.0), builder)
    arms = add_arms(plant, scene_graph, [Arm(robot, scenario.task) for robot in scenario.robots])
    grasp = None
    if scenario.plant.object_mode == "contact":
        from drake_coop.plant.grasp import add_contact_object

        grasp = add_contact_object(plant, scene_graph, scenario)
    props = ProximityProperties()
    standing = set()             # the clearance capsules of each arm's first moving link
    for handles in arms:
        world = plant.world_body()
        for j in plant.GetJointIndices(handles.instance):
            joint = plant.get_joint(j)
            parent = joint.parent_body()
            if parent.index() == world.index() or parent.name() == handles.arm.base_frame:
                continue                 # the base: welded where the arm stands
            p = joint.frame_on_parent().GetFixedPoseInBodyFrame().translation()
            if np.linalg.norm(p) < 1e-6:
                continue
            X, length = _segment_pose(np.asarray(p, float))
            geometry = plant.RegisterCollisionGeometry(
                parent, X, Capsule(radius, length),
                f"{parent.name()}_{joint.name()}_clearance", props)
            before = [plant.get_joint(i) for i in plant.GetJointIndices(handles.instance)
                      if plant.get_joint(i).child_body().index() == parent.index()]
            if before and (before[0].parent_body().name() == handles.arm.base_frame
                           or before[0].parent_body().index() == world.index()):
                standing.add(geometry)
    plant.Finalize()
    diagram = builder.Build()
    return diagram, plant, scene_graph, arms, grasp, standing


def first_contact(scenario, motions: dict[int, Callable[[np.ndarray], np.ndarray]],
                  postures: list[np.ndarray], duration: float, *,
                  radius: float = LINK_RADIUS, period: float = SAMPLE_PERIOD) -> str | None:
    """The first contact along the planned motion, as one line, or None if there is none.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its arms, their poses, the object mode).
    motions : dict of int to Callable
        Robot index → ``q(t)`` for times (K,) → positions (K, n): the arms that move.
    postures : list of numpy.ndarray
        Every arm's current reading (n,), rad: where the arms that do not move stay.
    duration : float
        The motion's length, s.
    radius : float
        The links' capsules' radius, m.
    period : float
        The check's sampling period, s.

    Returns
    -------
    str or None
        ``"<geometry> of <arm> and <geometry> of <arm or body> at t = ... s (depth ... mm)"``,
        or None.
    """
    diagram, plant, scene_graph, arms, grasp, standing = _build(scenario, radius)
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    if grasp is not None:               # the object on its stand, where a run starts it
        grasp.initialize(plant, plant_context)
    inspector = scene_graph.model_inspector()
    t = np.append(np.arange(0.0, duration, period), duration)
    paths = [motions[i](t) if i in motions else np.tile(np.asarray(postures[i], float),
                                                         (t.size, 1))
             for i in range(len(arms))]
    owner = {}
    names = {int(h.instance): h.arm.name for h in arms}

    def who(geometry) -> tuple[str, str]:
        if geometry not in owner:
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
            owner[geometry] = (names.get(int(body.model_instance()),
                                         plant.GetModelInstanceName(body.model_instance())),
                               inspector.GetName(geometry))
        return owner[geometry]

    port = plant.get_geometry_query_input_port()
    for k in range(t.size):
        for h, path in zip(arms, paths):
            plant.SetPositions(plant_context, h.instance, path[k])
        query = port.Eval(plant_context)
        for pair in query.ComputePointPairPenetration():
            (a, name_a), (b, name_b) = who(pair.id_A), who(pair.id_B)
            if a == b:
                continue
            # the first link's capsule starts at the base, which stands on the floor
            if (pair.id_A in standing and b not in names.values()) or (
                    pair.id_B in standing and a not in names.values()):
                if "floor" in (name_a + name_b):
                    continue
            return (f"{name_a} of {a} and {name_b} of {b} touch at t = {t[k]:.2f} s "
                    f"(depth {pair.depth * 1e3:.1f} mm)")
    return None
