"""Identification of an arm's dynamic parameters from encoder readings and commanded torques.

One concept per module:

* :mod:`~drake_coop.identification.excitation` — the exciting trajectory (a windowed finite
  Fourier series) and its limit checks;
* :mod:`~drake_coop.identification.collect` — the simulated experiment on the scenario's true
  arm alone, recording only encoder ``q`` and commanded ``τ`` at ``h``;
* :mod:`~drake_coop.identification.regressor` — the inverse-dynamics regressor
  ``τ = Y(q, q̇, q̈) θ`` built numerically from Drake's inverse dynamics;
* :mod:`~drake_coop.identification.estimate` — offline smoothing and differentiation, and the
  physically consistent least squares (a semidefinite program);
* :mod:`~drake_coop.identification.urdf_writer` — the identified model as a URDF;
* :mod:`~drake_coop.identification.report` — ``identify.json``, the fit figure,
  ``identified.yaml`` and the whole ``drake-coop identify`` pipeline.
"""
