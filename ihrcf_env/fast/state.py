"""The landing step's state pytree (:class:`EnvState`, one env, no batch axis) and the per-step
noise draws (:class:`StepDraws`, :class:`ReadDraws`)."""

from __future__ import annotations

from typing import NamedTuple

from jax import Array

from ihrcf_env.fast.advance import Flight
from ihrcf_env.fast.deck_motion import DeckTrack
from ihrcf_env.fast.episode import Episode
from ihrcf_env.fast.frames import FramePipe
from ihrcf_env.fast.imu import ImuState
from ihrcf_env.fast.navigation import NavState
from ihrcf_env.fast.wind import WindEpisode

__all__ = ["EnvState", "ReadDraws", "StepDraws"]


class EnvState(NamedTuple):
    """One env between control steps: the flight (drone, autopilot, touchdown latch), the deck at
    the current physics ``tick`` (and its body pose one tick before, for its velocity), the
    control ``steps`` taken, the episode's draws and wind, the navigation errors, the IMU's noise
    state, the ToF's sample clock (``tof_next``) and held sample, the camera's frames in flight
    (``pipe``, ``frames`` delivered so far), the frame dropout's chain, the shaping potential
    ``phi`` (landing tasks) and ``done`` (the episode ended)."""

    flight: Flight
    deck: DeckTrack
    deck_quat: Array
    deck_prev_body: Array
    deck_prev_quat: Array
    tick: Array
    steps: Array
    episode: Episode
    wind: WindEpisode
    nav: NavState
    imu: ImuState
    tof_next: Array
    tof_ranges: Array
    tof_valid: Array
    pipe: FramePipe
    frames: Array
    drop_bad: Array
    drop_started: Array
    phi: Array
    done: Array


class ReadDraws(NamedTuple):
    """The noise of one sensor reading: ToF normals and dropout uniforms per sample (M, 4), the
    IMU's normals (14,), the detector's normals (4, 2) and uniform, the frame dropout's uniform."""

    tof_z: Array
    tof_u: Array
    imu: Array
    cam_normals: Array
    cam_uniform: Array
    drop_u: Array


class StepDraws(NamedTuple):
    """The noise of one control step: the navigation errors' normals per physics tick (S, 6) and
    the sensor readings' draws."""

    nav: Array
    read: ReadDraws
