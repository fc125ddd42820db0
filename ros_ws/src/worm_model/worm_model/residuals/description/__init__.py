"""What is left after a fit, described (physics.md section 9, steps 5-6).

Modules, each using only the ones above it (and residuals' ``fitting`` folder, ``model``, ``free``, ``effects``):
  ``descriptors``    generic descriptions of a residual (binned means, angle orders) and the pseudo-effect of one
  ``unexplained``    the noise floor, and the description of a residual left above it
  ``aliases``        effects named from a refitted parameter beyond its tolerance band
  ``contributions``  what each named effect buys on held-out data

Read first: ``unexplained`` (the floor and what a residual above it goes with).
"""
