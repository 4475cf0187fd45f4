"""The two interfaces of the interchangeable sources: a velocity source and a force source.

The controller (13) reads ``q_hat``, ``qdot_hat``, ``qdot_o`` from a velocity source and
``lambda_hat``, ``Delta_F_tilde`` from a force source. The paper's observers and every
alternative (:mod:`drake_coop.control.sources`, :mod:`drake_coop.control.momentum`) declare
ports of these names; deriving from :class:`VelocitySource` or :class:`ForceSource` gives each
the same ``get_*_port()`` accessors, written once here.
"""

from __future__ import annotations

from pydrake.systems.framework import InputPort, LeafSystem, OutputPort

__all__ = ["VelocitySource", "ForceSource"]


class VelocitySource(LeafSystem):
    """A system that reads the encoders' ``q`` and estimates the joint velocities.

    Subclasses declare the input port ``q`` and the output ports ``q_hat`` (the position
    estimate ``q̂``), ``qdot_hat`` (``d/dt q̂`` of (15)) and ``qdot_o`` (``q̇_o`` of (8)).
    """

    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self.GetInputPort("q")

    def get_q_hat_output_port(self) -> OutputPort:
        """The position estimate ``q̂``."""
        return self.GetOutputPort("q_hat")

    def get_qdot_hat_output_port(self) -> OutputPort:
        """The velocity estimate ``d/dt q̂`` of (15)."""
        return self.GetOutputPort("qdot_hat")

    def get_qdot_o_output_port(self) -> OutputPort:
        """``q̇_o`` of (8)."""
        return self.GetOutputPort("qdot_o")


class ForceSource(LeafSystem):
    """A system that gives the controller its contact-force estimate.

    Subclasses declare the input port ``reference`` (the reference signal, for ``λ_d`` and
    the held flag) and the output ports ``lambda_hat`` (``λ̂`` of (22), m) and
    ``Delta_F_tilde`` (the force integral ``ΔF̃`` of (6), m).
    """

    def get_reference_input_port(self) -> InputPort:
        """The reference signal ``[q_d, q̇_d, q̈_d, λ_d, held]``."""
        return self.GetInputPort("reference")

    def get_lambda_hat_output_port(self) -> OutputPort:
        """The force estimate ``λ̂``."""
        return self.GetOutputPort("lambda_hat")

    def get_Delta_F_tilde_output_port(self) -> OutputPort:
        """The force integral ``ΔF̃`` of (6)."""
        return self.GetOutputPort("Delta_F_tilde")
