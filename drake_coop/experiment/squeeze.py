"""The squeeze an object model chooses before the run (``object_model.squeeze``): the least
squeeze that holds the object's load in every friction cone along the path
(:func:`friction_squeeze`), brought in after the grasp and out before the release by
:func:`grasp_ramp`. :meth:`~drake_coop.experiment.plan.RunPlan.squeeze` decides which applies.
"""

from __future__ import annotations

import numpy as np

from drake_coop.scenario.schema import Scenario, Task

__all__ = ["GRASP_RAMP", "friction_squeeze", "grasp_ramp"]

#: The squeeze's rise after the grasp and fall before the release (s): :func:`grasp_ramp`
#: in :func:`friction_squeeze` and :meth:`RunPlan.squeeze`.
GRASP_RAMP = 1.0


def grasp_ramp(task: Task, t: np.ndarray, ramp: float = GRASP_RAMP,
               exponent: float = 1.0) -> np.ndarray:
    """The squeeze's grasp ramp at the times ``t``: ``σ(τ)ᵖ``, ``σ`` the quintic time scaling
    (:func:`~drake_coop.scenario.task_path.quintic`: zero rate and acceleration at both ends),
    ``τ = min(t − t_grasp, t_release − t) / ramp`` clipped to [0, 1], ``p`` = ``exponent``;
    0 outside ``[t_grasp, t_release]``, 1 within it when ``ramp`` is 0.

    A squeeze ``λ σᵖ`` on a contact ``λ = a δᵖ`` compresses it by ``δ(λ) σ``: the pad is
    pressed in along the quintic, from rest, as the path moves.

    Parameters
    ----------
    task : Task
        The task (its ``t_grasp`` and ``t_release``, s).
    t : numpy.ndarray
        The times (K,), s.
    ramp : float
        The ramp's length, s.
    exponent : float
        ``p``: the pads' contact law's exponent.

    Returns
    -------
    numpy.ndarray
        ``σ(τ)ᵖ`` at the times (K,), between 0 and 1.
    """
    from drake_coop.scenario.task_path import quintic

    t = np.atleast_1d(np.asarray(t, dtype=float))
    held = (t >= task.t_grasp) & (t <= task.t_release)
    if ramp <= 0.0:
        return held.astype(float)
    s = quintic(np.minimum(t - task.t_grasp, task.t_release - t) / ramp)[0]
    return np.where(held, s ** float(exponent), 0.0)


def friction_squeeze(scenario: Scenario, obj, t: np.ndarray,
                     ramp: float = GRASP_RAMP, exponent: float = 1.0) -> np.ndarray:
    """``object_model.squeeze: friction``: the least squeeze holding the object in every
    friction cone along the desired path (:func:`~drake_coop.control.object.squeeze_for_grasp`
    on the loads of :func:`~drake_coop.control.object.load_distribution`, the controllers'
    object ``obj``, its ``mu``, ``margin``, ``squeeze_min``), between the grasp and the
    release, brought in over ``ramp`` seconds after the grasp and out before the release by
    :func:`grasp_ramp` (``exponent``: the contact law's, :attr:`RunPlan.compression_exponent`;
    ``ramp`` 0: none) (N, one per time).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    obj : ~drake_coop.experiment.plan.ObjectPlan
        The controllers' object (its ``model`` and ``mu``).
    t : numpy.ndarray
        The times (K,), s.
    ramp : float
        The ramps' length, s.
    exponent : float
        The grasp ramp's exponent (the pads' contact law's ``p``).

    Returns
    -------
    numpy.ndarray
        The squeeze (K,), N.
    """
    from drake_coop.control.object import load_distribution, squeeze_for_grasp
    from drake_coop.scenario.task_path import cartesian_reference

    om, task = scenario.object_model, scenario.task
    t = np.atleast_1d(np.asarray(t, dtype=float))
    xdd = cartesian_reference(task, scenario.robots[0], t)[2]
    lam = np.zeros_like(t)
    held = (t >= task.t_grasp) & (t <= task.t_release)
    for k in np.flatnonzero(held):
        loads = load_distribution(obj.model, xdd[k])
        lam[k] = squeeze_for_grasp(loads, obj.model.grasp_normals, obj.mu, om.margin,
                                   lambda_min=om.squeeze_min)[0]
    return lam * grasp_ramp(task, t, ramp, exponent)
