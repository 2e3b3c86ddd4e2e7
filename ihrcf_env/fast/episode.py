"""One episode's random quantities as arrays (:class:`Episode`): drawn on the host from the PyBullet
env's named streams (:func:`host_episode`: the same start, deck motion, wind and sensor episode
state as the env's seed), or in JAX from a key (:func:`draw_episode`, for pure-JAX training).

What pairs with the PyBullet env (:func:`host_episode` of the env's episode key): the start
(stream ``"start"``), the deck motion (``"deck"``, with its redraws), the wind (``"wind"``: mean
wind and the gust sequence), the navigation errors' start (``"navigation"``), the IMU's biases
(``"sensor.imu"``), the ToF offsets (``"sensor.tof"``), the realistic camera's imaging draw and
the corner-error field (``"sensor.tag_camera"``) and the dead ToF sensor and its onset
(``"fault.tof_dead"``). The per-step noise (navigation errors per tick, ToF, IMU and detector
noise, frame dropout) is drawn per step, from the step's key (:func:`ihrcf_env.fast.step.step`) or
given (:func:`ihrcf_env.fast.step.step_with`); :func:`host_streams` gives the generators the
env draws it from, for a lockstep comparison.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.core.profiles import ShiftedProfile, SumOfSines
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.core.ship import ShipMotion as CoreShipMotion
from ihrcf_env.fast.deck_motion import ShipMotion, ship_motion, sines_arrays
from ihrcf_env.fast.imu import RESET_DRAWS, reset_draws
from ihrcf_env.fast.params import StepParams
from ihrcf_env.tasks import episode as draws

__all__ = [
    "TAG_CAMERA_STREAM",
    "Episode",
    "Imaging",
    "Sines",
    "draw_episode",
    "host_episode",
    "host_streams",
    "imaging_draw",
    "start_towards_deck",
]

#: The projected tag camera's stream (``"sensor.<name>"`` of the simulator's camera sensor).
TAG_CAMERA_STREAM = "sensor.tag_camera"
N_TOF = 4


class Sines(NamedTuple):
    """A sum-of-sines deck profile: amplitudes (m, rad), frequencies (Hz) and phases (rad), (6, K)."""

    amp: Any
    freq: Any
    phase: Any


class Imaging(NamedTuple):
    """The realistic camera's episode draw: light direction (3,) (world), ambient and diffuse
    shading, brightness, exposure (s) and analog gain."""

    light: Any
    ambient: Any
    diffuse: Any
    brightness: Any
    exposure: Any
    gain: Any


class Episode(NamedTuple):
    """One episode's draws (arrays, one env): the start (``altitude`` m above the deck origin,
    ``offset`` (2,) m world, ``yaw`` rad, ``deck_time`` s), the deck motion (a
    :class:`~ihrcf_env.fast.deck_motion.ShipMotion` or :class:`Sines`), the wind's uniforms (2,) and
    gust normals (G, 3), the navigation errors' start normals (3, 3), the IMU's reset normals, the
    ToF offsets (4,) m, the dead ToF sensors (4,) and their onset (s), the camera's imaging draw
    and corner field (``field_omega`` (4, M, 2), ``field_phase`` (4, M))."""

    altitude: Any
    offset: Any
    yaw: Any
    deck_time: Any
    deck: Any
    wind_u: Any
    gusts: Any
    nav0: Any
    imu0: Any
    tof_offset: Any
    dead: Any
    dead_start: Any
    imaging: Imaging
    field_omega: Any
    field_phase: Any


def imaging_draw(params: Any, rng: np.random.Generator) -> Imaging:
    """The realistic camera's episode draw from ``rng`` (the simulator's ``draw_episode``: the
    same draws in the same order; the texture placement is drawn and dropped)."""
    az = rng.uniform(0.0, 2.0 * math.pi)
    el = math.radians(rng.uniform(*params.light_elevation_deg))
    light = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))
    ambient = float(rng.uniform(*params.ambient))
    diffuse = float(rng.uniform(*params.diffuse))
    lo, hi = params.scene_exposure_s
    needed = math.exp(rng.uniform(math.log(lo), math.log(hi)))
    exposure = min(needed, params.max_exposure_s)
    gain = min(needed / exposure, params.max_gain)
    brightness = exposure * gain / needed * math.exp(params.ae_error * rng.standard_normal())
    rng.uniform(0.0, params.texture_tile_m, 2)  # texture origin (rendered camera only)
    rng.uniform(0.0, 2.0 * math.pi)  # texture angle
    rng.uniform(0.0, params.drift_speed), rng.uniform(0.0, 2.0 * math.pi)  # texture drift
    f = np.float64
    return Imaging(np.asarray(light, f), f(ambient), f(diffuse), f(brightness), f(exposure), f(gain))


def _jax_imaging(params: Any, key: Array, dtype: Any) -> Imaging:
    k = jax.random.split(key, 6)
    az = jax.random.uniform(k[0], (), dtype, 0.0, 2.0 * math.pi)
    lo_e, hi_e = params.light_elevation_deg
    el = jnp.deg2rad(jax.random.uniform(k[1], (), dtype, lo_e, hi_e))
    light = jnp.stack([jnp.cos(el) * jnp.cos(az), jnp.cos(el) * jnp.sin(az), jnp.sin(el)])
    ambient = jax.random.uniform(k[2], (), dtype, *params.ambient)
    diffuse = jax.random.uniform(k[3], (), dtype, *params.diffuse)
    lo, hi = params.scene_exposure_s
    needed = jnp.exp(jax.random.uniform(k[4], (), dtype, math.log(lo), math.log(hi)))
    exposure = jnp.minimum(needed, params.max_exposure_s)
    gain = jnp.minimum(needed / exposure, params.max_gain)
    brightness = exposure * gain / needed * jnp.exp(params.ae_error * jax.random.normal(k[5], (), dtype))
    return Imaging(light, ambient, diffuse, brightness, exposure, gain)


def _deck_arrays(profile: Any) -> tuple[Any, float]:
    """(ship motion or sines, start time s) of a drawn profile."""
    t0 = 0.0
    if isinstance(profile, ShiftedProfile):
        profile, t0 = profile.base, float(profile.t0)
    if isinstance(profile, CoreShipMotion):
        a = np.asarray(profile.amplitudes)
        motion: Any = (np.asarray(profile.omega_e, np.float64), a.real.copy(), a.imag.copy())
        return ShipMotion(*motion), t0
    if isinstance(profile, SumOfSines):
        return Sines(*(np.asarray(a) for a in sines_arrays(profile.components))), t0
    if type(profile).__name__ == "StaticProfile":
        z = np.zeros((6, 1))
        return Sines(z, z, z), t0
    raise ValueError(
        f"deck profile {profile!r}: the JAX step supports ship, sum-of-sines and static profiles"
    )


def host_episode(
    params: StepParams, streams: SeedStreams | int, options: dict[str, Any] | None = None
) -> Episode:
    """The :class:`Episode` the PyBullet env draws for the episode key of ``streams`` (or an
    episode key), from the same named streams (module docstring); ``options`` as the env's
    ``reset(options=...)``."""
    s = streams if isinstance(streams, SeedStreams) else SeedStreams(streams)
    cfg: DeckLandingConfig = params.config
    start = draws.draw_start(cfg, s.generator("start"), options, disc=params.landing)
    profile, _ = draws.draw_deck(cfg, s.generator("deck"), start.deck_time)
    deck, t0 = _deck_arrays(profile)
    if params.wind is not None:
        w = draws.draw_wind(s.generator("wind"))
        wind_u = np.array([w.u_speed, w.u_direction])
        gusts = draws.gust_normals(w.gust_seed, params.gust_count)
    else:
        wind_u, gusts = np.zeros(2), np.zeros((2, 3))
    nav0 = np.zeros((3, 3))
    if params.nav is not None:
        seed = int(s.generator("navigation").integers(0, 2**63 - 1))
        nav0 = np.random.default_rng(seed).standard_normal((3, 3))
    imu0 = np.zeros(RESET_DRAWS)
    if params.imu is not None:
        imu0 = reset_draws(params.imu, s.generator("sensor.imu"))
    tof_offset = np.zeros(N_TOF)
    if params.tof.model is not None and params.tof.offset_sigma > 0:
        tof_offset = s.generator("sensor.tof").standard_normal(N_TOF) * params.tof.offset_sigma
    dead, dead_start = np.zeros(N_TOF, bool), np.float64(0.0)
    if params.tof.dead is not None:
        count, (lo, hi) = params.tof.dead
        rng = s.generator("fault.tof_dead")
        dead[sorted(int(i) for i in rng.choice(N_TOF, count, replace=False))] = True
        dead_start = np.float64(lo if hi == lo else float(rng.uniform(lo, hi)))
    m = params.camera.field if params.camera is not None else 1
    imaging = Imaging(np.zeros(3), *(np.float64(0.0),) * 5)
    omega, phase = np.zeros((4, m, 2)), np.zeros((4, m))
    if params.camera is not None:
        rng = s.generator(TAG_CAMERA_STREAM)
        if params.camera.realistic:
            imaging = imaging_draw(params.camera.imaging, rng)
        omega = rng.standard_normal((4, m, 2))
        phase = rng.uniform(0.0, 2.0 * math.pi, (4, m))
    f = np.float64
    return Episode(
        f(start.altitude), np.asarray(start.offset, f), f(start.yaw), f(t0), deck, wind_u, gusts, nav0, imu0,
        tof_offset, dead, dead_start, imaging, omega, phase,
    )  # fmt: skip


def host_streams(params: StepParams, streams: SeedStreams) -> dict[str, np.random.Generator]:
    """The generators the PyBullet env draws an episode's per-step noise from, positioned where the
    env's first step reading starts (after its episode draws): ``"navigation"`` (the GNSS/INS
    errors' generator: its start (3, 3) normals come first, then 6 normals per physics tick),
    ``"tof"``, ``"imu"``, ``"camera"`` (8 normals and a uniform per frame) and ``"dropout"`` (one
    uniform per frame)."""
    out: dict[str, np.random.Generator] = {}
    if params.nav is not None:
        out["navigation"] = np.random.default_rng(int(streams.generator("navigation").integers(0, 2**63 - 1)))
    tof = streams.generator("sensor.tof")
    if params.tof.model is not None and params.tof.offset_sigma > 0:
        tof.standard_normal(N_TOF)
    out["tof"] = tof
    imu = streams.generator("sensor.imu")
    if params.imu is not None:
        reset_draws(params.imu, imu)
    out["imu"] = imu
    if params.camera is not None:
        cam = streams.generator(TAG_CAMERA_STREAM)
        if params.camera.realistic:
            imaging_draw(params.camera.imaging, cam)
        m = params.camera.field
        cam.standard_normal((4, m, 2))
        cam.uniform(0.0, 2.0 * math.pi, (4, m))
        out["camera"] = cam
        out["dropout"] = streams.generator("fault.camera_dropout")
    return out


def draw_episode(key: Array, params: StepParams) -> Episode:
    """An :class:`Episode` drawn in JAX from ``key``: the distributions of the PyBullet env's draws
    (not its values). A random sea is not redrawn when it exceeds the legs' stroke (the deck then
    holds its last reachable pose, as the env's deck does past its checked horizon); the random
    ``"sea_state"`` profile is drawn on the host only (ValueError)."""
    cfg: DeckLandingConfig = params.config
    dt_ = params.dtype
    k = jax.random.split(key, 16)
    st = cfg.task.start
    alt = st.altitude + jax.random.uniform(k[0], (), dt_, -1.0, 1.0) * st.altitude_jitter
    off = jax.random.uniform(k[1], (2,), dt_, -1.0, 1.0) * st.offset
    yaw = jax.random.uniform(k[2], (), dt_, -1.0, 1.0) * st.yaw
    t0 = jax.random.uniform(k[3], (), dt_, 0.0, 130.0) if cfg.task.deck.random_start else jnp.zeros((), dt_)
    if params.landing:
        u = jax.random.uniform(k[4], (), dt_)
        phi = jax.random.uniform(k[5], (), dt_, 0.0, 2.0 * math.pi)
        r = start_radius_jnp(cfg, alt) * jnp.sqrt(u)
        off = jnp.stack([r * jnp.cos(phi), r * jnp.sin(phi)])
    d = params.deck
    if d.kind == "ship":
        assert d.ship is not None
        n = d.ship.n_components
        deck: Any = ship_motion(
            jax.random.uniform(k[6], (n,), dt_), jax.random.uniform(k[7], (n,), dt_), d.ship
        )
    elif d.random:
        raise ValueError(
            "deck_profile='sea_state': its random periods are drawn on the host only (reset_from with "
            "host_episode); use deck_profile='ship' for episodes drawn in JAX"
        )
    else:
        assert d.sines is not None
        deck = Sines(*(jnp.asarray(a, dt_) for a in d.sines))
    g = max(params.gust_count, 2)
    wind_u = jax.random.uniform(k[8], (2,), dt_)
    gusts = jax.random.normal(k[9], (g, 3), dt_)
    nav0 = jax.random.normal(k[10], (3, 3), dt_)
    imu0 = jax.random.normal(k[11], (RESET_DRAWS,), dt_)
    tof_offset = jax.random.normal(k[12], (N_TOF,), dt_) * params.tof.offset_sigma
    dead = jnp.zeros(N_TOF, bool)
    dead_start = jnp.zeros((), dt_)
    if params.tof.dead is not None:
        count, (lo, hi) = params.tof.dead
        kd = jax.random.split(k[13])
        perm = jax.random.permutation(kd[0], N_TOF)
        dead = jnp.zeros(N_TOF, bool).at[perm[:count]].set(True)
        dead_start = jax.random.uniform(kd[1], (), dt_, lo, hi) if hi > lo else jnp.asarray(lo, dt_)
    m = params.camera.field if params.camera is not None else 1
    kc = jax.random.split(k[14], 3)
    if params.camera is not None and params.camera.realistic:
        imaging = _jax_imaging(params.camera.imaging, kc[0], dt_)
    else:
        imaging = Imaging(jnp.zeros(3, dt_), *(jnp.zeros((), dt_),) * 5)
    omega = jax.random.normal(kc[1], (4, m, 2), dt_)
    phase = jax.random.uniform(kc[2], (4, m), dt_, 0.0, 2.0 * math.pi)
    return Episode(
        alt,
        off,
        yaw,
        t0,
        deck,
        wind_u,
        gusts,
        nav0,
        imu0,
        tof_offset,
        dead,
        dead_start,
        imaging,
        omega,
        phase,
    )


def start_towards_deck(episode: Episode, scale: Any, lowest: float) -> Episode:
    """``episode`` with its start brought towards the deck by ``scale`` in [0, 1] (a trainer's start
    curriculum): the altitude above the deck origin from ``lowest`` (m; or the drawn altitude if
    lower) at 0 to the drawn one at 1, the horizontal offset times ``scale``. At ``scale`` 1 (or
    above) the episode's own start, bit for bit."""
    f = jnp.clip(jnp.asarray(scale, episode.altitude.dtype), 0.0, 1.0)
    low = jnp.minimum(episode.altitude, lowest)
    full = f >= 1.0
    return episode._replace(
        altitude=jnp.where(full, episode.altitude, low + f * (episode.altitude - low)),
        offset=jnp.where(full, episode.offset, f * episode.offset),
    )


def start_radius_jnp(config: DeckLandingConfig, altitude: Array) -> Array:
    """:func:`ihrcf_env.tasks.episode.start_radius` of a traced ``altitude`` (m)."""
    limit = config.task.start.offset
    cam = config.world.camera
    goal = config.task.landing
    if cam is None or goal is None or not goal.start_in_view:
        return jnp.full_like(altitude, limit)
    tan_half = math.tan(cam.fov / 2) * min(1.0, cam.width / cam.height)
    half_view = (altitude + float(config.world.rig.camera_position[2])) * tan_half
    tag = config.world.deck.tag_size * draws.TAG_EXTENT * math.sqrt(2.0)
    return jnp.minimum(limit, jnp.maximum(0.0, half_view - tag - goal.view_margin))
