"""Ocean wave spectra and sea-state presets (pure numpy).

Spectra are one-sided wave-elevation spectra ``S(omega)`` (m^2 s / rad) of a long-crested sea,
parameterised by the significant wave height ``hs`` (m) and the peak period ``tp`` (s):

* **Pierson-Moskowitz** (Pierson & Moskowitz 1964), in the Hs/Tp form of DNV-RP-C205 (2010),
  section 3.5.5: ``S_PM(w) = 5/16 hs^2 wp^4 w^-5 exp(-5/4 (w / wp)^-4)``, ``wp = 2 pi / tp``.
* **JONSWAP** (Hasselmann et al. 1973), DNV-RP-C205 section 3.5.5:
  ``S_J(w) = A_g S_PM(w) gamma^exp(-(w - wp)^2 / (2 sigma^2 wp^2))`` with the peak enhancement
  ``gamma`` (3.3 on average in the JONSWAP data), ``sigma`` 0.07 below the peak and 0.09 above,
  and the normalising factor ``A_g = 1 - 0.287 ln(gamma)``. ``gamma = 1`` gives Pierson-Moskowitz.

Presets by WMO sea-state code (WMO code table 3700, which gives the significant wave height band)
use the mean significant wave height and the most probable modal (peak) period of the open-ocean
North Atlantic sea-state table of Bales (1983), "Designing ships to the natural environment", Naval
Engineers Journal 95(2) (from the hindcast climatology of Bales, Lee & Voelker 1981,
DTNSRDC/SPD-0919-01, the NATO standard wave environments).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.checks import check_mapping, check_real, check_str, describe, from_fields, is_int
from ihrcf_env.core.constants import GRAVITY

#: Bounds of a sea state: significant wave height (m), peak period (s), peak enhancement factor.
HS_BOUNDS = (0.01, 20.0)
TP_BOUNDS = (1.0, 30.0)
GAMMA_BOUNDS = (1.0, 10.0)
#: Largest mean wave steepness ``2 pi hs / (g tp^2)``: waves steeper than this break
#: (DNV-RP-C205 section 3.5.5 gives 1/15 as the limit for short peak periods).
MAX_STEEPNESS = 1.0 / 15.0


def jonswap(omega: ArrayLike, hs: float, tp: float, gamma: float = 3.3) -> NDArray[np.float64]:
    """JONSWAP wave-elevation spectrum (m^2 s / rad) at the wave frequencies ``omega`` (rad/s,
    > 0; zero where omega <= 0); ``gamma = 1`` gives Pierson-Moskowitz (DNV-RP-C205 3.5.5)."""
    w = np.asarray(omega, dtype=np.float64)
    wp = 2.0 * math.pi / tp
    out = np.zeros_like(w)
    pos = w > 0
    x = wp / w[pos]
    s_pm = 5.0 / 16.0 * hs**2 * wp**4 * w[pos] ** -5 * np.exp(-1.25 * x**4)
    sigma = np.where(w[pos] <= wp, 0.07, 0.09)
    peak = gamma ** np.exp(-0.5 * ((w[pos] - wp) / (sigma * wp)) ** 2)
    out[pos] = (1.0 - 0.287 * math.log(gamma)) * s_pm * peak
    return out


def pierson_moskowitz(omega: ArrayLike, hs: float, tp: float) -> NDArray[np.float64]:
    """Pierson-Moskowitz wave-elevation spectrum (m^2 s / rad), see :func:`jonswap`."""
    return jonswap(omega, hs, tp, 1.0)


@dataclass(frozen=True)
class SeaState:
    """A long-crested sea: significant wave height ``hs`` (m), peak period ``tp`` (s) and the
    JONSWAP peak enhancement ``gamma`` (1 = Pierson-Moskowitz). ``name`` labels tables only.

    Refused (ValueError naming the field): values out of :data:`HS_BOUNDS`, :data:`TP_BOUNDS`,
    :data:`GAMMA_BOUNDS`, or a mean steepness above :data:`MAX_STEEPNESS` (breaking waves)."""

    hs: float = 1.88
    tp: float = 8.8
    gamma: float = 3.3
    name: str = "custom"

    def __post_init__(self) -> None:
        hs = check_real("sea_state.hs", self.hs, "m", low=HS_BOUNDS[0], high=HS_BOUNDS[1])
        tp = check_real("sea_state.tp", self.tp, "s", low=TP_BOUNDS[0], high=TP_BOUNDS[1])
        gamma = check_real("sea_state.gamma", self.gamma, "", low=GAMMA_BOUNDS[0], high=GAMMA_BOUNDS[1])
        if not isinstance(self.name, str):
            raise TypeError(f"sea_state.name must be a str, got {describe(self.name)}")
        steep = self.steepness_of(hs, tp)
        if steep > MAX_STEEPNESS:
            raise ValueError(
                f"sea_state hs = {hs:g} m with tp = {tp:g} s has a mean steepness 2 pi hs / (g tp^2) = "
                f"{steep:.3f} above {MAX_STEEPNESS:.3f}: such waves break; lower hs or raise tp "
                f"(tp >= {math.sqrt(2 * math.pi * hs / (GRAVITY * MAX_STEEPNESS)):.2f} s for this hs)"
            )
        object.__setattr__(self, "hs", hs)
        object.__setattr__(self, "tp", tp)
        object.__setattr__(self, "gamma", gamma)

    @staticmethod
    def steepness_of(hs: float, tp: float) -> float:
        return 2.0 * math.pi * hs / (GRAVITY * tp**2)

    @property
    def omega_p(self) -> float:
        """Peak wave frequency (rad/s)."""
        return 2.0 * math.pi / self.tp

    def spectrum(self, omega: ArrayLike) -> NDArray[np.float64]:
        """Wave-elevation spectrum (m^2 s / rad) at ``omega`` (rad/s)."""
        return jonswap(omega, self.hs, self.tp, self.gamma)


#: Sea-state presets by WMO code: mean Hs and most probable peak period, open-ocean North
#: Atlantic (Bales 1983), JONSWAP with gamma = 3.3.
SEA_STATES: dict[int, SeaState] = {
    2: SeaState(0.30, 7.5, name="smooth"),
    3: SeaState(0.88, 7.5, name="slight"),
    4: SeaState(1.88, 8.8, name="moderate"),
    5: SeaState(3.25, 9.7, name="rough"),
    6: SeaState(5.0, 12.4, name="very_rough"),
    7: SeaState(7.5, 15.0, name="high"),
}
#: WMO significant-wave-height band (m) of each preset's code (WMO code table 3700).
WMO_HS_BANDS: dict[int, tuple[float, float]] = {
    2: (0.1, 0.5),
    3: (0.5, 1.25),
    4: (1.25, 2.5),
    5: (2.5, 4.0),
    6: (4.0, 6.0),
    7: (6.0, 9.0),
}
SEA_STATE_NAMES: tuple[str, ...] = tuple(s.name for s in SEA_STATES.values())


def sea_state(spec: int | str | SeaState | Mapping[str, object]) -> SeaState:
    """A :class:`SeaState` from a WMO code in :data:`SEA_STATES`, a preset name in
    :data:`SEA_STATE_NAMES` (``"moderate"``), a SeaState, or a dict of its fields (``{"hs": 2.0,
    "tp": 9.0}``; gamma defaults to 3.3). TypeError / ValueError name ``sea_state``."""
    if isinstance(spec, SeaState):
        return spec
    if is_int(spec):
        code = int(spec)  # type: ignore[arg-type]
        if code not in SEA_STATES:
            raise ValueError(f"sea_state code must be one of {sorted(SEA_STATES)} (WMO), got {code}")
        return SEA_STATES[code]
    if isinstance(spec, str):
        name = check_str("sea_state", spec, SEA_STATE_NAMES)
        return next(s for s in SEA_STATES.values() if s.name == name)
    if isinstance(spec, Mapping):
        check_mapping("sea_state", spec)
        return from_fields("sea_state", SeaState, spec, SeaState(name="custom"))
    raise TypeError(
        f"sea_state must be a WMO code {sorted(SEA_STATES)}, a name {SEA_STATE_NAMES}, a SeaState "
        f"or a dict of its fields, got {describe(spec)}"
    )


__all__ = [
    "GAMMA_BOUNDS",
    "HS_BOUNDS",
    "MAX_STEEPNESS",
    "SEA_STATES",
    "SEA_STATE_NAMES",
    "TP_BOUNDS",
    "WMO_HS_BANDS",
    "SeaState",
    "jonswap",
    "pierson_moskowitz",
    "sea_state",
]
