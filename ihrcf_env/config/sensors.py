"""Sensor configurations: the downward camera (with its realistic imaging parameters), the four ToF
sensors (ideal ray or the VL53L1X cone model) and the IMU noise. Frozen dataclasses checked in
``__post_init__``; the sensors built from them live in :mod:`ihrcf_env.sim.sensors`. SI units,
radians.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_fields, check_int, check_real, check_reals, set_field
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.rig import intrinsics_from_fov

BACKGROUNDS: tuple[str, ...] = ("sea", "ground")


#: 8-bit output: full scale in DN.
FULL_SCALE_DN = 255.0


@dataclass(frozen=True)
class ImagingParams:
    """Radiometry, noise, blur and scene-variation parameters of the realistic camera.

    Sensor: **Sony IMX296** (IMX296LLR mono / IMX296LQR colour): 1/2.9-inch, 1456 x 1088 (1.58 MP),
    3.45 um pixels, global shutter, 10-bit ADC, used in the Raspberry Pi Global Shutter Camera
    (https://www.raspberrypi.com/news/new-raspberry-pi-global-shutter-camera/; Linux binding
    https://kernel.org/doc/Documentation/devicetree/bindings/media/i2c/sony%2Cimx296.yaml) and in
    M12-lens boards for Raspberry Pi / Jetson drones (e.g. InnoMaker CAM-IMX296: 60 fps at full
    resolution, exposures down to 30 us, https://el.manuals.plus/inno/imx296-sensor-module-manual).

    Noise figures: no EMVA 1288 sheet of the IMX296 was found (MATRIX VISION's IMX296 camera page
    lists SNR and dynamic range as "TBD":
    https://assets.balluff.com/documents/DRF_958401_AA_000/mvBC_page_sensors.html). **Assumed:**
    the IMX296 shares the first-generation Sony Pregius 3.45 um pixel of the IMX250/IMX255, whose
    EMVA 1288 measurements are SNRmax 40.3 dB and dynamic range 71.2 dB (IMX250, mvBlueFOX3-2051,
    https://www.matrix-vision.com/manuals/mvBlueFOX3/mvBC_subsubsection_sensors_CMOS_models_2051.html)
    and 40.3 / 71.3 dB (IMX255, same manual). Hence full well = 10^(40.3/10) = 10,700 e- and
    temporal dark (read) noise = 10,700 / 10^(71.2/20) = 2.95 e-.

    **Assumed** mapping to the 8-bit output: at 0 dB analog gain the full well is 255 DN
    (42 e-/DN); at gain G, ``g = full_well / (255 G)`` electrons per DN. Shot-noise s.d. at mid
    grey is then 1.7 DN at 0 dB and 3.5 DN at 12 dB.

    Exposure (**assumed** auto-exposure policy): each episode draws the exposure the scene needs at
    unity gain, log-uniform in ``scene_exposure_s`` (1-20 ms: overcast daylight to a lit lab); the
    auto-exposure uses at most ``max_exposure_s`` (5 ms, to limit motion blur) and makes up the rest
    with analog gain up to ``max_gain`` (8x = 18 dB; the IMX296 goes to 48 dB); the mean level is
    then off by a log-normal factor of s.d. ``ae_error``. Light: azimuth uniform, elevation uniform
    in ``light_elevation_deg``, ambient and diffuse coefficients uniform in their ranges.

    Vignetting: relative illumination ``cos(theta)^vignetting_exponent`` of the field angle theta;
    4 is the natural cos^4 law, 2 (default, **assumed** for a small M12 lens) gives 60 % in the
    corners of the 60 deg (vertical) image.

    Background: ``"sea"`` (wind waves, crests and a little foam) or ``"ground"`` (fractal grass and
    soil); a periodic ``texture_px`` square texture covering ``texture_tile_m`` per period,
    generated from ``texture_seed`` when the camera is built; each episode places and rotates it at
    random and lets it drift at up to ``drift_speed`` m/s (surface current).
    """

    sensor: str = "Sony IMX296 (Raspberry Pi Global Shutter Camera)"
    full_well_e: float = 10_700.0
    read_noise_e: float = 2.95
    max_gain: float = 8.0
    max_exposure_s: float = 0.005
    scene_exposure_s: tuple[float, float] = (0.001, 0.02)
    ae_error: float = 0.08
    light_elevation_deg: tuple[float, float] = (40.0, 85.0)
    ambient: tuple[float, float] = (0.45, 0.65)
    diffuse: tuple[float, float] = (0.25, 0.4)
    vignetting_exponent: float = 2.0
    blur_threshold_px: float = 0.3
    background: str = "sea"
    texture_px: int = 256
    texture_tile_m: float = 3.0
    texture_seed: int = 0
    drift_speed: float = 0.2
    noise_margin_px: int = 96

    def __post_init__(self) -> None:
        def positive(name: str) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (math.isfinite(v) and v > 0):
                raise ValueError(f"imaging {name} must be a positive finite number, got {v!r}")

        def interval(name: str, lo: float, hi: float) -> None:
            v = getattr(self, name)
            ok = isinstance(v, tuple) and len(v) == 2 and all(isinstance(x, int | float) for x in v)
            if not ok or not (lo <= v[0] <= v[1] <= hi):
                raise ValueError(f"imaging {name} must be a (low, high) pair within [{lo}, {hi}], got {v!r}")

        for name in ("full_well_e", "read_noise_e", "max_exposure_s", "texture_tile_m"):
            positive(name)
        if not (isinstance(self.max_gain, int | float) and 1.0 <= self.max_gain <= 1000.0):
            raise ValueError(f"imaging max_gain must be in [1, 1000], got {self.max_gain!r}")
        interval("scene_exposure_s", 1e-6, 10.0)
        interval("light_elevation_deg", 5.0, 90.0)
        interval("ambient", 0.0, 1.0)
        interval("diffuse", 0.0, 1.0)
        for name, hi in (("ae_error", 1.0), ("vignetting_exponent", 8.0), ("drift_speed", 10.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (0.0 <= v <= hi):
                raise ValueError(f"imaging {name} must be in [0, {hi}], got {v!r}")
        if not (isinstance(self.blur_threshold_px, int | float) and self.blur_threshold_px >= 0):
            raise ValueError(f"imaging blur_threshold_px must be >= 0, got {self.blur_threshold_px!r}")
        if self.background not in BACKGROUNDS:
            raise ValueError(f"imaging background must be one of {BACKGROUNDS}, got {self.background!r}")
        for name, lo, hi in (("texture_px", 16, 1024), ("noise_margin_px", 1, 1024)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not (lo <= v <= hi):
                raise ValueError(f"imaging {name} must be an integer in [{lo}, {hi}], got {v!r}")
        if (
            isinstance(self.texture_seed, bool)
            or not isinstance(self.texture_seed, int)
            or self.texture_seed < 0
        ):
            raise ValueError(
                f"imaging texture_seed must be a non-negative integer, got {self.texture_seed!r}"
            )

    def electrons_per_dn(self, gain: float) -> float:
        """Conversion ``g`` (e-/DN) of the 8-bit output at analog gain ``gain`` (1 = 0 dB)."""
        return self.full_well_e / (FULL_SCALE_DN * gain)


#: Camera qualities: ``"ideal"`` (today's clean render) and ``"realistic"``.
CAMERA_QUALITIES: tuple[str, ...] = ("ideal", "realistic")


#: Largest ``CameraConfig.latency`` accepted (s).
MAX_LATENCY = 1.0


#: A typical delay (s) from exposure to detected tag corners of a global-shutter camera with
#: on-board AprilTag detection on an embedded computer (exposure, readout and transfer, detection),
#: the ``camera_latency`` of ``DeckLanding-v2``; the published figures behind it are in
#: ``docs/sensors.md`` ("Timing and latency").
PIPELINE_LATENCY = 0.045


@dataclass(frozen=True)
class CameraConfig:
    """Downward camera. ``fov`` is the vertical field of view (rad); square pixels.

    ``light_direction`` (world, pointing from the scene to the light) and the ambient/diffuse
    coefficients set TinyRenderer's single light. ``distortion = (k1, k2)`` applies Brown-Conrady
    radial lens distortion to the rendered image (0, 0: an ideal pinhole camera).

    ``quality``: ``"ideal"`` (default; the image is bit for bit what it was before the realistic
    model existed: grey deck on a blank background under the light above, no noise) or
    ``"realistic"``: the sensor and scene model of ``imaging``
    (:class:`~ihrcf_env.config.sensors.ImagingParams`, default a Sony IMX296 global-shutter
    camera; sources and assumptions there): a seeded sea (or ground) texture on the plane z = 0
    where the renderer's segmentation mask is background, the episode's light direction and
    ambient/diffuse coefficients (replacing the three fields above) and its exposure/gain, all
    drawn in ``reset``; motion blur from the drone's velocity and angular velocity over the
    exposure; vignetting; read and shot noise; 8-bit quantisation.

    Its per-frame cost: :func:`~ihrcf_env.experiments.camera_realism.realism_cost_ms`.

    Calibration: the realistic model changes radiometry and blur, never geometry. The projection
    (``intrinsics``, principal point), the ``distortion`` and its remap are the same, and the
    background is composited in the pinhole image before distorting; noise is zero-mean, the blur
    kernel is centred (it spreads an edge symmetrically, it does not move it), and vignetting and
    exposure are smooth gains. A calibration made with the ideal camera (the shipped one:
    chessboard K and distortion for ATDA, range-to-pixel tables of the ToF spots for IHRCF)
    therefore stays valid (``tests/sim/test_camera_realism.py`` checks the estimators' errors with
    both qualities).
    """

    width: int = 512
    height: int = 512
    fov: float = math.radians(60.0)
    near: float = 0.01
    far: float = 10.0
    light_direction: tuple[float, float, float] = (0.3, 0.2, 1.0)
    ambient: float = 0.6
    diffuse: float = 0.35
    specular: float = 0.0
    distortion: tuple[float, float] = (0.0, 0.0)
    quality: str = "ideal"
    imaging: ImagingParams = field(default_factory=ImagingParams)
    #: delay (s) from a frame's exposure to its delivery to the observation (exposure, readout,
    #: transfer and tag detection); 0: delivered in the control step it is exposed. See
    #: ``docs/sensors.md`` ("Timing and latency") and :data:`PIPELINE_LATENCY`.
    latency: float = 0.0

    def __post_init__(self) -> None:
        set_field(self, "latency", check_real("camera_latency", self.latency, "s", low=0.0, high=MAX_LATENCY))
        if self.quality not in CAMERA_QUALITIES:
            raise ValueError(f"camera quality must be one of {CAMERA_QUALITIES}, got {self.quality!r}")
        if not isinstance(self.imaging, ImagingParams):
            raise TypeError(f"camera imaging must be an ImagingParams, got {self.imaging!r}")
        if not (isinstance(self.width, int | np.integer) and self.width > 0):
            raise ValueError(f"camera width must be a positive integer, got {self.width!r}")
        if not (isinstance(self.height, int | np.integer) and self.height > 0):
            raise ValueError(f"camera height must be a positive integer, got {self.height!r}")
        if not (math.isfinite(self.fov) and 0.0 < self.fov < math.radians(170.0)):
            raise ValueError(f"camera fov must be in (0, 170 deg) in radians, got {self.fov!r}")
        if not (0.0 < self.near < self.far):
            raise ValueError(f"camera near/far must satisfy 0 < near < far, got {self.near}, {self.far}")
        k = np.asarray(self.distortion, dtype=np.float64)
        if k.shape != (2,) or not np.isfinite(k).all() or np.any(np.abs(k) > 1.0):
            raise ValueError(
                f"camera distortion must be two finite numbers (k1, k2) in [-1, 1], got {self.distortion!r}"
            )

    @property
    def distortion_coefficients(self) -> NDArray[np.float64]:
        """True OpenCV distortion vector (k1, k2, p1, p2, k3) of the image."""
        return np.array([self.distortion[0], self.distortion[1], 0.0, 0.0, 0.0])

    @property
    def intrinsics(self) -> NDArray[np.float64]:
        """True pinhole K of the rendered image (OpenCV convention). Estimators must not read this:
        ATDA uses the chessboard calibration, IHRCF the range-to-pixel table.

        TinyRenderer samples pixel (column i, row j) at screen point (i, H - 1 - j) of its
        viewport, so in OpenCV's pixel-centre convention the principal point is (W/2, H/2 - 1),
        not the image centre ((W - 1)/2, (H - 1)/2); checked against rendered tag corners.
        """
        K = intrinsics_from_fov(self.width, self.height, self.fov)
        K[0, 2] = self.width / 2.0
        K[1, 2] = self.height / 2.0 - 1.0
        return K


#: Ranges of ST's long distance mode used to calibrate :class:`VL53L1X`'s SNR model: an 88 %
#: (white) target, 33 ms timing budget, full 16x16 SPAD region of interest.
REFERENCE_REFLECTANCE = 0.88


#: Physical bounds (inclusive) of :class:`VL53L1X`'s real-valued fields: any real ToF sensor fits.
VL53L1X_BOUNDS: dict[str, tuple[float, float]] = {
    "fov": (math.radians(1.0), math.radians(90.0)),
    "reflectance": (0.01, 1.0),
    "ambient": (0.0, 1.0),
    "dark_range": (0.05, 50.0),
    "ambient_range": (0.01, 20.0),
    "sigma_at_limit": (1e-4, 1.0),
    "sigma_floor": (0.0, 1.0),
    "offset_sigma": (0.0, 1.0),
    "min_range": (0.0, 10.0),
    "dropout": (0.0, 1.0),
}


VL53L1X_UNITS = {
    "fov": "rad",
    "dark_range": "m",
    "ambient_range": "m",
    "sigma_at_limit": "m",
    "sigma_floor": "m",
    "offset_sigma": "m",
    "min_range": "m",
}


#: Bounds (m) of :class:`ToFConfig` ``max_range``.
MAX_RANGE_BOUNDS = (0.1, 100.0)


@dataclass(frozen=True)
class VL53L1X:
    """The realistic ToF model (see the module docstring). Metres, radians; ``ambient`` in [0, 1]
    (0 dark, 1 strong ambient light), ``reflectance`` in (0, 1], ``dropout`` a probability."""

    fov: float = math.radians(27.0)
    rays: int = 16
    reflectance: float = 0.54
    ambient: float = 0.0
    dark_range: float = 3.6
    ambient_range: float = 0.73
    sigma_at_limit: float = 0.010
    sigma_floor: float = 0.001
    offset_sigma: float = 0.0025
    min_range: float = 0.04
    dropout: float = 0.01

    def __post_init__(self) -> None:
        set_field(self, "rays", check_int("VL53L1X.rays", self.rays, low=1, high=256))
        check_fields(self, lambda f: f"VL53L1X.{f}", VL53L1X_BOUNDS, VL53L1X_UNITS)
        if not self.ambient_range < self.dark_range:
            raise ValueError(
                f"ambient_range ({self.ambient_range:g} m) must be shorter than dark_range "
                f"({self.dark_range:g} m)"
            )

    def directions(self) -> NDArray[np.float64]:
        """(rays, 3) unit vectors in the sensor frame (beam axis +z), uniform over the cone's solid
        angle: a Vogel (golden-angle) spiral."""
        return self._directions.copy()

    @functools.cached_property
    def _directions(self) -> NDArray[np.float64]:
        k = np.arange(self.rays) + 0.5
        cos_a = 1.0 - k / self.rays * (1.0 - math.cos(self.fov / 2))
        sin_a = np.sqrt(1.0 - cos_a**2)
        phi = k * math.pi * (3.0 - math.sqrt(5.0))
        return np.column_stack([sin_a * np.cos(phi), sin_a * np.sin(phi), cos_a])

    @functools.cached_property
    def _mean_cos3(self) -> float:
        return float(np.mean(self._directions[:, 2] ** 3))

    @functools.cached_property
    def flat_gain(self) -> float:
        """Weighted mean ray length over distance for a perpendicular flat target (weights
        ``cos^3``): the reading is divided by it, so such a target reads its true distance."""
        c = self._directions[:, 2]
        return float(np.sum(c**2) / np.sum(c**3))

    @functools.cached_property
    def snr_min(self) -> float:
        """SNR at the range limit (relative units: ``S = 1`` for a perpendicular rho = 1 target at 1 m)."""
        return math.sqrt(REFERENCE_REFLECTANCE * self._mean_cos3 / self.dark_range**2)

    @functools.cached_property
    def strong_ambient(self) -> float:
        """Ambient level ``A`` of strong ambient light (``ambient = 1``), same units as the signal."""
        s = REFERENCE_REFLECTANCE * self._mean_cos3 / self.ambient_range**2
        return (s / self.snr_min) ** 2 - s

    def sigma(self, signal: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Repeatability (m, 1 sigma) at total signal ``signal`` (see the module docstring)."""
        s = np.maximum(np.asarray(signal, dtype=np.float64), 1e-12)
        snr = s / np.sqrt(s + self.ambient * self.strong_ambient)
        return np.sqrt(self.sigma_floor**2 + (self.sigma_at_limit * self.snr_min / snr) ** 2)


#: Accepted ``ToFConfig.rate_hz`` (Hz): the VL53L1X ranges at up to 50 Hz (timing budget 20 ms).
TOF_RATE_BOUNDS = (1.0, 100.0)


#: ToF presets: ``"ideal"`` (one noise-free ray) and ``"realistic"`` (:class:`VL53L1X` defaults).
TOF_PRESETS: dict[str, VL53L1X | None] = {"ideal": None, "realistic": VL53L1X()}


@dataclass(frozen=True)
class ToFConfig:
    """Four ToF sensors looking along the optical axis. ``noise`` is a key of :data:`TOF_PRESETS` or a
    :class:`VL53L1X` (custom parameters); ``max_range`` (m) caps the readings."""

    max_range: float = 4.0
    noise: str | VL53L1X = "ideal"
    #: ranging frequency (Hz) on the sensor's own clock (the VL53L1X's timing budget plus its
    #: inter-measurement period: 20-50 Hz in practice); None: one reading per control step
    rate_hz: float | None = None

    def __post_init__(self) -> None:
        lo, hi = MAX_RANGE_BOUNDS
        set_field(self, "max_range", check_real("tof max_range", self.max_range, "m", low=lo, high=hi))
        if self.rate_hz is not None:
            lo, hi = TOF_RATE_BOUNDS
            set_field(self, "rate_hz", check_real("tof_hz", self.rate_hz, "Hz", low=lo, high=hi))
        if not isinstance(self.noise, VL53L1X) and self.noise not in TOF_PRESETS:
            raise ValueError(
                f"tof_noise must be one of {sorted(TOF_PRESETS)} or a VL53L1X, got {self.noise!r}"
            )

    @property
    def model(self) -> VL53L1X | None:
        """The cone model, or None for the ideal single ray."""
        return self.noise if isinstance(self.noise, VL53L1X) else TOF_PRESETS[self.noise]


#: IMU noise presets.
IMU_NOISE_PRESETS: tuple[str, ...] = ("ideal", "realistic")


_MG = 1e-3 * GRAVITY  # m/s^2 per milli-g


_DEG = math.pi / 180.0


_TAU = (1e-3, 1e4)  # s, correlation times


#: Physical bounds (inclusive) of :class:`IMUNoise`'s fields: generous for any MEMS or tactical IMU
#: and attitude filter.
IMU_NOISE_BOUNDS: dict[str, tuple[float, float]] = {
    "gyro_noise_density": (0.0, 0.1),
    "gyro_bias_instability": (0.0, 1.0),
    "gyro_bias_time_constant": _TAU,
    "gyro_turn_on_bias": (0.0, 1.0),
    "accel_noise_density": (0.0, 1.0),
    "accel_bias_instability": (0.0, 10.0),
    "accel_bias_time_constant": _TAU,
    "accel_turn_on_bias": (0.0, 10.0),
    "tilt_sigma": (0.0, 0.5),
    "tilt_time_constant": _TAU,
    "yaw_drift_rate": (0.0, 0.1),
}


IMU_NOISE_UNITS = {
    "gyro_noise_density": "rad/s/sqrt(Hz)",
    "gyro_bias_instability": "rad/s",
    "gyro_bias_time_constant": "s",
    "gyro_turn_on_bias": "rad/s",
    "accel_noise_density": "m/s^2/sqrt(Hz)",
    "accel_bias_instability": "m/s^2",
    "accel_bias_time_constant": "s",
    "accel_turn_on_bias": "m/s^2",
    "tilt_sigma": "rad",
    "tilt_time_constant": "s",
    "yaw_drift_rate": "rad/s",
}


@dataclass(frozen=True)
class IMUNoise:
    """Noise figures of the IMU and of its attitude filter. SI units: rad/s, m/s^2, rad, s.

    Sensor: Bosch **BMI088** data sheet (BST-BMI088-DS001, rev. 1.x), typical values:

    ========================  ===================================  ====================================
    field                     value                                source
    ========================  ===================================  ====================================
    gyro_noise_density        0.014 deg/s/sqrt(Hz)                 BMI088 gyro output noise density
    gyro_bias_instability     2 deg/h                              BMI088 gyro bias stability
    gyro_bias_time_constant   100 s                                assumption (Allan minimum region)
    gyro_turn_on_bias         1 deg/s (1 sigma)                    BMI088 zero-rate offset +-1 deg/s
    accel_noise_density       160, 160, 190 ug/sqrt(Hz) (x, y, z)  BMI088 accel output noise density
    accel_bias_instability    0.2 mg                               BMI088 TCO 0.2 mg/K x 1 K in flight
                                                                   (no instability figure is given)
    accel_bias_time_constant  100 s                                assumption
    accel_turn_on_bias        20 mg (1 sigma)                      BMI088 zero-g offset +-20 mg
    ========================  ===================================  ====================================

    Attitude filter: Xsens MTi user manual (MT0605P, sec. 4.3), MTi-30 AHRS typical dynamic
    roll/pitch error 0.5 deg (1 sigma RMS), and "based on the rate gyros the attitude and heading
    estimates will degrade slowly (typically a degree every minute)" without a heading reference
    (a magnetometer is unusable next to a steel deck): ``tilt_sigma`` 0.5 deg, ``tilt_time_constant``
    5 s (assumption: the filter's accelerometer-correction time scale), ``yaw_drift_rate`` 1 deg/min
    (1 sigma).

    The datasheet's typical offsets are taken as one standard deviation (a flight controller that
    calibrates its gyro at boot would leave less: set the turn-on fields to what it leaves).
    """

    gyro_noise_density: float = 0.014 * _DEG
    gyro_bias_instability: float = 2.0 * _DEG / 3600.0
    gyro_bias_time_constant: float = 100.0
    gyro_turn_on_bias: float = 1.0 * _DEG
    accel_noise_density: float | tuple[float, float, float] = (0.160 * _MG, 0.160 * _MG, 0.190 * _MG)
    accel_bias_instability: float = 0.2 * _MG
    accel_bias_time_constant: float = 100.0
    accel_turn_on_bias: float = 20.0 * _MG
    tilt_sigma: float = 0.5 * _DEG
    tilt_time_constant: float = 5.0
    yaw_drift_rate: float = 1.0 * _DEG / 60.0

    def __post_init__(self) -> None:
        density = self.accel_noise_density
        if isinstance(density, tuple | list | np.ndarray):
            if len(density) != 3:
                raise ValueError(
                    f"IMUNoise.accel_noise_density must be one number or 3 (x, y, z), got {density!r}"
                )
            lo, hi = IMU_NOISE_BOUNDS["accel_noise_density"]
            set_field(
                self,
                "accel_noise_density",
                check_reals("IMUNoise.accel_noise_density", density, 3, "m/s^2/sqrt(Hz)", low=lo, high=hi),
            )
            bounds = {k: v for k, v in IMU_NOISE_BOUNDS.items() if k != "accel_noise_density"}
        else:
            bounds = IMU_NOISE_BOUNDS
        check_fields(self, lambda f: f"IMUNoise.{f}", bounds, IMU_NOISE_UNITS)


@dataclass(frozen=True)
class IMUConfig:
    """``noise``: a key of :data:`IMU_NOISE_PRESETS` or an :class:`IMUNoise` (custom figures)."""

    noise: str | IMUNoise = "ideal"
    #: output data rate (Hz) on the IMU's own clock (the latest sample is shown); None: one sample
    #: per control step
    rate_hz: float | None = None

    def __post_init__(self) -> None:
        if self.rate_hz is not None:
            lo, hi = IMU_RATE_BOUNDS
            set_field(self, "rate_hz", check_real("imu_hz", self.rate_hz, "Hz", low=lo, high=hi))
        if not isinstance(self.noise, IMUNoise) and self.noise not in IMU_NOISE_PRESETS:
            raise ValueError(
                f"imu_noise must be one of {IMU_NOISE_PRESETS} or an IMUNoise, got {self.noise!r}"
            )

    @property
    def model(self) -> IMUNoise | None:
        """The noise figures, or None for the ideal IMU."""
        if isinstance(self.noise, IMUNoise):
            return self.noise
        return None if self.noise == "ideal" else IMUNoise()


#: Accepted ``IMUConfig.rate_hz`` (Hz).
IMU_RATE_BOUNDS = (1.0, 10_000.0)

__all__ = [
    "BACKGROUNDS",
    "CAMERA_QUALITIES",
    "FULL_SCALE_DN",
    "IMU_NOISE_BOUNDS",
    "IMU_NOISE_PRESETS",
    "IMU_NOISE_UNITS",
    "IMU_RATE_BOUNDS",
    "MAX_LATENCY",
    "MAX_RANGE_BOUNDS",
    "PIPELINE_LATENCY",
    "REFERENCE_REFLECTANCE",
    "TOF_PRESETS",
    "TOF_RATE_BOUNDS",
    "VL53L1X",
    "VL53L1X_BOUNDS",
    "VL53L1X_UNITS",
    "CameraConfig",
    "IMUConfig",
    "IMUNoise",
    "ImagingParams",
    "ToFConfig",
]
