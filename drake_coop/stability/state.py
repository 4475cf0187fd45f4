"""The numeric state of a closed loop, read from and written to a Diagram's context generically.

The one-period map (:mod:`drake_coop.stability.period_map`) perturbs *every* number that the
context holds as state, whatever systems the diagram contains, so that it survives any rewrite
of the controllers: no system's private layout is assumed. :class:`LoopState` walks the diagram's
leaf systems (recursing into sub-Diagrams) and collects

* every discrete state group of every leaf system (the plant's ``[q, v]``, the observers'
  ``q̂, q̇̂_o, ΔF̃``, latches, delay lines, counters), labelled ``system[group][i]`` (the plant's
  entries by Drake's state names), and
* the continuous state, if any.

Abstract state is *not* perturbed: before each evaluation the map restores it with the rest
of the operating point's context (``SetTimeStateAndParametersFrom``) and then runs
``Simulator.Initialize()``, whose initialization events recompute abstract state derived from
the state (a discrete plant with sampled output ports keeps its step results there), as a fresh
simulation from the written state would. The paper's plant has no abstract state (live output
ports).

Components that are not degrees of freedom of the loop are identified by
:meth:`LoopState.locked_indices` (the positions and velocities of a joint the plant holds locked,
e.g. the planes-mode sliders while the object is released: a locked joint keeps its position
whatever it is, an eigenvalue 1 that belongs to no motion); tick counters and latched values
that the next tick overwrites are found by the map itself (:mod:`~drake_coop.stability.period_map`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, Diagram, System

__all__ = ["LoopState", "StateBlock", "leaf_systems"]


def leaf_systems(diagram: Diagram) -> list[System]:
    """Every leaf system of ``diagram``, depth first, in the diagram's own order.

    Parameters
    ----------
    diagram : Diagram
        The diagram.
    """
    out: list[System] = []
    for system in diagram.GetSystems():
        if isinstance(system, Diagram):
            out.extend(leaf_systems(system))
        else:
            out.append(system)
    return out


@dataclass
class StateBlock:
    """One discrete state group of one leaf system (``group = -1``: its continuous state).

    Attributes
    ----------
    system : System
        The leaf system.
    group : int
        The discrete state group, or -1.
    size : int
        Its entries.
    labels : list of str
        One label per entry.
    """

    system: System
    group: int
    size: int
    labels: list[str]

    @property
    def name(self) -> str:
        """The system's name."""
        return self.system.get_name()


class LoopState:
    """The flattened numeric state ``x`` of a diagram: ``get``/``set`` on any of its contexts.

    Parameters
    ----------
    diagram : Diagram
        The closed loop.
    context : Context
        A root context of ``diagram`` (sizes and labels are read from it).
    """

    def __init__(self, diagram: Diagram, context: Context):
        self.diagram = diagram
        self.blocks: list[StateBlock] = []
        for system in leaf_systems(diagram):
            sub = system.GetMyContextFromRoot(context)
            if sub.num_continuous_states():
                size = sub.num_continuous_states()
                self.blocks.append(StateBlock(system, -1, size, [
                    f"{system.get_name()}[xc][{i}]" for i in range(size)]))
            for g in range(sub.num_discrete_state_groups()):
                size = sub.get_discrete_state(g).size()
                labels = [f"{system.get_name()}[{g}][{i}]" for i in range(size)]
                if isinstance(system, MultibodyPlant) and size == system.num_multibody_states():
                    labels = [f"{system.get_name()}:{s}"
                              for s in system.GetStateNames(add_model_instance_prefix=True)]
                self.blocks.append(StateBlock(system, g, size, labels))
        self.size = sum(b.size for b in self.blocks)
        self.labels = [label for b in self.blocks for label in b.labels]
        self.num_abstract_states = context.num_abstract_states()

    def get(self, context: Context) -> np.ndarray:
        """``x`` from a root context (a copy).

        Parameters
        ----------
        context : Context
            The root context.
        """
        parts = []
        for b in self.blocks:
            sub = b.system.GetMyContextFromRoot(context)
            if b.group < 0:
                parts.append(sub.get_continuous_state_vector().CopyToVector())
            else:
                parts.append(sub.get_discrete_state(b.group).CopyToVector())
        return np.concatenate(parts) if parts else np.zeros(0)

    def set(self, context: Context, x: np.ndarray) -> None:
        """Write ``x`` into a root context (the abstract state is left as it is).

        Parameters
        ----------
        context : Context
            The root context.
        x : numpy.ndarray
            The state (size,).
        """
        x = np.asarray(x, dtype=float)
        if x.shape != (self.size,):
            raise ValueError(f"state of size {self.size} expected, got {x.shape}")
        i = 0
        for b in self.blocks:
            sub = b.system.GetMyMutableContextFromRoot(context)
            part = x[i:i + b.size]
            if b.group < 0:
                sub.get_mutable_continuous_state_vector().SetFromVector(part)
            else:
                sub.get_mutable_discrete_state(b.group).SetFromVector(part)
            i += b.size

    def offsets(self) -> dict[str, tuple[int, int]]:
        """``label of the block -> (start, stop)`` in ``x``.

        Returns
        -------
        dict of str to tuple
            ``(start, stop)`` per block.
        """
        out, i = {}, 0
        for b in self.blocks:
            out[f"{b.name}[{b.group}]"] = (i, i + b.size)
            i += b.size
        return out

    def locked_indices(self, context: Context) -> list[int]:
        """The indices of ``x`` that are positions or velocities of joints a plant holds locked.

        A locked joint's velocity is held at zero and its position stays wherever it is: these
        entries give eigenvalues 0 and 1 that belong to no motion of the loop, so the map leaves
        them out.

        Parameters
        ----------
        context : Context
            The root context.
        """
        out: list[int] = []
        i = 0
        for b in self.blocks:
            system = b.system
            if (isinstance(system, MultibodyPlant) and b.group >= 0
                    and b.size == system.num_multibody_states()):
                pc = system.GetMyContextFromRoot(context)
                nq = system.num_positions()
                for j in system.GetJointIndices():
                    joint = system.get_joint(j)
                    if joint.num_velocities() and joint.is_locked(pc):
                        out += [i + joint.position_start() + k
                                for k in range(joint.num_positions())]
                        out += [i + nq + joint.velocity_start() + k
                                for k in range(joint.num_velocities())]
            i += b.size
        return sorted(out)
