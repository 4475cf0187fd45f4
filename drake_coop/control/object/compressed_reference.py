"""One arm's joint reference pressed into a compliant contact by the compression of its
online ``λ_d`` (:class:`CompressedReference`, a LeafSystem)."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    InputPort,
    LeafSystem,
    OutputPort,
)

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object.model import _vector
from drake_coop.control.object.stiffness import ContactStiffness


class CompressedReference(LeafSystem):
    r"""One arm's joint reference pressed into a compliant contact by the compression its
    current ``λ_d`` asks for, online (for a ``λ_d`` chosen during the run, e.g. by
    :class:`ObjectStateEstimator`).

    On a compliant contact the pad is held where the contact carries ``λ_d``: pressed in by
    ``δ(λ_d)`` (:class:`ContactStiffness`) along the inward normal ``n``, in the joint
    references too (else the tangent part of (4) reads the compression as a position error
    and the pad sags). A planned ``λ_d`` gets it on the planned path (the experiment's
    ``compressed_path``, the exact inverse kinematics of ``x_d + δ n``); an online one gets
    its first order at each tick,

    .. math::
        q_d \leftarrow q_d + J_x(q_d)^+\, n\, \delta(\lambda_{d,1})\ \text{while held},

    with ``J_x⁺`` the least-squares inverse (the inverse for a 3-joint arm) and ``λ_d,1`` the
    first constraint row. When the reference follows the pad's material contact point ``P``
    across the normal and its centre ``E`` along it (``point_offset``, the experiment's
    ``control_point``), the Jacobian is that followed point's,
    ``J_y = (I − n nᵀ) J_P + n nᵀ J_E``: the pad is pressed in along the normal with ``P``
    kept on its path across it. ``q̇_d`` and ``q̈_d`` are left as they are (the online squeeze
    changes slowly: ``δ̇ = c(λ) λ̇`` is below 1 mm/s on the shipped pads). The paper's
    blocks are unchanged; this block sits between the reference and them.

    .. pydrake_system::

        name: CompressedReference
        input_ports:
        - reference
        output_ports:
        - compressed_reference

    Parameters
    ----------
    model : ArmModel
        The arm's model (``J_x``).
    stiffness : ContactStiffness
        The contact's law ``λ = a δᵖ``.
    inward : array_like, shape (3,)
        The contact's inward normal (world frame; normalized).
    point_offset : array_like, shape (3,), optional
        ``P``'s offset from the end effector's origin, fixed in its body and expressed in
        its frame (:class:`~drake_coop.control.arm_model.ArmModel`'s ``point_offset``);
        default: the reference follows ``E`` itself.

    Input ports
    -----------
    reference : (3n + m + 1)-vector
        The arm's reference, planned without the compression.

    Output ports
    ------------
    compressed_reference : (3n + m + 1)-vector
        The same with ``q_d`` pressed in.
    """

    def __init__(self, model: ArmModel, stiffness: ContactStiffness, inward,
                 point_offset=None):
        super().__init__()
        if not callable(getattr(stiffness, "compression", None)):
            raise TypeError("stiffness: a ContactStiffness is required, got "
                            f"{type(stiffness).__name__}")
        n = _vector(inward, "inward")
        size = float(np.linalg.norm(n))
        if size < 1e-9:
            raise ValueError("inward: a nonzero normal is required")
        self._n = n / size
        self._model = model
        #: The followed point's model (None: the centre's) and the projector across n.
        self._point = None if point_offset is None else ArmModel(
            model.plant, model.ee_frame.name(), model.N, model.c,
            point_offset=_vector(point_offset, "point_offset"))
        self._across = np.eye(3) - np.outer(self._n, self._n)
        self._stiffness = stiffness
        self._layout = ReferenceLayout(model.n, model.m)
        self._in = self.DeclareVectorInputPort("reference", self._layout.size)
        self._out = self.DeclareVectorOutputPort(
            "compressed_reference", self._layout.size,
            lambda c, out: out.SetFromVector(self.compressed(self._in.Eval(c))))

    def get_reference_input_port(self) -> InputPort:
        """The planned reference."""
        return self._in

    def get_compressed_reference_output_port(self) -> OutputPort:
        """The reference with ``q_d`` pressed in."""
        return self._out

    def compressed(self, r) -> np.ndarray:
        """``r`` with ``q_d + J_x(q_d)⁺ n δ(λ_d,1)`` while held (``r`` otherwise).

        Parameters
        ----------
        r : array_like
            One reference sample ``[q_d, q̇_d, q̈_d, λ_d, held]`` (rad, rad/s, rad/s², N).
        """
        r = np.array(r, dtype=float)
        lay = self._layout
        if not lay.held(r):
            return r
        s = lay.slices()
        q_d = r[s["q_d"]]
        delta = float(self._stiffness.compression(r[s["lambda_d"]][0]))
        if delta == 0.0:
            return r
        J = self._model.J_x(q_d)
        if self._point is not None:
            J = self._across @ self._point.J_x(q_d) + (np.eye(3) - self._across) @ J
        r[s["q_d"]] = q_d + np.linalg.lstsq(J, self._n * delta, rcond=None)[0]
        return r
