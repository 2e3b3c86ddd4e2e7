"""Where the configuration finds the checks of the options that name user components
(``sensors``, ``measurement_noise``, ``faults``): a slot the package root fills.

The registries of sensors, noise models and faults belong to the simulator
(:mod:`ihrcf_env.sim.registry`); :func:`ihrcf_env.config.make.make_config` checks those options
with them, but the configuration imports nothing above the core. So the package root registers
a provider here (:func:`register_component_checks`) that imports the simulator's registry the
first time an option is checked. This module imports nothing of the package: like
``ihrcf_env._version``, it sits below every layer.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from typing import Any, Protocol

__all__ = ["ComponentChecks", "component_checks", "register_component_checks"]


class ComponentChecks(Protocol):
    """What :func:`~ihrcf_env.config.make.make_config` asks of the component registries (each
    raises TypeError / ValueError naming the option)."""

    def check_sensor_names(self, value: Any) -> tuple[str, ...]:
        """The ``sensors`` option: registered sensor names."""
        ...

    def check_measurement_noise(self, value: Any, sensors: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
        """The ``measurement_noise`` option: ``(measurement, noise model)`` pairs."""
        ...

    def check_faults(
        self,
        value: Any,
        measurements: Collection[str] | None = None,
        context: Mapping[str, Any] | None = None,
    ) -> tuple[tuple[str, tuple[tuple[str, Any], ...]], ...]:
        """The ``faults`` option: ``(name, ((parameter, value), ...))`` pairs."""
        ...

    def world_measurements(self, camera_output: str | None, sensors: tuple[str, ...] = ()) -> frozenset[str]:
        """What a world with this camera output and these sensors measures."""
        ...


_provider: Callable[[], Any] | None = None


def register_component_checks(provider: Callable[[], Any]) -> None:
    """Make ``provider()`` (called when the checks are needed, e.g. importing the simulator's
    registry) give the :class:`ComponentChecks` of every later ``make_config``."""
    global _provider
    if not callable(provider):
        raise TypeError(f"provider must be callable (() -> ComponentChecks), got {provider!r}")
    _provider = provider


def component_checks() -> ComponentChecks:
    """The registered :class:`ComponentChecks`; RuntimeError if none is registered (importing
    ``ihrcf_env`` registers the simulator's)."""
    if _provider is None:
        raise RuntimeError("no component registry is registered: import ihrcf_env first")
    checks: ComponentChecks = _provider()
    return checks
