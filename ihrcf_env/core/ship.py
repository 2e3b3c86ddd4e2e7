"""Ship-like deck motion: one seeded sea realisation through a vessel's response, Froude-scaled to
the Stewart platform (pure numpy/scipy).

**Sea.** A long-crested sea (:class:`~ihrcf_env.core.waves.SeaState`: JONSWAP or
Pierson-Moskowitz) is a sum of ``n_components`` cosines: the wave-frequency band
[:data:`BAND`] x ``omega_p`` is cut into equal bins, each holding one component at a seeded
random frequency within the bin (so the record never repeats), amplitude
``sqrt(2 S(omega) d_omega)`` and a seeded random phase. The waves travel at ``wave_heading``
relative to the bow (pi = head seas, pi/2 = beam seas travelling from starboard to port, 0 =
following seas); the ship sails at ``speed``, so a component of wave number ``k = omega^2 / g``
(deep water) is met at the encounter frequency ``omega_e = omega - k speed cos(heading)``.

**Vessel.** Ship axes: x forward, y to port, z up, origin at the centre of motion; roll, pitch,
yaw are ZYX angles (positive pitch = bow down). Every DOF sees the SAME components:

* heave, pitch and roll are second-order systems (natural period ``Tn``, damping ratio ``zeta``),
  ``H(w_e) = 1 / (1 - (w_e Tn / 2 pi)^2 + 2 i zeta w_e Tn / 2 pi)``, driven by the hull's
  quasi-static (Froude-Krylov) equilibrium: the wave elevation averaged over the L x B waterplane
  (heave), the least-squares slope of that surface along the length (pitch, sign so the bow
  rises on a wave crest ahead) and across the beam times ``roll_slope_factor`` (the effective
  wave slope of roll), all attenuated by ``exp(-k draught)`` (Smith effect); the box-hull
  averaging follows the closed-form approach of Jensen, Mansour & Olsen (2004), "Estimation of
  ship motions using closed-form expressions", Ocean Engineering 31;
* surge, sway and yaw follow the waterplane-averaged orbital displacement of the water at half
  the draught (no restoring force, no dynamics): small.

The **deck** is the point ``deck_position`` of the ship: its offset is ``p + R r - r`` (exact
rotation), its attitude the ship's.

**Scaling.** Froude scaling by the length scale ``lambda``: lengths / lambda, angles unchanged,
times / sqrt(lambda) (so velocities / sqrt(lambda), accelerations unchanged). The profile's time
is model time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import (
    check_fields,
    check_int,
    check_real,
    check_reals,
    from_fields,
    set_field,
)
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.profiles import MotionProfile, PoseArrays, profile_leg_lengths
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.core.waves import SeaState, sea_state

#: Wave-frequency band of the components, in multiples of the peak frequency.
BAND = (0.5, 4.0)
#: Rows per block of :meth:`ShipMotion.ship_motion`'s phasor recurrence.
BLOCK = 128


@dataclass(frozen=True)
class Vessel:
    """A ship's size (m), its heave/roll/pitch natural periods (s) and damping ratios, the
    effective-slope factor of roll, and the deck point ``deck_position`` (m, ship axes from the
    centre of motion). The default is a frigate-size ship (:data:`FRIGATE`)."""

    length: float = 120.0
    beam: float = 14.5
    draught: float = 4.5
    heave_period: float = 7.0
    heave_damping: float = 0.25
    roll_period: float = 11.0
    roll_damping: float = 0.06
    pitch_period: float = 6.0
    pitch_damping: float = 0.25
    roll_slope_factor: float = 0.8
    deck_position: tuple[float, float, float] = (-40.0, 0.0, 6.0)

    def __post_init__(self) -> None:
        size = (1.0, 500.0)
        period = (1.0, 60.0)
        damping = (0.005, 2.0)
        check_fields(
            self,
            lambda n: f"vessel.{n}",
            {
                "length": size,
                "beam": size,
                "draught": (0.1, 50.0),
                "heave_period": period,
                "heave_damping": damping,
                "roll_period": period,
                "roll_damping": damping,
                "pitch_period": period,
                "pitch_damping": damping,
                "roll_slope_factor": (0.0, 2.0),
            },
            {"length": "m", "beam": "m", "draught": "m", "heave_period": "s", "roll_period": "s"},
        )
        deck = check_reals("vessel.deck_position", self.deck_position, 3, "m", low=-500.0, high=500.0)
        set_field(self, "deck_position", deck)


#: A frigate-size ship: 120 m x 14.5 m x 4.5 m, heave Tn 7 s, roll Tn 11 s (lightly damped),
#: pitch Tn 6 s, flight deck 40 m aft of and 6 m above the centre of motion.
FRIGATE = Vessel()

#: Default Froude length scale of the "ship" profile (fits the paper's platform, see the docs).
DEFAULT_LENGTH_SCALE = 30.0
LENGTH_SCALE_BOUNDS = (1.0, 1000.0)


@dataclass(frozen=True)
class ShipOptions:
    """Everything the "ship" profile needs: the ``sea_state`` (WMO code, name, SeaState or dict,
    see :func:`~ihrcf_env.core.waves.sea_state`), the ``vessel`` (a Vessel or a dict of its
    fields), ``wave_heading`` (rad, pi = head seas), ``speed`` (m/s, full scale), the Froude
    ``length_scale`` and the number of wave components."""

    sea_state: int | str | SeaState | Mapping[str, object] = 4
    vessel: Vessel | Mapping[str, object] = field(default_factory=Vessel)
    wave_heading: float = math.radians(150.0)
    speed: float = 5.0
    length_scale: float = DEFAULT_LENGTH_SCALE
    n_components: int = 256

    def __post_init__(self) -> None:
        set_field(self, "sea_state", sea_state(self.sea_state))
        set_field(self, "vessel", from_fields("ship.vessel", Vessel, self.vessel))
        head = check_real("ship.wave_heading", self.wave_heading, "rad", low=-2 * math.pi, high=2 * math.pi)
        set_field(self, "wave_heading", head)
        set_field(self, "speed", check_real("ship.speed", self.speed, "m/s", low=0.0, high=25.0))
        lo, hi = LENGTH_SCALE_BOUNDS
        set_field(
            self, "length_scale", check_real("ship.length_scale", self.length_scale, "", low=lo, high=hi)
        )
        set_field(self, "n_components", check_int("ship.n_components", self.n_components, low=8, high=4096))

    @property
    def sea(self) -> SeaState:
        assert isinstance(self.sea_state, SeaState)
        return self.sea_state

    @property
    def ship(self) -> Vessel:
        assert isinstance(self.vessel, Vessel)
        return self.vessel


def _g1(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """3 (sin u - u cos u) / u^3: the least-squares slope of cos over [-1, 1] u, per unit slope."""
    out = np.ones_like(u)
    big = np.abs(u) > 1e-3
    ub = u[big]
    out[big] = 3.0 * (np.sin(ub) - ub * np.cos(ub)) / ub**3
    out[~big] = 1.0 - u[~big] ** 2 / 10.0
    return out


def _second_order(omega_e: NDArray[np.float64], period: float, damping: float) -> NDArray[np.complex128]:
    r = omega_e * period / (2.0 * math.pi)
    return np.asarray(1.0 / (1.0 - r**2 + 2j * damping * r), dtype=np.complex128)


def transfer(
    omega: NDArray[np.float64], vessel: Vessel, heading: float, speed: float
) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """Encounter frequencies (N,) (rad/s, signed) and the complex response (6, N) of (surge,
    sway, heave (m), roll, pitch, yaw (rad)) at the centre of motion per metre of wave amplitude,
    for wave frequencies ``omega`` (rad/s); full scale. Phase reference: the wave elevation at the
    centre of motion, ``Re(a exp(i (omega_e t + phase)))``."""
    k = omega**2 / GRAVITY
    kx, ky = k * math.cos(heading), k * math.sin(heading)
    ux, uy = kx * vessel.length / 2, ky * vessel.beam / 2
    sx, sy = np.sinc(ux / math.pi), np.sinc(uy / math.pi)
    att = np.exp(-k * vessel.draught)
    att_half = np.exp(-k * vessel.draught / 2)
    omega_e = omega - k * speed * math.cos(heading)
    out = np.zeros((6, omega.shape[0]), dtype=np.complex128)
    orbital = -1j * sx * sy * att_half  # horizontal particle displacement along the waves
    out[0] = math.cos(heading) * orbital
    out[1] = math.sin(heading) * orbital
    out[2] = sx * sy * att * _second_order(omega_e, vessel.heave_period, vessel.heave_damping)
    roll_eq = -1j * ky * _g1(uy) * sx * att * vessel.roll_slope_factor
    out[3] = roll_eq * _second_order(omega_e, vessel.roll_period, vessel.roll_damping)
    pitch_eq = 1j * kx * _g1(ux) * sy * att
    out[4] = pitch_eq * _second_order(omega_e, vessel.pitch_period, vessel.pitch_damping)
    L2, B2 = vessel.length**2, vessel.beam**2
    twist = (L2 * _g1(ux) * sy - B2 * _g1(uy) * sx) / (L2 + B2)
    out[5] = -k * math.sin(heading) * math.cos(heading) * twist * att_half
    return omega_e, out


def _real_dot(z: NDArray[np.complex128], a_pairs: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 6) ``Re(z @ a.T)`` for phasors ``z`` (n, N) and ``a_pairs`` = ``conj(a)`` (6, N) viewed
    as (6, 2N) floats. A plain summed product (numpy's einsum loop), not BLAS: a BLAS thread pool
    waking for these small products costs far more than the sums when the cores are shared."""
    zc = np.ascontiguousarray(z)
    return np.einsum("ij,kj->ik", zc.view(np.float64), a_pairs)


def _rotate_zyx(rpy: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 3) ``Rz(yaw) Ry(pitch) Rx(roll) v`` for ZYX angles ``rpy`` (n, 3) (rad)."""
    cr, sr = np.cos(rpy[:, 0]), np.sin(rpy[:, 0])
    cp, sp = np.cos(rpy[:, 1]), np.sin(rpy[:, 1])
    cy, sy = np.cos(rpy[:, 2]), np.sin(rpy[:, 2])
    x, y, z = v
    y1, z1 = y * cr - z * sr, y * sr + z * cr
    x2, z2 = x * cp + z1 * sp, -x * sp + z1 * cp
    return np.column_stack([x2 * cy - y1 * sy, x2 * sy + y1 * cy, z2])


class ShipMotion(MotionProfile):
    """The deck of a ship in one seeded sea realisation (see the module docstring), model scale.

    ``omega_e`` (N,) encounter frequencies (rad/s, full scale), ``amplitudes`` (6, N) complex
    full-scale motion of the centre of motion per component (phases included), ``deck`` (3,) the
    deck point (m, ship axes), ``length_scale`` the Froude scale. Build with :func:`ship_profile`.
    """

    name = "ship"

    def __init__(
        self,
        omega_e: NDArray[np.float64],
        amplitudes: NDArray[np.complex128],
        deck: NDArray[np.float64],
        length_scale: float,
        options: ShipOptions | None = None,
    ) -> None:
        self.omega_e = np.asarray(omega_e, dtype=np.float64)
        self.amplitudes = np.asarray(amplitudes, dtype=np.complex128)
        self.deck = np.asarray(deck, dtype=np.float64)
        self.length_scale = float(length_scale)
        self.options = options

    @property
    def time_scale(self) -> float:
        """Full-scale seconds per model second (sqrt of the length scale)."""
        return math.sqrt(self.length_scale)

    def ship_motion(self, t_full: NDArray[np.float64]) -> NDArray[np.float64]:
        """(n, 6) full-scale motion of the centre of motion (m, rad) at full-scale times (s):
        ``Re(sum_j amplitudes[:, j] exp(i omega_e[j] t))``. On a uniform time grid the phasors of
        each block of :data:`BLOCK` rows are those of the previous block times one rotation
        (exact up to rounding), which avoids most of the complex exponentials."""
        t = np.asarray(t_full, dtype=np.float64)
        n = t.shape[0]
        # Re(z a) = Re z Re a - Im z Im a: the phasors' (re, im) pairs dotted with conj(a)'s
        a_pairs = np.ascontiguousarray(np.conj(self.amplitudes)).view(np.float64)  # (6, 2N)
        if n < 2 * BLOCK:
            return _real_dot(np.exp(1j * np.outer(t, self.omega_e)), a_pairs)
        dt = (t[-1] - t[0]) / (n - 1)
        if not np.all(np.abs(t - (t[0] + dt * np.arange(n))) <= 1e-9 * max(1.0, abs(t[-1]))):
            return _real_dot(np.exp(1j * np.outer(t, self.omega_e)), a_pairs)
        z = np.exp(1j * np.outer(t[:BLOCK], self.omega_e))
        step = np.exp(1j * self.omega_e * (BLOCK * dt))
        out = np.empty((n, 6))
        for s in range(0, n, BLOCK):
            m = min(BLOCK, n - s)
            out[s : s + m] = _real_dot(z[:m], a_pairs)
            z *= step
        return out

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        m = self.ship_motion(np.asarray(t, dtype=np.float64) * self.time_scale)
        rpy = m[:, 3:]
        offset = (m[:, :3] + _rotate_zyx(rpy, self.deck) - self.deck) / self.length_scale
        return offset, rpy

    def deck_amplitudes(self) -> NDArray[np.complex128]:
        """(6, N) complex model-scale amplitudes of the deck offset (m) and attitude (rad),
        linearised in the angles (small rotations): the basis of the target spectra."""
        ang = self.amplitudes[3:]
        lever = np.cross(ang.T, self.deck).T
        return np.concatenate([(self.amplitudes[:3] + lever) / self.length_scale, ang])

    def deck_std(self) -> NDArray[np.float64]:
        """(6,) standard deviation of the deck offset (m) and attitude (rad), model scale, from
        the components (linearised in the angles)."""
        return np.sqrt(0.5 * np.sum(np.abs(self.deck_amplitudes()) ** 2, axis=1))


def ship_profile(
    rng: np.random.Generator, options: ShipOptions | Mapping[str, object] | None = None
) -> ShipMotion:
    """A seeded ship deck motion: the frequencies' jitter and the phases are drawn from ``rng``
    (deterministic for a seed); ``options`` a :class:`ShipOptions` or a dict of its fields."""
    opts = from_fields("ship", ShipOptions, options if options is not None else {})
    sea, vessel = opts.sea, opts.ship
    n = opts.n_components
    lo, hi = BAND[0] * sea.omega_p, BAND[1] * sea.omega_p
    d_omega = (hi - lo) / n
    omega = lo + d_omega * (np.arange(n) + rng.uniform(0.0, 1.0, n))
    phase = rng.uniform(0.0, 2 * math.pi, n)
    a = np.sqrt(2.0 * sea.spectrum(omega) * d_omega)
    omega_e, T = transfer(omega, vessel, opts.wave_heading, opts.speed)
    amps = T * (a * np.exp(1j * phase))
    return ShipMotion(omega_e, amps, np.asarray(vessel.deck_position), opts.length_scale, opts)


def response_psd(options: ShipOptions, f_hz: NDArray[np.float64], n_grid: int = 40000) -> NDArray[np.float64]:
    """(6, len(f_hz)) target one-sided PSD of the deck offset (m^2/Hz) and attitude (rad^2/Hz)
    at the model-scale frequencies ``f_hz`` (a uniform grid, e.g. Welch's): the wave spectrum
    through :func:`transfer` and the deck lever arm (linearised), mapped to encounter frequency
    (variance of a fine wave-frequency grid binned by |omega_e|, so folded encounter frequencies
    of following seas add up), then Froude-scaled."""
    f = np.asarray(f_hz, dtype=np.float64)
    df = f[1] - f[0]
    sea, vessel = options.sea, options.ship
    lo, hi = BAND[0] * sea.omega_p, BAND[1] * sea.omega_p
    d_omega = (hi - lo) / n_grid
    omega = np.asarray(lo + d_omega * (np.arange(n_grid) + 0.5), dtype=np.float64)
    omega_e, T = transfer(omega, vessel, options.wave_heading, options.speed)
    fake = ShipMotion(
        omega_e,
        T * np.sqrt(2.0 * sea.spectrum(omega) * d_omega),
        np.asarray(vessel.deck_position),
        options.length_scale,
    )
    var = 0.5 * np.abs(fake.deck_amplitudes()) ** 2  # (6, n_grid)
    f_model = np.abs(omega_e) / (2 * math.pi) * math.sqrt(options.length_scale)
    idx = np.rint((f_model - f[0]) / df).astype(int)
    ok = (idx >= 0) & (idx < f.shape[0])
    out = np.zeros((6, f.shape[0]))
    for k in range(6):
        out[k] = np.bincount(idx[ok], weights=var[k, ok], minlength=f.shape[0])[: f.shape[0]]
    return out / df


#: A Stewart platform twice the paper's in every length (same proportions, so the same tilt
#: range; twice the translation range): for rougher seas at a given scale.
LARGE_STEWART = StewartGeometry(
    base_radius=1.10, top_radius=0.64, base_height=0.16, home_height=1.70, joint_depth=0.12, stroke=0.60
)


def stroke_margin(
    profile: MotionProfile, geometry: StewartGeometry, horizon_s: float, dt: float = 0.05
) -> tuple[float, float, int]:
    """(margin (m), time (s), leg 1-6): the smallest distance of any leg length from the ends of
    its stroke over ``[0, horizon_s]`` sampled every ``dt`` s (the grid the deck's reset check
    uses), where and which leg; a negative margin means the legs cannot follow the profile."""
    horizon = check_real("horizon_s", horizon_s, "s", low=0.0, high=1e6)
    dt = check_real("dt", dt, "s", low=1e-4, high=10.0)
    t = np.arange(0.0, horizon + dt, dt)
    legs = profile_leg_lengths(profile, geometry, t)
    margin = np.minimum(legs - geometry.min_leg, geometry.max_leg - legs)
    margin = np.where(np.isfinite(margin), margin, -np.inf)
    k, leg = np.unravel_index(int(np.argmin(margin)), margin.shape)
    return float(margin[k, leg]), float(t[k]), int(leg) + 1


def fits(profile: MotionProfile, geometry: StewartGeometry, horizon_s: float, dt: float = 0.05) -> bool:
    """Whether the legs of ``geometry`` can follow ``profile`` over ``[0, horizon_s]`` (model s),
    checked as the deck does at reset (:func:`stroke_margin` >= 0)."""
    return stroke_margin(profile, geometry, horizon_s, dt)[0] >= 0.0


__all__ = [
    "BAND",
    "BLOCK",
    "DEFAULT_LENGTH_SCALE",
    "FRIGATE",
    "LARGE_STEWART",
    "LENGTH_SCALE_BOUNDS",
    "ShipMotion",
    "ShipOptions",
    "Vessel",
    "fits",
    "response_psd",
    "ship_profile",
    "stroke_margin",
    "transfer",
]
