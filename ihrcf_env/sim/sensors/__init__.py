"""The drone's sensors in the simulator, each a :class:`Sensor`: downward camera, four ToF beams, IMU."""

from ihrcf_env.sim.sensors.base import TAG_STATUS, BodyState, Sensor
from ihrcf_env.sim.sensors.camera import CameraConfig, DownCamera, render_rgb
from ihrcf_env.sim.sensors.imu import IMU
from ihrcf_env.sim.sensors.tof import TOF_PRESETS, ToFArray, ToFConfig

__all__ = [
    "IMU",
    "TAG_STATUS",
    "TOF_PRESETS",
    "BodyState",
    "CameraConfig",
    "DownCamera",
    "Sensor",
    "ToFArray",
    "ToFConfig",
    "render_rgb",
]
