"""The simulated world's configuration: :class:`WorldConfig` (rates, sensors, deck plate and tag,
Stewart geometry, vehicle, action mode, registered components). The world itself is
:class:`ihrcf_env.sim.world.World`. SI units.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ihrcf_env.config.sensors import CameraConfig, IMUConfig, ToFConfig
from ihrcf_env.config.vehicle import NavigationConfig, QuadParams, VelocityGains
from ihrcf_env.core.checks import check_fields, check_int, set_field
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.core.stewart import StewartGeometry

if TYPE_CHECKING:
    from ihrcf_env.core.detector_model import DetectorModel


#: Physical bounds (inclusive) of :class:`DeckConfig`'s real fields (the plate must stay much
#: heavier than the drone: it is driven, not pushed).
DECK_BOUNDS: dict[str, tuple[float, float]] = {
    "size": (0.1, 5.0),
    "thickness": (0.005, 0.2),
    "mass": (10.0, 1e4),
    "tag_size": (0.01, 4.0),
    "friction": (0.0, 10.0),
}


DECK_UNITS = {"size": "m", "thickness": "m", "mass": "kg", "tag_size": "m"}


@dataclass(frozen=True)
class DeckConfig:
    """Deck plate and tag. Metres, kilograms."""

    size: float = 0.8  # square plate edge
    thickness: float = 0.04
    mass: float = 400.0
    tag_id: int = 0
    tag_size: float = 0.4  # edge of the tag's black square
    friction: float = 1.0

    def __post_init__(self) -> None:
        # tag_id: its range is the tag family's, checked where the texture is made
        set_field(self, "tag_id", check_int("deck tag_id", self.tag_id))
        check_fields(self, lambda f: f"deck {f}", DECK_BOUNDS, DECK_UNITS)
        if self.tag_size * 10 / 8 > self.size:
            raise ValueError(
                f"tag_size {self.tag_size} m (plus its white quiet zone) does not fit on the "
                f"{self.size} m deck"
            )


ACTION_MODES: tuple[str, ...] = ("velocity", "motors")


#: How the camera is simulated: ``"rendered"`` (TinyRenderer + the tag detector) or ``"projected"``
#: (no image: the exact projection of the tag corners through a fitted detector model).
CAMERA_MODELS: tuple[str, ...] = ("rendered", "projected")


#: What the camera delivers: the ``"image"`` (rendered only) or the tag's ``"corners"`` (a rendered
#: window around the tag + detection, or the projected model).
CAMERA_OUTPUTS: tuple[str, ...] = ("image", "corners")


@dataclass(frozen=True)
class WorldConfig:
    """Everything that defines the simulated world. SI units."""

    physics_hz: int = 240
    control_hz: int = 20
    camera: CameraConfig | None = field(default_factory=CameraConfig)  # None: no camera rendering
    tof: ToFConfig = field(default_factory=ToFConfig)
    imu: IMUConfig = field(default_factory=IMUConfig)
    navigation: NavigationConfig = field(default_factory=NavigationConfig)
    deck: DeckConfig = field(default_factory=DeckConfig)
    stewart: StewartGeometry = field(default_factory=StewartGeometry)
    quad: QuadParams = field(default_factory=QuadParams)
    gains: VelocityGains = field(default_factory=VelocityGains)
    rig: SensorRig = field(default_factory=SensorRig)
    action_mode: str = "velocity"
    camera_model: str = "rendered"
    camera_output: str = "image"
    camera_hz: int | None = None  # None: every control step
    detector_model: DetectorModel | None = None  # "projected": the fitted model (None: the shipped one)
    #: per-rotor ground effect over the deck and the ground (:mod:`ihrcf_env.sim.ground_effect`)
    ground_effect: bool = False
    #: registered sensors (:mod:`ihrcf_env.sim.registry`) read after the built-in ones
    extra_sensors: tuple[str, ...] = ()
    #: (measurement, registered noise model) pairs applied to the readings
    measurement_noise: tuple[tuple[str, str], ...] = ()
    #: sensor faults (:func:`ihrcf_env.sim.registry.check_faults`), applied after the noise models
    faults: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()

    def __post_init__(self) -> None:
        if not (isinstance(self.physics_hz, int | np.integer) and self.physics_hz > 0):
            raise ValueError(f"physics_hz must be a positive integer, got {self.physics_hz!r}")
        if not (isinstance(self.control_hz, int | np.integer) and self.control_hz > 0):
            raise ValueError(f"control_hz must be a positive integer, got {self.control_hz!r}")
        if self.physics_hz % self.control_hz != 0:
            raise ValueError(
                f"control_hz ({self.control_hz}) must divide physics_hz ({self.physics_hz}) evenly"
            )
        if self.action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {self.action_mode!r}")
        if self.camera_model not in CAMERA_MODELS:
            raise ValueError(f"camera_model must be one of {CAMERA_MODELS}, got {self.camera_model!r}")
        if self.camera_output not in CAMERA_OUTPUTS:
            raise ValueError(f"camera_output must be one of {CAMERA_OUTPUTS}, got {self.camera_output!r}")
        if self.camera_model == "projected" and self.camera_output == "image":
            raise ValueError(
                'camera_model="projected" renders no image: it delivers the tag corners only '
                '(camera_output="corners"); use camera_model="rendered" for images'
            )
        hz = self.camera_hz
        if hz is not None:
            if isinstance(hz, bool) or not (isinstance(hz, int | np.integer) and hz > 0):
                raise ValueError(f"camera_hz must be a positive integer (Hz) or None, got {hz!r}")
            if self.control_hz % hz != 0:
                raise ValueError(f"camera_hz ({hz}) must divide control_hz ({self.control_hz}) evenly")
        for what, rate in (("tof_hz", self.tof.rate_hz), ("imu_hz", self.imu.rate_hz)):
            if rate is not None and rate > self.physics_hz:
                raise ValueError(f"{what} ({rate:g} Hz) must not exceed physics_hz ({self.physics_hz} Hz)")

    @property
    def camera_every(self) -> int:
        """The camera delivers a frame every this many control steps."""
        return 1 if self.camera_hz is None else self.control_hz // self.camera_hz

    @property
    def substeps(self) -> int:
        return self.physics_hz // self.control_hz


__all__ = [
    "ACTION_MODES",
    "CAMERA_MODELS",
    "CAMERA_OUTPUTS",
    "DECK_BOUNDS",
    "DECK_UNITS",
    "DeckConfig",
    "WorldConfig",
]
