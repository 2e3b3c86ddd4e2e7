"""Extension points of the simulation: sensors and measurement-noise models, added by name.

A **sensor** is a class with the :class:`~ihrcf_env.sim.sensors.base.Sensor` shape (``reset(rng)``,
``read(state, dt, rng) -> {measurement: array}``, optional ``update_interval``) plus a registration
saying how to build it from the world and what it measures::

    register_sensor("baro", lambda world: Barometer(), {"pressure": SensorOutput((1,), 0.0, 2e5)})
    gym.make("ihrcf_env/DeckHoverRaw-v0", sensors=("baro",))   # obs["pressure"]

A **noise model** (:class:`~ihrcf_env.sim.noise.NoiseModel`: ``reset(rng)``,
``apply(value, valid, dt, rng)``) is registered with a factory of the measurement's size and
applied to any measurement by option::

    register_noise_model("spikes", lambda size: Spikes(size))
    gym.make(..., measurement_noise={"ranges": "spikes"})

Both draw their randomness from their own streams (``"sensor.<name>"``, ``"noise.<measurement>"``),
so adding one never changes the start, deck or wind of a seed. Registering is process-wide; the
options are validated by name like every other option.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ihrcf_env.core.checks import check_real, describe
from ihrcf_env.sim.noise import NoiseModel, NoNoise

if TYPE_CHECKING:
    from ihrcf_env.sim.sensors.base import Sensor
    from ihrcf_env.sim.world import World


@dataclass(frozen=True)
class SensorOutput:
    """One measurement of a registered sensor: its array ``shape`` and the bounds of its values
    (the observation clips into them; NaN reads as ``low``)."""

    shape: tuple[int, ...]
    low: float
    high: float

    def __post_init__(self) -> None:
        if not isinstance(self.shape, tuple) or not all(isinstance(n, int) and n > 0 for n in self.shape):
            raise ValueError(f"SensorOutput.shape must be a tuple of positive ints, got {self.shape!r}")
        lo = check_real("SensorOutput.low", self.low, low=-1e12, high=1e12)
        hi = check_real("SensorOutput.high", self.high, low=lo, high=1e12)
        object.__setattr__(self, "low", lo)
        object.__setattr__(self, "high", hi)


@dataclass(frozen=True)
class SensorEntry:
    """A registered sensor: ``factory(world) -> Sensor`` and its measurements."""

    factory: Callable[[World], Sensor]
    outputs: Mapping[str, SensorOutput]


#: Measurements of the built-in sensors (a registered sensor may not reuse these names).
BUILTIN_MEASUREMENTS: tuple[str, ...] = (
    "image",
    "tag_corners",
    "tag_detected",
    "tag_reason",
    "tag_status",
    "ranges",
    "ranges_valid",
    "quaternion",
    "angular_velocity",
    "linear_acceleration",
)
#: Built-in measurements a registered noise model may corrupt, with their sizes.
NOISY_MEASUREMENTS: dict[str, int] = {
    "ranges": 4,
    "angular_velocity": 3,
    "linear_acceleration": 3,
    "tag_corners": 8,
}
#: Observation keys the env uses itself.
RESERVED_KEYS: frozenset[str] = frozenset(
    {*BUILTIN_MEASUREMENTS, "imu", "camera_age", "nav_velocity", "ground_truth", "motion"}
)

SENSORS: dict[str, SensorEntry] = {}
NOISE_MODELS: dict[str, Callable[[int], NoiseModel]] = {"none": lambda size: NoNoise()}


def register_sensor(
    name: str,
    factory: Callable[[World], Sensor],
    outputs: Mapping[str, SensorOutput],
    *,
    replace: bool = False,
) -> None:
    """Add the sensor ``name`` (enabled by the option ``sensors=(name, ...)``). Its measurements
    become observation keys: they must not clash with the built-in ones or another sensor's."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"sensor name must be an identifier, got {name!r}")
    if not callable(factory):
        raise TypeError(f"sensor factory must be callable (World -> Sensor), got {describe(factory)}")
    if not isinstance(outputs, Mapping) or not outputs:
        raise TypeError(f"sensor outputs must be a non-empty dict of SensorOutput, got {describe(outputs)}")
    for key, out in outputs.items():
        if not isinstance(out, SensorOutput):
            raise TypeError(f"sensor output {key!r} must be a SensorOutput, got {describe(out)}")
        if not isinstance(key, str) or not key.isidentifier() or key in RESERVED_KEYS:
            raise ValueError(f"sensor output name {key!r} is not an identifier or is taken by the env")
        for other, entry in SENSORS.items():
            if other != name and key in entry.outputs:
                raise ValueError(f"sensor output {key!r} is already measured by the sensor {other!r}")
    if name in SENSORS and not replace:
        raise ValueError(f"a sensor {name!r} is already registered (replace=True to replace it)")
    SENSORS[name] = SensorEntry(factory, dict(outputs))


def register_noise_model(name: str, factory: Callable[[int], NoiseModel], *, replace: bool = False) -> None:
    """Add the noise model ``name``: ``factory(size)`` builds one for a measurement of ``size``
    values (applied by the option ``measurement_noise={measurement: name}``)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"noise model name must be an identifier, got {name!r}")
    if not callable(factory):
        raise TypeError(f"noise model factory must be callable (size -> NoiseModel), got {describe(factory)}")
    if name in NOISE_MODELS and not replace:
        raise ValueError(f"a noise model {name!r} is already registered (replace=True to replace it)")
    NOISE_MODELS[name] = factory


def check_sensor_names(value: Any) -> tuple[str, ...]:
    """The ``sensors`` option: registered names, each once."""
    if isinstance(value, str) or not isinstance(value, tuple | list):
        raise TypeError(f"sensors must be a sequence of registered sensor names, got {describe(value)}")
    names = tuple(value)
    for n in names:
        if n not in SENSORS:
            raise ValueError(f"sensors: unknown sensor {n!r}; registered: {sorted(SENSORS)}")
    if len(set(names)) != len(names):
        raise ValueError(f"sensors: a name is given twice in {list(names)}")
    return names


def measurement_sizes(sensors: tuple[str, ...]) -> dict[str, int]:
    """Measurement name -> size of what a noise model may corrupt, with these extra sensors."""
    sizes = dict(NOISY_MEASUREMENTS)
    for s in sensors:
        for key, out in SENSORS[s].outputs.items():
            n = 1
            for d in out.shape:
                n *= d
            sizes[key] = n
    return sizes


def check_measurement_noise(value: Any, sensors: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
    """The ``measurement_noise`` option: {measurement: registered noise model name}."""
    if value is None:
        return ()
    if not isinstance(value, Mapping):
        raise TypeError(
            f"measurement_noise must be a dict {{measurement: noise model}}, got {describe(value)}"
        )
    sizes = measurement_sizes(sensors)
    out = []
    for key, model in value.items():
        if key not in sizes:
            raise ValueError(f"measurement_noise: no measurement {key!r}; noisy ones: {sorted(sizes)}")
        if model not in NOISE_MODELS:
            raise ValueError(
                f"measurement_noise[{key!r}]: unknown noise model {model!r}; "
                f"registered: {sorted(NOISE_MODELS)}"
            )
        out.append((str(key), str(model)))
    return tuple(out)
