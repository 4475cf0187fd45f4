"""Realistic sensors and actuators between the plant and the control blocks.

Per robot: plant → ``robotN_encoders`` (:mod:`.encoders`) → control block →
``robotN_actuators`` (:mod:`.actuators`) → plant; ``robotN_ft_sensor`` (:mod:`.force_sensor`)
downstream of the ground-truth ``robotN_force_sensor``. :mod:`.model_error` builds the
controller's model with scaled parameters and the simulated arm's unmodelled payload;
:mod:`.sampling` holds what the sampled sensors share (tick index, seeded noise, low-pass gain).
"""
