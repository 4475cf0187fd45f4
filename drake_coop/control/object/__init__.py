"""The held object as part of the controller: its model, the load each arm carries, the
squeeze that holds it, its mass estimated online, and the compliant contact's stiffness.

The paper's controllers know nothing about the object: its weight and inertia reach each arm
as a load that the force observer (22) cannot tell from squeeze. The blocks here add, per arm
and beside the paper's (which stay unchanged):

* :class:`ObjectModel`: mass, centre of mass, inertia and the grasp (contact points, inward
  normals), all in an object frame aligned with the world (the desired path translates the
  object without turning it);
* :func:`grasp_matrix`, :func:`object_wrench`, :func:`load_distribution`: the wrench the
  contacts must apply along the desired motion, ``w = [m (a − g); I α + ω × I ω]`` about the
  centre of mass, split by the grasp matrix ``G`` into its minimum-norm (load) part
  ``f_L = G⁺ w`` and an internal (squeeze) part in the null space of ``G`` (the load
  distribution of Walker, Freeman & Marcus with equal weights; Uchiyama & Dauchez's
  external/internal decomposition);
* :func:`mass_shares`: each contact's share ``m_i`` of the mass in that split (the lever rule
  for two opposing pads), so that arm ``i``'s load is ``f_i = m_i (a_d − g)``;
* :class:`LoadFeedforward` (LeafSystem): ``τ_ff,i = J_x(q)ᵀ m_i (a_d − g)``, added to the
  paper's torque (13);
* :class:`MassEstimator` (LeafSystem): recursive least squares of ``m_i`` from the arm's own
  model, ``q``, the commanded ``τ`` and the observer's signals (no F/T sensor);
* :func:`squeeze_for_grasp`, :func:`max_squeeze`: the least squeeze that keeps every contact in
  its friction cone, times a margin, within the torque limits;
* :class:`ObjectStateEstimator` (LeafSystem, shared by the arms): the total mass and centre
  of mass from every arm's share, and the squeeze chosen online from them, rate limited, into
  every arm's ``λ_d``; :class:`CompressedReference` (LeafSystem): ``q_d`` pressed in by the
  online ``λ_d``'s compression;
* :class:`ContactStiffness`: ``λ = a δᵖ``, the compression ``δ(λ)`` that
  :class:`~drake_coop.control.finger.FingerLaw` takes as the constrained position's reference
  on a compliant contact.

What each arm's blocks know, and communication: the object model (or its prior) and the shared
desired path ``a_d(t)`` — both given before the run, as the paper's desired force (29) is —
and the arm's own model and signals. The arms exchange nothing during the run (the paper's
decentralization is kept): each estimates its own share ``m_i``. The one exception is
opt-in and named: :class:`ObjectStateEstimator`, a single block that reads every arm's share
and gives every arm the squeeze chosen online from the estimated total load (with
:class:`CompressedReference`, each arm's own, pressing its joint reference in by that
squeeze's compression on a compliant contact).

Why (22) then estimates the squeeze net of the load: with the arm's dynamics
``H q̈ + C q̇ + D q̇ + g = τ_13 + τ_ff + J_φᵀ λ + J_xᵀ f_t`` (``f_t`` the object's load on the
pad, ``f_t = −f_i`` when the object follows its path) and ``τ_ff = J_xᵀ f_i``, the load terms
cancel and the arm obeys the paper's model (1) with ``τ = τ_13``. The force observer is left
as it is: its closed form (22) is (21) with ``τ = τ_13``, i.e. (21) with the feedforward moved
to the model side, ``λ̂ = J⁺ᵀ {H q̈̂_r + C q̇_r + D q̇_r + g − (τ − τ_ff)}``. Nothing of
the feedforward is fed into the observer: it sees the arm as the paper's.

This package imports only NumPy and Drake. One module per concept: the object's model
(model), the grasp and the load split (grasp), the squeeze (squeeze), the contact's
stiffness (stiffness), and one per LeafSystem (feedforward, mass_estimator, state_estimator,
compressed_reference); every name is imported from here.
"""

from drake_coop.control.object.model import GRAVITY, ObjectModel
from drake_coop.control.object.grasp import (
    contact_jacobian,
    grasp_matrix,
    internal_part,
    load_distribution,
    mass_shares,
    object_wrench,
)
from drake_coop.control.object.squeeze import max_squeeze, squeeze_for_grasp
from drake_coop.control.object.stiffness import ContactStiffness
from drake_coop.control.object.feedforward import LoadFeedforward
from drake_coop.control.object.mass_estimator import MassEstimator
from drake_coop.control.object.state_estimator import ObjectStateEstimator
from drake_coop.control.object.compressed_reference import CompressedReference

__all__ = [
    "GRAVITY",
    "ObjectModel",
    "contact_jacobian",
    "grasp_matrix",
    "object_wrench",
    "load_distribution",
    "internal_part",
    "mass_shares",
    "squeeze_for_grasp",
    "max_squeeze",
    "ContactStiffness",
    "LoadFeedforward",
    "MassEstimator",
    "ObjectStateEstimator",
    "CompressedReference",
]
