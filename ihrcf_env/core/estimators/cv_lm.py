"""The constants of OpenCV's square-tag PnP as ATDA (:mod:`ihrcf_env.core.estimators.atda`) calls
it: the fixed-point undistortion of ``SOLVEPNP_IPPE_SQUARE``'s input and ``cv2.solvePnPRefineLM``'s
Levenberg-Marquardt with its default criteria. Ports of that algorithm (the JAX backend's
:mod:`ihrcf_env.fast.ippe`, :mod:`ihrcf_env.fast.lm`, :mod:`ihrcf_env.fast.pnp`) read them here.

The LM, as OpenCV 5 runs it:

- parameters: the rotation vector and the translation, ``p = (rvec, tvec)``, updated additively;
  residuals: projected minus observed pixels; energy: the sum of squared residuals;
- damping: ``lambda`` times the diagonal of J^T J, each term clamped to [:data:`MIN_DIAG`,
  :data:`MAX_DIAG`], starting at :data:`LAMBDA0`;
- geodesic acceleration: the second directional derivative along the step from a probe at
  ``p + H_GEO x``, added (times :data:`GEO_SCALE`) when its relative size is below 1;
- a step is rejected when the energy increases: lambda times the up factor (:data:`UP0`, doubled
  each time); accepted: lambda times max(1 / :data:`DOWN`, 1 - (2 q - 1)^3), q the actual over
  the predicted decrease;
- it stops after :data:`MAX_ITER` tried steps, when lambda exceeds :data:`MAX_LAMBDA`, or after an
  accepted step with max |J^T r| below :data:`MIN_GRADIENT` (before the step), a squared step norm
  below :data:`STEP_TOL`, a relative energy decrease below :data:`REL_ENERGY_TOL`, or the energy
  below :data:`SMALL_ENERGY`.
"""

from __future__ import annotations

import numpy as np

_FLT_EPSILON = float(np.finfo(np.float32).eps)

#: Fixed-point undistortion iterations of the IPPE starting points (OpenCV's undistortPoints uses 5).
UNDISTORT_ITERATIONS = 5
#: Iteration cap (tried steps, accepted or not), as cv2's default criteria.
MAX_ITER = 20
#: Stop when the squared norm of an accepted step is below this (cv2: the criteria's epsilon).
STEP_TOL = _FLT_EPSILON
#: Stop when the energy (px^2) is below this (cv2: epsilon squared).
SMALL_ENERGY = _FLT_EPSILON * _FLT_EPSILON
#: Stop when an accepted step lowers the energy by less than this fraction of the new energy.
REL_ENERGY_TOL = 1e-6
#: Stop when max |J^T r| (px^2 per parameter unit) is below this.
MIN_GRADIENT = 1e-6
#: Damping: initial lambda, its up factor after a rejected step (doubled each time) and down
#: divisor bound after an accepted one.
LAMBDA0, UP0, DOWN = 1e-4, 2.0, 3.0
#: Damping terms are clamped to [MIN_DIAG, MAX_DIAG]; the LM stops once lambda reaches MAX_LAMBDA.
MIN_DIAG, MAX_DIAG, MAX_LAMBDA = 1e-6, 1e32, 1e32
#: Geodesic acceleration: probe fraction of the step, and the weight of the correction.
H_GEO, GEO_SCALE = 1e-4, 0.5

__all__ = [
    "DOWN",
    "GEO_SCALE",
    "H_GEO",
    "LAMBDA0",
    "MAX_DIAG",
    "MAX_ITER",
    "MAX_LAMBDA",
    "MIN_DIAG",
    "MIN_GRADIENT",
    "REL_ENERGY_TOL",
    "SMALL_ENERGY",
    "STEP_TOL",
    "UNDISTORT_ITERATIONS",
    "UP0",
]
