"""Pure core: frames, geometry, rig, Stewart kinematics, motion profiles, calibration maths,
estimators, the camera-detector model (``detector_model``), metrics. numpy / scipy / OpenCV only:
no PyBullet, no Gymnasium, so every module here works on real drone logs as well as in the
simulator (enforced by ``tests/test_layers.py``)."""
