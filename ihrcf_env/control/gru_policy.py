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
import zipfile
import zlib
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


class PolicyFileError(ValueError):
    """A file that is not a GRU policy :meth:`GruPolicy.save` wrote (the message names the file and
    the problem)."""


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
        """Read a policy :meth:`save` wrote; :class:`PolicyFileError` (a ValueError) naming ``path``
        and the problem if it is not one (not a ``.npz`` archive, truncated, a header or weight
        missing or of the wrong type)."""
        name = repr(os.fspath(path))
        try:
            if not zipfile.is_zipfile(path):
                raise PolicyFileError(f"{name}: not a GRU policy file (not a .npz archive)")
            with np.load(path, allow_pickle=False) as data:
                missing = sorted({"header", *WEIGHTS} - set(data.files))
                if missing:
                    raise PolicyFileError(f"{name}: not a GRU policy file (no {', '.join(missing)})")
                header = _read_header(name, data["header"])
                weights = {k: _read_weight(name, k, data[k]) for k in WEIGHTS}
        except PolicyFileError:
            raise
        except (OSError, EOFError, zipfile.BadZipFile, zlib.error, KeyError, ValueError, TypeError) as e:
            raise PolicyFileError(f"{name}: not a GRU policy file (unreadable: {_one_line(e)})") from None
        try:
            return cls(weights, header["inputs"], header["obs_size"], header["meta"])
        except (ValueError, TypeError) as e:
            raise PolicyFileError(f"{name}: not a usable GRU policy ({_one_line(e)})") from None


#: Largest header (characters) and input count a policy file may have.
MAX_HEADER_CHARS = 1_000_000
MAX_INPUTS = 1_000_000


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _short(value: Any) -> str:
    """``repr(value)``, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _read_header(name: str, raw: Any) -> dict[str, Any]:
    """The JSON header of a policy file, its fields checked (format, inputs, obs_size, meta)."""
    arr = np.asarray(raw)
    if arr.shape != () or arr.dtype.kind != "U":
        raise PolicyFileError(
            f"{name}: header must be one JSON string, got an array of {arr.dtype} {arr.shape}"
        )
    text = str(arr)
    if len(text) > MAX_HEADER_CHARS:
        raise PolicyFileError(f"{name}: header longer than {MAX_HEADER_CHARS} characters")
    try:
        header = json.loads(text)
    except RecursionError:
        raise PolicyFileError(f"{name}: header nested too deeply") from None
    except ValueError as e:
        raise PolicyFileError(f"{name}: header is not JSON ({_one_line(e)})") from None
    if not isinstance(header, dict):
        raise PolicyFileError(f"{name}: header must be a JSON object, got {type(header).__name__}")
    if header.get("format") != FORMAT:
        raise PolicyFileError(
            f"{name}: GRU policy format {FORMAT} expected, got {_short(header.get('format'))}"
        )
    for key in ("inputs", "obs_size"):
        if key not in header:
            raise PolicyFileError(f"{name}: header has no {key!r}")
    obs_size = header["obs_size"]
    if isinstance(obs_size, bool) or not isinstance(obs_size, int) or not 0 < obs_size <= MAX_INPUTS:
        raise PolicyFileError(
            f"{name}: header 'obs_size' must be an integer in [1, {MAX_INPUTS}], got {_short(obs_size)}"
        )
    inputs = header["inputs"]
    if (
        not isinstance(inputs, list)
        or not 0 < len(inputs) <= MAX_INPUTS
        or not all(isinstance(i, int) and not isinstance(i, bool) for i in inputs)
    ):
        raise PolicyFileError(f"{name}: header 'inputs' must be a non-empty list of integers")
    meta = header.get("meta", {})
    if not isinstance(meta, dict):
        raise PolicyFileError(f"{name}: header 'meta' must be a JSON object, got {type(meta).__name__}")
    return {"inputs": inputs, "obs_size": obs_size, "meta": dict(meta)}


def _read_weight(name: str, key: str, raw: Any) -> NDArray[np.float64]:
    """The weight ``key`` of a policy file as float64 (real numbers only)."""
    arr = np.array(raw)
    if arr.dtype.kind not in "biuf":
        raise PolicyFileError(f"{name}: weight {key!r} must be real numbers, got {arr.dtype}")
    return arr.astype(np.float64)


__all__ = [
    "FORMAT",
    "WEIGHTS",
    "GruPolicy",
    "PolicyFileError",
]
