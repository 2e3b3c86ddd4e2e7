"""Spreading a batch of envs over the host's devices with JAX's own sharding.

A batch of N envs is split along its leading (env) axis into equal shards, one per device of a
one-dimensional :class:`jax.sharding.Mesh` whose axis is named :data:`ENV_AXIS`; a per-shard
function runs on each device under :func:`jax.shard_map` with no communication between them (every
env's computation is its own). On a CPU, JAX shows one device unless asked for more:
:func:`request_host_devices` asks for one device per core this process may run on
(``os.sched_getaffinity``) before JAX starts its backend, so the shards run on separate cores. On a
machine with several GPUs the same mesh spans them (``jax.devices()``): nothing here is specific to
the CPU but the device request.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

__all__ = [
    "ENV_AXIS",
    "check_device_count",
    "check_devices",
    "env_mesh",
    "host_cores",
    "request_host_devices",
    "shard_envs",
]

#: The mesh axis the env batch is split along.
ENV_AXIS = "envs"


def host_cores() -> int:
    """The cores this process may run on (its CPU affinity; all the host's where that is unknown)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def check_device_count(devices: Any) -> None:
    """``devices`` is None or a positive int (ValueError naming it)."""
    if devices is not None and (isinstance(devices, bool) or not isinstance(devices, int) or devices < 1):
        raise ValueError(f"devices must be a positive int, got {devices!r}")


def request_host_devices(count: int | None = None) -> int:
    """Ask JAX for ``count`` CPU devices (default: :func:`host_cores`) if its backend has not
    started yet (the request must precede any JAX computation); returns the devices JAX has now.
    A backend already started keeps the devices it has (a request cannot change them)."""
    import jax
    from jax._src import xla_bridge

    check_device_count(count)
    if count is not None and count > host_cores():
        raise ValueError(f"devices={count}: this process may use {host_cores()} core(s)")
    want = host_cores() if count is None else count
    if not xla_bridge.backends_are_initialized() and getattr(jax.config, "jax_num_cpu_devices", -1) < 0:
        jax.config.update("jax_num_cpu_devices", want)
    return len(jax.devices())


def check_devices(devices: Any, num_envs: int) -> int:
    """``devices`` (None: every device JAX has) checked against the devices JAX has and against
    ``num_envs`` (the batch must split into equal shards); returns the count. Errors name the
    argument."""
    import jax

    have = len(jax.devices())
    if devices is None:
        devices = have
        # fall back to fewer devices when the batch does not split over all of them
        while num_envs % devices:
            devices -= 1
        return devices
    check_device_count(devices)
    if devices > have:
        raise ValueError(
            f"devices={devices}: JAX has {have} device(s) here ({jax.devices()[0].platform}); on a CPU, "
            "the devices are requested before JAX starts (ihrcf_env.vector.jax_devices.request_host_devices)"
        )
    if num_envs % devices:
        raise ValueError(f"num_envs={num_envs} does not split over devices={devices}: use a multiple of it")
    return devices


def env_mesh(devices: int) -> Any:
    """A one-dimensional mesh of the first ``devices`` devices along :data:`ENV_AXIS`."""
    import jax
    import numpy as np
    from jax.sharding import Mesh

    return Mesh(np.asarray(jax.devices()[:devices]), (ENV_AXIS,))


def shard_envs(fn: Callable[..., Any], mesh: Any) -> Callable[..., Any]:
    """``fn`` (batched arguments in, batched results out, every leaf along its leading env axis) run
    on each device's shard of the batch (:func:`jax.shard_map`); with a one-device mesh, ``fn``."""
    import jax
    from jax.sharding import PartitionSpec

    if mesh.devices.size == 1:
        return fn
    spec = PartitionSpec(ENV_AXIS)
    return jax.shard_map(fn, mesh=mesh, in_specs=spec, out_specs=spec, check_vma=False)
