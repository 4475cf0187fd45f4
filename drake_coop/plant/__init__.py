"""The simulated cooperative plant: arm geometry and kinematics (arms), the MultibodyPlant of both
arms and the object (cooperative), the contact mode's grasp (grasp)."""
