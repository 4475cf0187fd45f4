"""Force arrows, the held box and the replay's camera (``drake_coop/results/viz.py``)."""

from __future__ import annotations

import base64
import math
import re

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake_coop.plant.arms import Arm
from drake_coop.results.export import shared_meshcat
from drake_coop.results.viz import (
    ARROW_KINDS,
    HEAD_LENGTH,
    ForceArrows,
    arrow_pose,
    held_box_pose,
    held_disc_pose,
    workspace_camera,
)
from drake_coop.scenario import default_scenario, load_scenario

msgpack = pytest.importorskip("msgpack")


def test_arrow_tip_is_tail_plus_scaled_force():
    rng = np.random.default_rng(3)
    for _ in range(50):
        p, F, scale = rng.normal(size=3), rng.normal(size=3) * 40, rng.uniform(1e-3, 1e-2)
        X, L = arrow_pose(p, F, scale)
        assert L == pytest.approx(scale * math.sqrt(F @ F), rel=1e-14)
        np.testing.assert_allclose(X.translation(), p, atol=1e-15)
        np.testing.assert_allclose(X.multiply(np.array([0.0, 0.0, L])), p + scale * F,
                                   atol=1e-12)
        R = X.rotation().matrix()
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    X, L = arrow_pose(np.ones(3), np.zeros(3), 0.01)
    assert L == 0.0


def test_held_disc_touches_every_pad_on_a_circle():
    rng = np.random.default_rng(5)
    for l in (3, 4, 5):        # l pads equally spaced on a circle of radius R, any phase
        centre, R, r_pad = rng.normal(size=3), rng.uniform(0.05, 0.3), 0.015
        angles = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(l) / l
        points = [centre + R * np.array([np.cos(a), np.sin(a), 0.0]) for a in angles]
        c, radius = held_disc_pose(points, r_pad)
        np.testing.assert_allclose(c, centre, atol=1e-12)
        for p in points:       # the rim is at each pad's surface
            assert np.linalg.norm(p[:2] - c[:2]) - radius == pytest.approx(r_pad, abs=1e-12)


def test_held_box_spans_the_gap_between_the_pads():
    p1, p2, r = np.array([0.6, 0.01, 0.52]), np.array([0.8192, 0.03, 0.54]), 0.015
    centre, size = held_box_pose(p1, p2, r)
    assert centre[0] - size[0] / 2 == pytest.approx(p1[0] + r)   # touches pad 1's surface
    assert centre[0] + size[0] / 2 == pytest.approx(p2[0] - r)   # and pad 2's
    np.testing.assert_allclose(centre[1:], (p1[1:] + p2[1:]) / 2)


@pytest.mark.parametrize("name", ["paper", "three_arms", "six_joint"])
def test_camera_sees_every_arm_from_outside(name):
    s = default_scenario() if name == "paper" else load_scenario(f"scenarios/{name}.yaml")
    arms = [Arm(r, s.task) for r in s.robots]
    camera, target = workspace_camera(arms, 0.585)
    forward = (target - camera) / np.linalg.norm(target - camera)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)                       # the camera keeps +z up
    points = [a.p_base for a in arms] + [np.asarray(r.home) for r in s.robots]
    points += [a.fk(np.zeros(np.size(a.q_min))) for a in arms]   # straight up: their tops
    for p in points:
        d = p - camera
        vertical = math.degrees(math.atan2(d @ up, d @ forward))
        horizontal = math.degrees(math.atan2(d @ right, d @ forward))
        # Meshcat's camera: 75° vertical field of view, wider horizontally (landscape).
        assert abs(vertical) < 34.0 and abs(horizontal) < 34.0, (p, vertical, horizontal)
    assert camera[2] > target[2] and camera[1] < 0
    # Outside the robots' circle: no base is nearer to the camera than to the target.
    for a in arms:
        assert np.linalg.norm(a.p_base - camera) > np.linalg.norm(a.p_base - target)


def _scene(html: str) -> list[dict]:
    """The Meshcat commands embedded in a StaticHtml page."""
    blobs = re.findall(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', html)
    return [msgpack.unpackb(base64.b64decode(b), raw=False) for b in blobs]


def _last(scene: list[dict], kind: str, path: str, prop: str | None = None):
    found = [m for m in scene if m.get("type") == kind and m.get("path") == path
             and (prop is None or m.get("property") == prop)]
    return found[-1] if found else None


@pytest.mark.parametrize("held", [False, True])
def test_published_arrows_and_box_match_the_inputs(held):
    s = default_scenario()
    arms = [Arm(r) for r in s.robots]
    meshcat = shared_meshcat()
    meshcat.Delete()
    b = DiagramBuilder()
    arrows = b.AddSystem(ForceArrows(meshcat, arms, scale=0.002, show_held_box=True))
    diagram = b.Build()
    simulator = Simulator(diagram)
    ctx = arrows.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    q = [np.array([0.1, 0.5, 1.2]), np.array([-0.1, 0.4, 1.3])]
    lambda_d, lambda_hat = [30.0, 20.0], [29.0, 0.0]
    F_meas = [np.array([-31.0, 1.0, -2.0]), np.array([0.0, 0.0, 0.0])]
    for i, arm in enumerate(arms):
        ref = np.zeros(11)
        ref[9], ref[10] = lambda_d[i], float(held)
        arrows.GetInputPort(f"{arm.name}_state").FixValue(ctx, np.r_[q[i], np.zeros(3)])
        arrows.GetInputPort(f"{arm.name}_reference").FixValue(ctx, ref)
        arrows.GetInputPort(f"{arm.name}_F_meas").FixValue(ctx, F_meas[i])
        arrows.GetInputPort(f"{arm.name}_lambda_hat").FixValue(ctx, [lambda_hat[i]])
    simulator.Initialize()                  # the initialization publish draws
    scene = _scene(meshcat.StaticHtml())
    for i, arm in enumerate(arms):
        p_E = arm.fk(q[i])
        n = np.array([arm.s, 0.0, 0.0])
        expected = {"desired": -lambda_d[i] * n, "measured": -F_meas[i],
                    "estimated": -lambda_hat[i] * n}
        for kind, F in expected.items():
            path = f"/drake/coop/forces/{arm.name}/{kind}"
            visible = _last(scene, "set_property", path, "visible")["value"]
            L = 0.002 * np.linalg.norm(F)
            assert visible == (L > 1e-3)
            if not visible:
                continue
            M = np.array(_last(scene, "set_transform", path)["matrix"]).reshape(4, 4).T
            tail = p_E + np.array([0.0, 0.0, ARROW_KINDS[kind][1]])
            np.testing.assert_allclose(M[:3, 3], tail, atol=1e-12)
            np.testing.assert_allclose(M[:3, 2], F / np.linalg.norm(F), atol=1e-12)
            head = np.array(_last(scene, "set_transform", f"{path}/head")["matrix"])
            assert head[14] == pytest.approx(L)          # the tip at tail + 0.002 F
            scale = _last(scene, "set_property", f"{path}/shaft", "scale")["value"]
            assert scale == pytest.approx([1.0, 1.0, L - HEAD_LENGTH])
    box = "/drake/coop/held_object"
    assert _last(scene, "set_property", box, "visible")["value"] == held
    if held:
        M = np.array(_last(scene, "set_transform", box)["matrix"])
        np.testing.assert_allclose(M[12:15], (arms[0].fk(q[0]) + arms[1].fk(q[1])) / 2,
                                   atol=1e-12)


def test_three_arms_draw_a_held_disc_touching_each_pad_and_arrows_along_their_normals():
    s = load_scenario("scenarios/three_arms.yaml")
    arms = [Arm(r, s.task) for r in s.robots]
    meshcat = shared_meshcat()
    meshcat.Delete()
    b = DiagramBuilder()
    arrows = b.AddSystem(ForceArrows(meshcat, arms, scale=0.002, show_held_box=True))
    simulator = Simulator(b.Build())
    ctx = arrows.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    for arm in arms:                       # every pad at its contact point (a symmetric grasp)
        q_i = arm.ik(arm.c)
        ref = np.zeros(11)
        ref[9], ref[10] = 25.0, 1.0
        arrows.GetInputPort(f"{arm.name}_state").FixValue(ctx, np.r_[q_i, np.zeros(3)])
        arrows.GetInputPort(f"{arm.name}_reference").FixValue(ctx, ref)
        arrows.GetInputPort(f"{arm.name}_F_meas").FixValue(ctx, np.zeros(3))
        arrows.GetInputPort(f"{arm.name}_lambda_hat").FixValue(ctx, [25.0])
    simulator.Initialize()
    scene = _scene(meshcat.StaticHtml())
    box = "/drake/coop/held_object"
    assert _last(scene, "set_property", box, "visible")["value"] is True
    centre = np.array(_last(scene, "set_transform", box)["matrix"])[12:15]
    radius = _last(scene, "set_property", f"{box}/scaled", "scale")["value"][0]
    for arm in arms:
        # The contact points stand 0.1 m from the object's axis: the rim at the pad's surface.
        assert np.linalg.norm(arm.c[:2] - centre[:2]) - radius == pytest.approx(0.015, abs=1e-9)
        M = np.array(_last(scene, "set_transform", f"/drake/coop/forces/{arm.name}/desired")
                     ["matrix"]).reshape(4, 4).T
        np.testing.assert_allclose(M[:3, 2], -arm.N[0], atol=1e-12)   # into the object
