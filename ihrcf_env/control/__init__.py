"""Controllers and their filters (pure: numpy and :mod:`ihrcf_env.core` only, no simulator).

* :mod:`ihrcf_env.control.hover`: :class:`HoverTracker` / :func:`tracking_action`, hold a height above
  the deck and follow it with one deck-pose estimate.
* :mod:`ihrcf_env.control.landing`: :class:`LandingController`, land on the moving deck from IHRCF,
  ToF ranges and the IMU.
* :mod:`ihrcf_env.control.filters`: :class:`AlphaBeta`.
"""

from ihrcf_env.control.filters import AlphaBeta
from ihrcf_env.control.hover import HoverGains, HoverTracker, tracking_action
from ihrcf_env.control.landing import LandingConfig, LandingController, Measurement

__all__ = [
    "AlphaBeta",
    "HoverGains",
    "HoverTracker",
    "LandingConfig",
    "LandingController",
    "Measurement",
    "tracking_action",
]
