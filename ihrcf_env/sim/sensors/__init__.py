"""The drone's sensors in the simulator, each a :class:`Sensor`: downward camera, four ToF beams, IMU.
Their configurations are in :mod:`ihrcf_env.config.sensors`."""

from ihrcf_env.sim.sensors.base import TAG_STATUS, BodyState, Sensor
from ihrcf_env.sim.sensors.camera import DownCamera, render_rgb
from ihrcf_env.sim.sensors.imu import IMU
from ihrcf_env.sim.sensors.tof import ToFArray

__all__ = ["IMU", "TAG_STATUS", "BodyState", "DownCamera", "Sensor", "ToFArray", "render_rgb"]
