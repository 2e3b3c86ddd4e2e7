"""A recurrent (GRU) landing policy evaluated in numpy: :class:`GruPolicy` (pure: numpy only).

The policy reads the flat landing observation one step at a time and keeps a hidden state across
the steps of an episode, so it can carry what one observation does not show (filtered heave and
tilt, how long the deck has been calm, where the tag was when it left the view). Its network:

    x = clip((obs[inputs] - mean) / std, -10, 10)
    e = tanh(W_e x + b_e)                       # input layer
    h = GRU(e, h)                               # one recurrent layer (PyTorch's GRU equations)
    a = clip(W_o tanh(W_h h + b_h) + b_o, -1, 1)  # velocity action in [-1, 1]^4

It is trained elsewhere (:mod:`ihrcf_env.rl.recurrent`, the ``[rl]`` extra, with PyTorch) and
saved as a ``.npz`` file of its weights (float32, as trained) and a JSON header
(:meth:`GruPolicy.save`, :meth:`GruPolicy.load`), so running a trained policy needs numpy only; it
is evaluated in float64.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Version of the ``.npz`` layout :meth:`GruPolicy.save` writes.
FORMAT = 1
#: The weight arrays of a policy file and their shapes in terms of D (inputs), E (input layer),
#: H (recurrent state), F (head layer) and A (actions).
WEIGHTS = {
    "mean": ("D",),
    "std": ("D",),
    "w_e": ("E", "D"),
    "b_e": ("E",),
    "w_ih": ("3H", "E"),
    "w_hh": ("3H", "H"),
    "b_ih": ("3H",),
    "b_hh": ("3H",),
    "w_h": ("F", "H"),
    "b_h": ("F",),
    "w_o": ("A", "F"),
    "b_o": ("A",),
}


def _sigmoid(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (1.0 + np.tanh(0.5 * x))


@dataclass
class GruPolicy:
    """A GRU policy over ``inputs`` of a flat observation of size ``obs_size`` (module docstring).

    ``weights`` maps the names of :data:`WEIGHTS` to arrays; ``meta`` is free-form JSON-able
    information saved with it (the env id and options it was trained on, its training run)."""

    weights: Mapping[str, NDArray[np.float64]]
    inputs: Sequence[int]
    obs_size: int
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        w = {k: np.asarray(v, dtype=np.float64) for k, v in self.weights.items()}
        missing = sorted(set(WEIGHTS) - set(w))
        if missing:
            raise ValueError(f"weights: missing {missing}")
        self.inputs = [int(i) for i in self.inputs]
        if not self.inputs or min(self.inputs) < 0 or max(self.inputs) >= int(self.obs_size):
            raise ValueError(
                f"inputs: indices into an observation of size {self.obs_size}, got {self.inputs}"
            )
        sizes = {
            "D": len(self.inputs),
            "E": w["w_e"].shape[0],
            "H": w["w_hh"].shape[1],
            "F": w["w_h"].shape[0],
            "A": w["w_o"].shape[0],
        }
        sizes["3H"] = 3 * sizes["H"]
        for name, dims in WEIGHTS.items():
            want = tuple(sizes[d] for d in dims)
            if w[name].shape != want:
                raise ValueError(f"weights[{name!r}]: shape {want} ({', '.join(dims)}), got {w[name].shape}")
            if not np.all(np.isfinite(w[name])):
                raise ValueError(f"weights[{name!r}]: not finite")
        if np.any(w["std"] <= 0):
            raise ValueError("weights['std']: must be > 0")
        self.weights = w
        self.obs_size = int(self.obs_size)
        self._h = np.zeros(sizes["H"])

    @property
    def hidden_size(self) -> int:
        """Size of the recurrent state."""
        return int(self._h.shape[0])

    def reset(self) -> None:
        """Episode start: the recurrent state back to zero."""
        self._h = np.zeros(self.hidden_size)

    def act(self, obs: NDArray[np.float32]) -> NDArray[np.float32]:
        """The action for this step's observation (advances the recurrent state)."""
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != (self.obs_size,):
            raise ValueError(f"obs: shape ({self.obs_size},), got {x.shape}")
        a, h = self.step(x[None], self._h[None])
        self._h = h[0]
        return a[0].astype(np.float32)

    def step(
        self, obs: NDArray[np.float64], hidden: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Actions ``(N, A)`` and next states ``(N, H)`` for N observations ``(N, obs_size)`` and
        their states ``(N, H)`` (N episodes at once; zeros start an episode)."""
        w = self.weights
        x = np.clip((obs[:, self.inputs] - w["mean"]) / w["std"], -10.0, 10.0)
        e = np.tanh(x @ w["w_e"].T + w["b_e"])
        gi = e @ w["w_ih"].T + w["b_ih"]
        gh = hidden @ w["w_hh"].T + w["b_hh"]
        n_h = self.hidden_size
        r = _sigmoid(gi[:, :n_h] + gh[:, :n_h])
        z = _sigmoid(gi[:, n_h : 2 * n_h] + gh[:, n_h : 2 * n_h])
        n = np.tanh(gi[:, 2 * n_h :] + r * gh[:, 2 * n_h :])
        h = (1.0 - z) * n + z * hidden
        a = np.tanh(h @ w["w_h"].T + w["b_h"]) @ w["w_o"].T + w["b_o"]
        return np.clip(a, -1.0, 1.0), h

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the policy to ``path`` (a ``.npz``: the weights in float32 and a JSON header)."""
        header = {"format": FORMAT, "inputs": self.inputs, "obs_size": self.obs_size, "meta": self.meta}
        payload: dict[str, Any] = {k: np.asarray(v, dtype=np.float32) for k, v in self.weights.items()}
        payload["header"] = np.array(json.dumps(header))
        with open(path, "wb") as f:
            np.savez(f, **payload)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> GruPolicy:
        """Read a policy :meth:`save` wrote; ValueError naming ``path`` if it is not one."""
        try:
            with np.load(path, allow_pickle=False) as data:
                header = json.loads(str(data["header"]))
                weights = {k: np.array(data[k]) for k in WEIGHTS}
        except (OSError, KeyError, ValueError, TypeError) as e:
            raise ValueError(f"{os.fspath(path)!r}: not a GRU policy file ({e})") from None
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise ValueError(f"{os.fspath(path)!r}: GRU policy format {FORMAT} expected")
        return cls(weights, header["inputs"], header["obs_size"], dict(header.get("meta", {})))


__all__ = [
    "FORMAT",
    "WEIGHTS",
    "GruPolicy",
]
