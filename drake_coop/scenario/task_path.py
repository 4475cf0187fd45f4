"""The task's Cartesian paths (28) and force profile (29), from the scenario's numbers alone.

Every phase moves the end-effector point along a Cartesian path, rest to rest, with the
quintic time scaling ``σ(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` (zero velocity and acceleration at both
ends), so that the whole reference is C² in time:

====================  =====================================  ======================================
phase                 time                                   path of robot i
====================  =====================================  ======================================
free (approach)       ``[0, t_pregrasp]``                    home → pre-grasp (straight line)
free (approach)       ``[t_pregrasp, t_grasp]``              pre-grasp → grasp, along the normal
lift                  ``[t_grasp, t_circle_start]``          grasp → circle start, 0.1 m up
circle (28)           ``[t_circle_start, t_circle_end]``     ``y = R sin θ``, ``z = z_top − R + R cos θ``
put-down              ``[t_circle_end, t_release]``          circle start → grasp
return                ``[t_release, t_release + Δ]``         grasp → pre-grasp
return                ``[t_release + Δ, t_end]``             pre-grasp → home
====================  =====================================  ======================================

with ``θ(t) = 2π σ((t − t_i)/(t_f − t_i))`` on the circle (``θ̇ = θ̈ = 0`` at ``t_i``, ``t_f``),
drawn in the plane of ``task.circle_axes = [u, v]`` (the paper: y and z):
``x = c − R v + R sin θ u + R cos θ v`` from its start point ``c``; ``Δ = t_grasp − t_pregrasp``,
the grasp point ``(contact_xy, z_top − lift)`` and the pre-grasp point moved out along the
object's first outward normal by ``pregrasp_distance``.

The desired squeeze force (29), ``f(t)``, times each constraint row's weight
(``robots[i].force_weights``, the paper: one row of weight 1): ``f_mean (t − t_grasp)/(t_circle_start − t_grasp)`` on the
lift, ``f_mean + f_amp sin(ω (t − t_circle_start))`` on the circle and
``f_mean (1 − (t − t_circle_end)/(t_release − t_circle_end))`` on the put-down; zero otherwise.
With the paper's numbers this is ``16(t − 15)/5``, ``32 + 18 sin(3π(t − 25)/40)`` and
``32 − 16(t − 65)/5``.

(Joint references and the reference signal are :mod:`drake_coop.experiment.references`.) This
module needs only NumPy and the scenario's dataclasses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_coop.scenario.schema import Robot, Task


def quintic(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quintic time scaling σ(τ) and its first two derivatives, τ clipped to [0, 1].

    Parameters
    ----------
    tau : numpy.ndarray
        The normalized time τ.
    """
    tau = np.clip(tau, 0.0, 1.0)
    s = tau ** 3 * (10 - 15 * tau + 6 * tau ** 2)
    ds = 30 * tau ** 2 * (1 - tau) ** 2
    dds = 60 * tau * (1 - tau) * (1 - 2 * tau)
    return s, ds, dds


def first_normal(robot: Robot) -> np.ndarray:
    """The object's first outward unit normal at the robot's contact (the squeeze direction).

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    n = np.asarray(robot.normals[0], dtype=float)
    return n / np.linalg.norm(n)


def waypoints(task: Task, robot: Robot) -> dict[str, np.ndarray]:
    """Home, pre-grasp, grasp and circle-start points of one robot (palm frame, m).

    Parameters
    ----------
    task : Task
        The task.
    robot : Robot
        The robot.

    Returns
    -------
    dict of str to numpy.ndarray
        Name → point (3,), m.
    """
    z_top = task.circle_top_z
    x, y = (float(v) for v in robot.contact_xy)
    grasp = np.array([x, y, z_top - task.lift_height])
    return {
        "home": np.asarray(robot.home, dtype=float),
        "pregrasp": grasp + task.pregrasp_distance * first_normal(robot),
        "grasp": grasp,
        "circle_start": np.array([x, y, z_top]),
    }


@dataclass(frozen=True)
class Segment:
    """A rest-to-rest straight line from ``a`` to ``b`` during ``[t0, t1]``.

    Attributes
    ----------
    t0, t1 : float
        Its start and end, s.
    a, b : numpy.ndarray
        Its start and end points (3,), m, palm frame.
    """

    t0: float
    t1: float
    a: np.ndarray
    b: np.ndarray


def segments(task: Task, robot: Robot) -> list[Segment]:
    """The straight-line segments of the path (the circle is handled apart).

    Parameters
    ----------
    task : Task
        The task.
    robot : Robot
        The robot.

    Returns
    -------
    list of Segment
        The segments, in time order.
    """
    w = waypoints(task, robot)
    back = task.t_release + (task.t_grasp - task.t_pregrasp)
    return [
        Segment(0.0, task.t_pregrasp, w["home"], w["pregrasp"]),
        Segment(task.t_pregrasp, task.t_grasp, w["pregrasp"], w["grasp"]),
        Segment(task.t_grasp, task.t_circle_start, w["grasp"], w["circle_start"]),
        Segment(task.t_circle_end, task.t_release, w["circle_start"], w["grasp"]),
        Segment(task.t_release, back, w["grasp"], w["pregrasp"]),
        Segment(back, task.t_end, w["pregrasp"], w["home"]),
    ]


def cartesian_reference(task: Task, robot: Robot, t: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Desired end-effector position, velocity and acceleration at times ``t``.

    Parameters
    ----------
    task : Task
        The task.
    robot : Robot
        The robot.
    t : numpy.ndarray
        The times, s.

    Returns
    -------
    x_d, xdot_d, xddot_d : ndarray, shape (N, 3)
        m, m/s, m/s², palm frame.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    x = np.zeros((t.size, 3))
    xd = np.zeros_like(x)
    xdd = np.zeros_like(x)
    w = waypoints(task, robot)
    x[:] = w["home"]
    for seg in segments(task, robot):
        T = seg.t1 - seg.t0
        sel = t >= seg.t0
        s, ds, dds = quintic((t[sel] - seg.t0) / T)
        d = seg.b - seg.a
        x[sel] = seg.a + s[:, None] * d
        xd[sel] = (ds / T)[:, None] * d
        xdd[sel] = (dds / T ** 2)[:, None] * d
    # The circle (28) overrides [t_circle_start, t_circle_end).
    T = task.t_circle_end - task.t_circle_start
    sel = (t >= task.t_circle_start) & (t < task.t_circle_end)
    s, ds, dds = quintic((t[sel] - task.t_circle_start) / T)
    th, thd, thdd = 2 * np.pi * s, 2 * np.pi * ds / T, 2 * np.pi * dds / T ** 2
    R = task.circle_radius
    u, v = (np.asarray(a, dtype=float) for a in task.circle_axes)
    centre = w["circle_start"] - R * v
    # Written per axis so that the paper's u = e_y, v = e_z give its very doubles (28).
    x[sel] = centre + (R * np.sin(th))[:, None] * u + (R * np.cos(th))[:, None] * v
    xd[sel] = ((R * np.cos(th) * thd)[:, None] * u + (-R * np.sin(th) * thd)[:, None] * v)
    xdd[sel] = ((-R * np.sin(th) * thd ** 2 + R * np.cos(th) * thdd)[:, None] * u
                + (-R * np.cos(th) * thd ** 2 - R * np.sin(th) * thdd)[:, None] * v)
    return x, xd, xdd


def force_reference(task: Task, t: np.ndarray) -> np.ndarray:
    """The desired squeeze force λ_d of (29) (N) at times ``t``.

    Parameters
    ----------
    task : Task
        The task (its phase times and force profile).
    t : numpy.ndarray
        The times, s.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    f = np.zeros_like(t)
    up = (t >= task.t_grasp) & (t < task.t_circle_start)
    f[up] = task.force_mean * (t[up] - task.t_grasp) / (task.t_circle_start - task.t_grasp)
    circle = (t >= task.t_circle_start) & (t < task.t_circle_end)
    f[circle] = task.force_mean + task.force_amplitude * np.sin(
        task.force_omega * (t[circle] - task.t_circle_start))
    down = (t >= task.t_circle_end) & (t <= task.t_release)
    f[down] = task.force_mean * (1.0 - (t[down] - task.t_circle_end)
                                 / (task.t_release - task.t_circle_end))
    return f
