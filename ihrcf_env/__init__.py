"""ihrcf_env: UAV landing on a moving Stewart-platform deck, with the IHRCF pose estimator as a sensor.

Layers: pure geometry/estimation modules (``frames``, ``rig``, ``geometry``, ``calibration``,
``estimators``; numpy/scipy/cv2 only), the PyBullet simulation layer (``ihrcf_env.sim``), the
Gymnasium env (``ihrcf_env.envs``) and wrappers on top. Importing this package registers
``ihrcf_env/DeckLanding-v0`` (wrapped) and ``ihrcf_env/DeckLandingRaw-v0`` without importing PyBullet.
"""

import warnings

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

ENV_ID = "ihrcf_env/DeckLanding-v0"  # wrapped with the IHRCF/ATDA/ground-truth observation (raw=True: raw)
RAW_ENV_ID = "ihrcf_env/DeckLandingRaw-v0"  # the raw DeckLandingEnv
ENV_V1_ID = "ihrcf_env/DeckLanding-v1"  # the v1 landing task, flat RL observation (raw=True: raw)

if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="ihrcf_env.wrappers.estimates:make_deck_landing", max_episode_steps=600)
if RAW_ENV_ID not in registry:
    register(id=RAW_ENV_ID, entry_point="ihrcf_env.envs.deck_landing:DeckLandingEnv", max_episode_steps=600)
if ENV_V1_ID not in registry:
    register(
        id=ENV_V1_ID, entry_point="ihrcf_env.wrappers.landing_obs:make_deck_landing_v1", max_episode_steps=600
    )

# v0 is not an outdated v1: it is the paper's hover experiment, kept as it is, and v1 is a different
# task (landing). Gymnasium warns "out of date" on every make of a lower version; silence exactly that.
warnings.filterwarnings(
    "ignore", message=r".*ihrcf_env/DeckLanding-v0 is out of date", category=DeprecationWarning
)
