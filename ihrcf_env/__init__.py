"""ihrcf_env: UAV landing on a moving Stewart-platform deck, with the IHRCF pose estimator as a sensor.

Layers: pure geometry/estimation modules (``frames``, ``rig``, ``geometry``, ``calibration``,
``estimators``; numpy/scipy/cv2 only), the PyBullet simulation layer (``ihrcf_env.sim``), the
Gymnasium env (``ihrcf_env.envs``) and wrappers on top.
"""

__version__ = "0.1.0"
