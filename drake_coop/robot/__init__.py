"""The controller on a real robot: the paper's blocks over a driver's LCM messages
(:mod:`~drake_coop.robot.drivers`), paced against the wall clock with its figures
(:mod:`~drake_coop.robot.pacing`), and ``drake-coop serve`` / ``sim-driver``
(:mod:`~drake_coop.robot.cli`)."""
