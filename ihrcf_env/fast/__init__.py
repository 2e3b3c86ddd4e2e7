"""Array kernels of the landing step in JAX: pure per-env functions over ``jax.numpy`` arrays.

Every kernel here takes the arrays of one environment (no leading batch axis) and is meant to be
``jax.vmap``-ped over environments and ``jax.jit``-compiled; none branches on data (flags and
``jnp.where`` instead), every loop has a fixed count, and the small linear algebra is written out
(no ``jnp.linalg``). Each kernel ports a reference of :mod:`ihrcf_env.core` or the simulator's
array twins; ``docs/jax-backend.md`` lists what each one matches. Needs the ``[jax]`` extra.

Modules: :mod:`.linalg3` (3-vectors, 3x3 matrices, Euler angles, small SVDs), :mod:`.camera` (tag
points through the camera), :mod:`.rays` (range beams against the ground, the Stewart base and the
deck plate), :mod:`.tof` (the ToF readings), :mod:`.homography`, :mod:`.plane`, :mod:`.rigid`,
:mod:`.table` and :mod:`.ihrcf` (the IHRCF pose), :mod:`.ippe`, :mod:`.lm` and :mod:`.pnp` (ATDA's
PnP), :mod:`.dynamics` (the physics tick, mixer, ground effect), :mod:`.autopilot` (the velocity
controller), :mod:`.deck_motion` (profiles, the ship, Stewart legs), :mod:`.contact` (touchdown
geometry), :mod:`.wind`, :mod:`.navigation` (GNSS/INS errors), :mod:`.detector` (the fitted detector
model), :mod:`.tag_camera` (the projected camera's reading), :mod:`.frames` (camera latency and
frame dropout), :mod:`.imu`, :mod:`.imm` (the fused filter's bank), :mod:`.fused_blocks` and
:mod:`.fused` (the IMU-fused filter), :mod:`.advance` (one control period of flight).
"""

from __future__ import annotations

__all__: list[str] = []
