"""drake_coop: decentralized position/force control of cooperating robot arms on Drake.

Implements the observer-based controller of the paper (joint-velocity observer (15)-(16),
force observer (22), controller (13)) as Drake LeafSystems and reproduces its Section IV
experiment. Start with :func:`drake_coop.scenario.load_scenario` and
:func:`drake_coop.experiment.simulate.simulate`, or the ``drake-coop`` command.
"""

__version__ = "0.1.0"
