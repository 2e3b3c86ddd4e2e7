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

A **fault** (:class:`Fault`: ``reset(rng)``, ``apply(reading, time, dt, rng) -> reading``) acts on
a whole sensor reading, several measurements at once (a lost camera frame clears the corners and
sets ``tag_detected``, ``tag_reason`` and ``tag_status``), after the noise models. It is registered
with a factory of its parameters and switched on by the option ``faults={name: params or True}``;
each draws from its own stream ``"fault.<name>"``. Built in: :mod:`ihrcf_env.sim.faults`::

    register_fault("tof_glare", lambda **params: Glare(**params), acts_on=("ranges",))
    gym.make(..., faults={"tof_dead": {"sensors": [2]}, "camera_dropout": True})
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_real, describe
from ihrcf_env.core.estimators.registry import ESTIMATORS
from ihrcf_env.core.keys import INFO_KEYS, OBSERVATION_KEYS, env_key_reason
from ihrcf_env.sim import faults as _faults
from ihrcf_env.sim.noise import NoiseModel, NoNoise
from ihrcf_env.sim.sensors.base import tag_reading

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
#: Names a registered sensor's output may not take: the built-in measurements and the env's own
#: observation and info keys (:mod:`ihrcf_env.core.keys`); a registered estimator's name is refused
#: too (it is an observation key of the estimate wrapper).
RESERVED_KEYS: frozenset[str] = frozenset({*BUILTIN_MEASUREMENTS, *OBSERVATION_KEYS, *INFO_KEYS})


def output_name_reason(key: str) -> str | None:
    """Why a sensor output may not be called ``key`` (the key of the env or of an estimator it
    would overwrite), or None if it may."""
    if key in BUILTIN_MEASUREMENTS:
        return f"a built-in measurement is called {key!r}"
    reason = env_key_reason(key)
    if reason is not None:
        return reason
    if key in ESTIMATORS:
        return f"the estimator {key!r} writes obs[{key!r}]"
    return None


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
        if not isinstance(key, str) or not key.isidentifier():
            raise ValueError(f"register_sensor({name!r}): output name {key!r} is not an identifier")
        _check_output_name(name, key)
        for other, entry in SENSORS.items():
            if other != name and key in entry.outputs:
                raise ValueError(f"sensor output {key!r} is already measured by the sensor {other!r}")
    if name in SENSORS and not replace:
        raise ValueError(f"a sensor {name!r} is already registered (replace=True to replace it)")
    SENSORS[name] = SensorEntry(_checked_sensor_factory(name, factory, dict(outputs)), dict(outputs))


def _check_output_name(sensor: str, key: str) -> None:
    reason = output_name_reason(key)
    if reason is not None:
        raise ValueError(f"sensor {sensor!r}: output name {key!r} is reserved, taken by the env ({reason})")


def _checked_sensor_factory(
    name: str, factory: Callable[[World], Sensor], outputs: Mapping[str, SensorOutput]
) -> Callable[[World], Sensor]:
    """``factory`` whose sensor is checked when built and whose readings are checked
    (:class:`CheckedSensor`)."""

    def build(world: World) -> Sensor:
        sensor = factory(world)
        for method in ("reset", "read"):
            if not callable(getattr(sensor, method, None)):
                raise TypeError(
                    f"sensor {name!r}: its factory must return a Sensor (reset(rng), read(state, dt, "
                    f"rng)), got {describe(sensor)} without {method}()"
                )
        return CheckedSensor(name, sensor, outputs)

    return build


class CheckedSensor:
    """A registered sensor whose readings are checked: exactly its declared outputs, each of real
    numbers of its declared size (ValueError / TypeError naming the sensor otherwise). Other
    attributes (``update_interval``) are the sensor's."""

    def __init__(self, name: str, sensor: Any, outputs: Mapping[str, SensorOutput]) -> None:
        self.name, self.sensor, self.outputs = name, sensor, outputs

    def __getattr__(self, attr: str) -> Any:
        return getattr(self.__dict__["sensor"], attr)

    def reset(self, rng: np.random.Generator) -> None:
        self.sensor.reset(rng)

    def read(self, state: Any, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        reading = self.sensor.read(state, dt, rng)
        if not isinstance(reading, Mapping) or set(reading) != set(self.outputs):
            got = sorted(reading) if isinstance(reading, Mapping) else describe(reading)
            raise ValueError(
                f"sensor {self.name!r}: read() must return {{output: array}} of its outputs "
                f"{sorted(self.outputs)}, got {got}"
            )
        out: dict[str, NDArray] = {}
        for key, spec in self.outputs.items():
            value = _real_array(f"sensor {self.name!r}: output {key!r}", reading[key])
            if value.size != int(np.prod(spec.shape)):
                raise ValueError(
                    f"sensor {self.name!r}: output {key!r} must have shape {spec.shape}, got {value.shape}"
                )
            out[key] = value
        return out


def _real_array(what: str, value: Any) -> NDArray:
    """``value`` as an array of real numbers (bools, ints, floats), or TypeError naming ``what``."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be an array of real numbers, got {describe(value)}") from None
    if a.dtype.kind not in "biuf":
        raise TypeError(f"{what} must be an array of real numbers, got an array of {a.dtype}")
    return a


def register_noise_model(name: str, factory: Callable[[int], NoiseModel], *, replace: bool = False) -> None:
    """Add the noise model ``name``: ``factory(size)`` builds one for a measurement of ``size``
    values (applied by the option ``measurement_noise={measurement: name}``)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"noise model name must be an identifier, got {name!r}")
    if not callable(factory):
        raise TypeError(f"noise model factory must be callable (size -> NoiseModel), got {describe(factory)}")
    if name in NOISE_MODELS and not replace:
        raise ValueError(f"a noise model {name!r} is already registered (replace=True to replace it)")
    NOISE_MODELS[name] = _checked_noise_factory(name, factory)


def _checked_noise_factory(name: str, factory: Callable[[int], NoiseModel]) -> Callable[[int], NoiseModel]:
    """``factory`` whose model is checked when built and whose outputs are checked
    (:class:`CheckedNoiseModel`)."""

    def build(size: int) -> NoiseModel:
        model = factory(size)
        for method in ("reset", "apply"):
            if not callable(getattr(model, method, None)):
                raise TypeError(
                    f"noise model {name!r}: its factory must return a NoiseModel (reset(rng), "
                    f"apply(value, valid, dt, rng)), got {describe(model)} without {method}()"
                )
        return CheckedNoiseModel(name, model, size)

    return build


class CheckedNoiseModel:
    """A registered noise model whose ``apply`` is checked: ``(value, valid)`` of the measurement's
    size, real numbers (ValueError / TypeError naming the model otherwise); values it makes
    non-finite are flagged invalid (see :func:`finite_reading` for what they then read)."""

    def __init__(self, name: str, model: NoiseModel, size: int) -> None:
        self.name, self.model, self.size = name, model, int(size)

    def __getattr__(self, attr: str) -> Any:
        return getattr(self.__dict__["model"], attr)

    def reset(self, rng: np.random.Generator) -> None:
        self.model.reset(rng)

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        out = self.model.apply(value, valid, dt, rng)
        what = f"noise model {self.name!r}"
        if not isinstance(out, tuple | list) or len(out) != 2:
            raise TypeError(f"{what}: apply() must return (value, valid), got {describe(out)}")
        noisy = _real_array(f"{what}: value", out[0]).astype(np.float64).ravel()
        ok = _real_array(f"{what}: valid", out[1]).astype(bool).ravel()
        for label, a in (("value", noisy), ("valid", ok)):
            if a.size != self.size:
                raise ValueError(f"{what}: apply() must return a {label} of {self.size} values, got {a.size}")
        return noisy, ok & np.isfinite(noisy)


def check_sensor_names(value: Any) -> tuple[str, ...]:
    """The ``sensors`` option: registered names, each once, whose outputs clash with no key of the
    env or of a registered estimator."""
    if isinstance(value, str) or not isinstance(value, tuple | list):
        raise TypeError(f"sensors must be a sequence of registered sensor names, got {describe(value)}")
    names = tuple(value)
    for n in names:
        if n not in SENSORS:
            raise ValueError(f"sensors: unknown sensor {n!r}; registered: {sorted(SENSORS)}")
    if len(set(names)) != len(names):
        raise ValueError(f"sensors: a name is given twice in {list(names)}")
    for n in names:  # an estimator registered after the sensor may have taken an output's name
        for key in SENSORS[n].outputs:
            _check_output_name(n, key)
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


# -- faults ------------------------------------------------------------------------------------------
@runtime_checkable
class Fault(Protocol):
    """A sensor failure acting on whole readings (several measurements at once).

    ``reset(rng)`` draws the episode's fault; ``apply(reading, time, dt, rng)`` returns the faulty
    reading as a new dict (``reading`` is one sensor's mapping, after the noise models; keys the
    fault does not act on pass unchanged, a reading without its keys passes whole). ``time`` (s) is
    the reading's time since the episode's start, ``dt`` (s) the time since the sensor's previous
    sample. An optional ``check_with(faults: {name: Fault})`` raises ValueError for a combination
    of faults that contradict each other."""

    def reset(self, rng: np.random.Generator) -> None: ...

    def apply(
        self, reading: Mapping[str, NDArray], time: float, dt: float, rng: np.random.Generator
    ) -> dict[str, NDArray]: ...


@dataclass(frozen=True)
class FaultEntry:
    """A registered fault: ``factory(**params) -> Fault`` and the measurements it acts on."""

    factory: Callable[..., Fault]
    acts_on: frozenset[str]


FAULTS: dict[str, FaultEntry] = {}
#: A validated ``faults`` option: (name, ((parameter, value), ...)) pairs, lists made tuples.
FaultSpec = tuple[tuple[str, tuple[tuple[str, Any], ...]], ...]


def register_fault(
    name: str, factory: Callable[..., Fault], acts_on: Collection[str] = (), *, replace: bool = False
) -> None:
    """Add the fault ``name``: ``factory(**params)`` builds one (it validates its parameters,
    raising TypeError / ValueError naming them), switched on by ``faults={name: params or True}``.
    ``acts_on``: the measurements it changes (an env without any of them refuses the fault)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"fault name must be an identifier, got {name!r}")
    if not callable(factory):
        raise TypeError(f"fault factory must be callable (**params -> Fault), got {describe(factory)}")
    if isinstance(acts_on, str) or not all(isinstance(k, str) for k in acts_on):
        raise TypeError(f"fault acts_on must be a sequence of measurement names, got {describe(acts_on)}")
    if name in FAULTS and not replace:
        raise ValueError(f"a fault {name!r} is already registered (replace=True to replace it)")
    FAULTS[name] = FaultEntry(factory, frozenset(acts_on))


def _frozen_param(value: Any) -> Any:
    """Lists (and arrays) as tuples, so a validated option is hashable and compares by value."""
    if isinstance(value, list | tuple | np.ndarray):
        return tuple(_frozen_param(v) for v in value)
    return value


def _parameters(factory: Callable[..., Fault]) -> list[str] | None:
    """The keyword parameters ``factory`` accepts (None: any, or not inspectable)."""
    try:
        params = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
        return None
    return [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


def build_fault(name: str, params: Mapping[str, Any]) -> Fault:
    """The registered fault ``name`` built with ``params``; errors name the option and parameter."""
    entry = FAULTS[name]
    known = _parameters(entry.factory)
    if known is not None:
        for key in params:
            if key not in known:
                raise ValueError(f"faults[{name!r}]: unknown parameter {key!r}; parameters: {known}")
    try:
        fault = entry.factory(**params)
    except (TypeError, ValueError) as e:
        raise type(e)(f"faults[{name!r}]: {e}") from None
    if not (callable(getattr(fault, "reset", None)) and callable(getattr(fault, "apply", None))):
        raise TypeError(f"faults[{name!r}]: the factory must return a Fault, got {describe(fault)}")
    return fault


def build_faults(spec: FaultSpec) -> dict[str, Fault]:
    """Name -> a new fault of each entry of a validated ``faults`` option (:func:`check_faults`),
    in the option's order (the order they are applied in)."""
    return {name: build_fault(name, dict(params)) for name, params in spec}


def check_faults(
    value: Any,
    measurements: Collection[str] | None = None,
    context: Mapping[str, Any] | None = None,
) -> FaultSpec:
    """The ``faults`` option: ``{name: params dict, True (defaults) or False (off)}`` of registered
    faults. Every fault is built once, so bad parameters are refused here, naming them, and so are
    contradicting faults. ``measurements``: what the env measures (a fault acting on none of them is
    refused); ``context``: world settings handed to every factory taking a parameter of that name
    unless given (e.g. ``tof_max_range``, the value an invalid ToF reading reads)."""
    if value is None:
        return ()
    if not isinstance(value, Mapping):
        raise TypeError(f"faults must be a dict {{fault: params dict or True}}, got {describe(value)}")
    out = []
    built: dict[str, Fault] = {}
    for name, params in value.items():
        if name not in FAULTS:
            raise ValueError(f"faults: unknown fault {name!r}; registered: {sorted(FAULTS)}")
        if params is False:
            continue
        if params is True:
            params = {}
        if not isinstance(params, Mapping) or not all(isinstance(k, str) for k in params):
            raise TypeError(
                f"faults[{name!r}] must be a dict of its parameters or True, got {describe(params)}"
            )
        entry = FAULTS[name]
        if measurements is not None and entry.acts_on and not entry.acts_on & set(measurements):
            raise ValueError(
                f"faults[{name!r}] acts on {sorted(entry.acts_on)}, which this env does not measure"
            )
        full = dict(params)
        known = _parameters(entry.factory) or []
        for key, setting in (context or {}).items():
            if key in known and key not in full:
                full[key] = setting
        built[name] = build_fault(name, full)
        out.append((str(name), tuple((k, _frozen_param(v)) for k, v in full.items())))
    for fault in built.values():
        check_with = getattr(fault, "check_with", None)
        if callable(check_with):
            check_with(built)
    return tuple(out)


def world_measurements(camera_output: str | None, sensors: tuple[str, ...] = ()) -> frozenset[str]:
    """What a world measures (the ``measurements`` of :func:`check_faults`): the camera's
    (``camera_output`` "image" or "corners"; None without a camera), the ToF's and the IMU's, and
    the registered ``sensors``'."""
    camera = {
        "image": ("image",),
        "corners": ("tag_corners", "tag_detected", "tag_reason", "tag_status"),
        None: (),
    }[camera_output]
    out = {*camera, "ranges", "ranges_valid", "quaternion", "angular_velocity", "linear_acceleration"}
    for s in sensors:
        out |= set(SENSORS[s].outputs)
    return frozenset(out)


def apply_faults(
    faults: Mapping[str, Fault],
    reading: Mapping[str, NDArray],
    time: float,
    dt: float,
    generator: Callable[[str], np.random.Generator],
) -> dict[str, NDArray]:
    """``reading`` through every fault in order; ``generator(name)`` is the fault's stream. Each
    fault must return the reading's keys with their shapes (ValueError / TypeError naming it)."""
    out = dict(reading)
    for name, fault in faults.items():
        new = fault.apply(out, time, dt, generator(name))
        if not isinstance(new, Mapping) or set(new) != set(out):
            got = sorted(new) if isinstance(new, Mapping) else describe(new)
            raise ValueError(
                f"faults[{name!r}]: apply() must return the reading's keys {sorted(out)}, got {got}"
            )
        for key, value in new.items():
            before = np.asarray(out[key])
            if before.dtype.kind not in "biuf":  # text (a reason) or other values: passed as they are
                continue
            a = _real_array(f"faults[{name!r}]: {key!r}", value)
            if a.shape != before.shape:
                raise ValueError(
                    f"faults[{name!r}]: {key!r} must keep its shape {before.shape}, got {a.shape}"
                )
        out = dict(new)
    return out


#: ``tag_reason`` of tag corners a noise model or fault made non-finite.
REASON_NOT_FINITE = "tag corners not finite (measurement noise or fault)"
#: Measurements with a validity flag: non-finite values there are flagged invalid, not refused.
_FLAGGED = ("ranges", "tag_corners")


def finite_reading(
    reading: Mapping[str, NDArray],
    max_range: float,
    noise: Mapping[str, object] | None = None,
    faults: Mapping[str, object] | None = None,
) -> dict[str, NDArray]:
    """``reading`` after its noise models and faults, with no NaN/inf left: non-finite ranges read
    ``max_range`` (m) with ``ranges_valid = 0``, as a reading with no target does; non-finite tag
    corners make the frame a non-detection (``tag_reason`` :data:`REASON_NOT_FINITE`). Any other
    built-in measurement (the IMU's) that is not finite raises ValueError naming it and the noise
    models and faults configured (``noise``: measurement -> model, ``faults``: name -> fault);
    registered sensors' outputs pass (the observation reads their NaN as the output's low). Without
    noise models and faults the reading passes as it is (the built-in sensors' readings are
    finite)."""
    if not noise and not faults:
        return dict(reading)
    out = dict(reading)
    if "ranges" in out:
        r = np.asarray(out["ranges"])
        bad = ~np.isfinite(r)
        if bad.any():
            out["ranges"] = np.where(bad, max_range, r).astype(r.dtype)
            if "ranges_valid" in out:
                v = np.asarray(out["ranges_valid"])
                out["ranges_valid"] = np.where(bad, 0, v).astype(v.dtype)
    if "tag_corners" in out and not np.isfinite(np.asarray(out["tag_corners"], np.float64)).all():
        out.update({k: v for k, v in tag_reading(None, REASON_NOT_FINITE).items() if k in out})
    for key in BUILTIN_MEASUREMENTS:
        if key in out and key not in _FLAGGED and np.asarray(out[key]).dtype.kind == "f":
            if not np.isfinite(out[key]).all():
                models = {k: getattr(m, "name", type(m).__name__) for k, m in (noise or {}).items()}
                raise ValueError(
                    f"measurement {key!r} is not finite after the noise models {models} and the "
                    f"faults {sorted(faults or {})}: a noise model or fault returned NaN or inf"
                )
    return out


register_fault("tof_dead", _faults.ToFDead, ("ranges",))
register_fault("tof_stuck", _faults.ToFStuck, ("ranges",))
register_fault("camera_dropout", _faults.CameraDropout, ("tag_corners", "image"))
register_fault("tag_occlusion", _faults.TagOcclusion, ("tag_corners",))
register_fault("imu_bias_step", _faults.ImuBiasStep, ("angular_velocity", "linear_acceleration"))

__all__ = [
    "BUILTIN_MEASUREMENTS",
    "FAULTS",
    "NOISE_MODELS",
    "NOISY_MEASUREMENTS",
    "RESERVED_KEYS",
    "SENSORS",
    "Fault",
    "FaultEntry",
    "FaultSpec",
    "SensorEntry",
    "SensorOutput",
    "apply_faults",
    "build_fault",
    "build_faults",
    "check_faults",
    "check_measurement_noise",
    "check_sensor_names",
    "measurement_sizes",
    "register_fault",
    "register_noise_model",
    "register_sensor",
    "world_measurements",
]
