"""Fitting the model to measured data, and judging a fit (physics.md section 9, steps 1-3).

Modules, each using only the ones above it (and residuals' ``model``, ``free``, ``effects``, ``settings``):
  ``split``       the held-out split: interleaved time blocks with guards
  ``fitting``     fits of the model to the training samples (current; transmission error), Problem and Fit
  ``screening``   every candidate ranked by the held-out error it would leave
  ``acceptance``  when a fit earns its keep: held-out improvement, block bootstrap, BIC, physical range

Read first: ``fitting`` (Problem, fit, Fit).  Nothing here imports residuals' ``description`` folder.
"""
