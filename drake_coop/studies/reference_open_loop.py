"""The reference table's open-loop column: an estimator beside a loop closed on another source.

In the table's other columns a row's estimator is in the loop: its ``λ̂`` feeds the control
law (13) and the integral (6), so its error and the squeeze error move together. In the
open-loop column the loop is closed on the wrist F/T sensor (σ = 0.3 N, the exact model) and
the row's estimator runs *beside* it: it reads the same signals it would read in the loop
(the encoders' ``q``, the velocity source's ``q̂``, ``q̇̂``, ``q̇_o``, the commanded ``τ``, the
reference) but nothing reads its ``λ̂``. The cell's estimate error is then the estimator's own
error, on a trajectory it does not shape; the squeeze error is the sensor loop's.

How the worker builds it (:func:`open_loop_built`): the sensor's registry entry is swapped,
while the experiment is built, for a two-system diagram — the sensor source, whose
``lambda_hat`` and ``Delta_F_tilde`` feed the controller, and the row's estimator, whose
``lambda_hat`` the diagram exports as ``lambda_hat_beside``; the experiment's view of the
control block reads ``lambda_hat_beside`` where it logs (and guards) ``lambda_hat``. The
estimated-force guard then watches the estimator beside the loop: an estimate beyond it ends
the draw, counted as diverged.

For the F/T rows the open-loop cell is the exact column's case (a sensor's reading does not
depend on the loop); the applied-torque residual without torque limits is the momentum
observer's case.
"""

from __future__ import annotations

import contextlib
import dataclasses
from typing import Iterator

from drake_coop.scenario.schema import Scenario

__all__ = ["BESIDE", "LOOP_NOISE", "open_loop_built"]

#: The rows that run beside the loop (the others are their exact column's case).
BESIDE = ("observer", "momentum", "applied_torque", "online", "none")
#: The loop's F/T sensor noise (N).
LOOP_NOISE = 0.3


class _BesideView:
    """The control block as the experiment reads it: ``lambda_hat`` is the estimator's
    beside the loop (every other port, and everything else, the block's own)."""

    def __init__(self, diagram):
        self._diagram = diagram

    def GetOutputPort(self, name: str):
        """The block's output port ``name`` (``lambda_hat``: ``lambda_hat_beside``).

        Parameters
        ----------
        name : str
            The port's name.

        Returns
        -------
        OutputPort
            The block's port.
        """
        return self._diagram.GetOutputPort("lambda_hat_beside" if name == "lambda_hat"
                                           else name)

    def __getattr__(self, attribute):
        return getattr(self._diagram, attribute)


def _estimator_factory(scenario: Scenario, row: str, online_build):
    """``make(law, h, options)`` of the row's estimator, robot by robot in the scenario's
    order."""
    from drake_coop.control.registry import source

    if row == "online":
        if online_build is None:
            raise ValueError("online_build: the online row needs its builder")
        return lambda law, h, options: online_build(None, law, h, options)
    name = "momentum" if row == "applied_torque" else row
    limits = iter([r.actuators.torque_limits for r in scenario.robots])
    entry = source("force", name)

    def make(law, h, options):
        extra = next(limits) if row == "applied_torque" else None
        return entry.make(law, h, {**options, "momentum_torque_limits": extra})
    return make


def _beside_entry(loop, row_inputs: tuple[str, ...], make_estimator):
    """The loop's registry entry, building the two-system diagram (module docstring)."""
    from pydrake.systems.framework import DiagramBuilder

    inputs = tuple(dict.fromkeys(loop.inputs + row_inputs))

    def build(cls, law, h, options):
        b = DiagramBuilder()
        systems = (b.AddNamedSystem("loop", loop.make(law, h, options)),
                   b.AddNamedSystem("beside", make_estimator(law, h, options)))
        for port in inputs:
            readers = [s for s in systems if s.HasInputPort(port)]
            b.ExportInput(readers[0].GetInputPort(port), port)
            for s in readers[1:]:
                b.ConnectInput(port, s.GetInputPort(port))
        b.ExportOutput(systems[0].GetOutputPort("lambda_hat"), "lambda_hat")
        b.ExportOutput(systems[0].GetOutputPort("Delta_F_tilde"), "Delta_F_tilde")
        b.ExportOutput(systems[1].GetOutputPort("lambda_hat"), "lambda_hat_beside")
        diagram = b.Build()
        diagram.set_name("beside_the_loop")
        return diagram
    return dataclasses.replace(loop, inputs=inputs, build=build,
                               outputs=("lambda_hat_beside",))


@contextlib.contextmanager
def open_loop_built(scenario: Scenario, row: str, online_build=None) -> Iterator[None]:
    """While inside, experiments of ``scenario`` (``force_source: sensor`` on every robot)
    are built with ``row``'s estimator beside the sensor loop.

    Parameters
    ----------
    scenario : Scenario
        The case's scenario.
    row : str
        One of :data:`BESIDE`.
    online_build : callable or None
        ``online`` only: ``build(cls, law, h, options)`` making each robot's online block in
        the scenario's order (the online row's, :mod:`~drake_coop.studies.reference_variants`).

    Yields
    ------
    None
        The swap holds until the block exits.

    Raises
    ------
    ValueError
        A row not in :data:`BESIDE`, a scenario whose robots are not on the sensor, or the
        online row without ``online_build``.
    """
    if row not in BESIDE:
        raise ValueError(f"row: {row!r} does not run beside the loop; allowed: "
                         f"{', '.join(BESIDE)}")
    if any(r.force_source != "sensor" for r in scenario.robots):
        raise ValueError("scenario: the open-loop column closes every robot's loop on the "
                         "sensor (force_source: sensor)")
    import drake_coop.control.block as block
    import drake_coop.control.registry as registry
    import drake_coop.experiment.diagram as diagram

    saved = (registry.SOURCES, block.SOURCES, diagram.AddCooperativeController)
    try:
        estimator = registry.source("force", "momentum" if row in ("applied_torque", "online")
                                    else row)
        entry = _beside_entry(registry.source("force", "sensor"), estimator.inputs,
                              _estimator_factory(scenario, row, online_build))
        registry.SOURCES = block.SOURCES = tuple(
            entry if (s.kind, s.name) == ("force", "sensor") else s for s in registry.SOURCES)
        original = diagram.AddCooperativeController

        def viewed(*args, **kwargs):
            handles = original(*args, **kwargs)
            return dataclasses.replace(handles, system=_BesideView(handles.system))
        diagram.AddCooperativeController = viewed
        yield
    finally:
        registry.SOURCES, block.SOURCES, diagram.AddCooperativeController = saved
