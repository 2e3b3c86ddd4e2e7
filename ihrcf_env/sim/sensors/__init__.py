"""The drone's sensors in the simulator: downward camera, four ToF beams."""

from ihrcf_env.sim.sensors.camera import CameraConfig, DownCamera, render_rgb
from ihrcf_env.sim.sensors.tof import TOF_PRESETS, ToFArray, ToFConfig

__all__ = ["TOF_PRESETS", "CameraConfig", "DownCamera", "ToFArray", "ToFConfig", "render_rgb"]
