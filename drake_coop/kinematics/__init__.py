"""Arm kinematics, below the scenario and the plant: they import only Drake and NumPy.

:mod:`~drake_coop.kinematics.crs` is the closed form of the paper's three-joint arms,
:mod:`~drake_coop.kinematics.drake_arm` Drake's kinematics of any arm parsed from its model file
(forward kinematics, Jacobians, inverse kinematics and the joint reference of a task path).
"""
