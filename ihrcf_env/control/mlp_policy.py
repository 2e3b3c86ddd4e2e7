"""A feed-forward (MLP) landing policy evaluated in numpy: :class:`MlpPolicy` (pure: numpy only).

The policy maps one flat landing observation to a velocity action:

    x = clip((obs - mean) / sqrt(var + 1e-8), -clip_obs, clip_obs)   # running normalisation
    h = act(W_k h + b_k) for each hidden layer k (h_0 = x)           # act: swish, tanh or relu
    a = clip(W_o h + b_o, -1, 1)                                     # the Gaussian policy's mean

It is trained elsewhere (:mod:`ihrcf_env.rl.jax_ppo`: PPO on the JAX backend) and saved as a
``.npz`` file of its weights and a JSON header (:meth:`MlpPolicy.save`, :meth:`MlpPolicy.load`),
so running a trained policy needs numpy only; it is evaluated in float64.
"""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.control.gru_policy import PolicyFileError

__all__ = ["ACTIVATIONS", "KIND", "MlpPolicy"]

#: The ``kind`` a file's header names.
KIND = "mlp"
#: Version of the ``.npz`` layout :meth:`MlpPolicy.save` writes.
FORMAT = 1
#: Hidden-layer activations by name.
ACTIVATIONS = ("swish", "tanh", "relu")


def _act(name: str, x: NDArray[np.float64]) -> NDArray[np.float64]:
    if name == "swish":
        return x * (0.5 * (1.0 + np.tanh(0.5 * x)))
    if name == "tanh":
        return np.tanh(x)
    return np.maximum(x, 0.0)


@dataclass
class MlpPolicy:
    """An MLP policy (module docstring): ``weights[k]`` (out, in) and ``biases[k]`` per layer (the
    last one the action head), the observation normalisation ``mean`` / ``var`` and ``clip_obs``;
    ``meta`` is free JSON-able text saved with it (how it was trained)."""

    weights: list[NDArray[np.float64]]
    biases: list[NDArray[np.float64]]
    mean: NDArray[np.float64]
    var: NDArray[np.float64]
    activation: str = "swish"
    clip_obs: float = 10.0
    meta: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {ACTIVATIONS}, got {self.activation!r}")
        if not self.weights or len(self.weights) != len(self.biases):
            raise ValueError("weights and biases: one of each per layer (at least the action head)")
        self.weights = [np.asarray(w, np.float64) for w in self.weights]
        self.biases = [np.asarray(b, np.float64) for b in self.biases]
        self.mean = np.asarray(self.mean, np.float64)
        self.var = np.asarray(self.var, np.float64)
        d = self.mean.shape[0] if self.mean.ndim == 1 else -1
        if self.var.shape != self.mean.shape or d < 1:
            raise ValueError(f"mean and var: vectors of one size, got {self.mean.shape} and {self.var.shape}")
        inputs = d
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            if w.ndim != 2 or w.shape[1] != inputs or b.shape != (w.shape[0],):
                raise ValueError(
                    f"layer {k}: weights ({b.shape[0] if b.ndim else '?'}, {inputs}) expected, got {w.shape}"
                )
            inputs = w.shape[0]
        if not all(np.isfinite(a).all() for a in [*self.weights, *self.biases, self.mean, self.var]):
            raise ValueError("weights, biases, mean and var must be finite")

    @property
    def input_size(self) -> int:
        """Length of the observation vector it takes."""
        return int(self.mean.shape[0])

    @property
    def action_size(self) -> int:
        return int(self.weights[-1].shape[0])

    def act(self, obs: Any) -> NDArray[np.float32]:
        """The action (in [-1, 1]) for one observation vector."""
        x = np.asarray(obs, np.float64).reshape(-1)
        if x.shape[0] != self.input_size:
            raise ValueError(f"obs: {self.input_size} values expected, got {x.shape[0]}")
        h = np.clip((x - self.mean) / np.sqrt(self.var + 1e-8), -self.clip_obs, self.clip_obs)
        for w, b in zip(self.weights[:-1], self.biases[:-1], strict=True):
            h = _act(self.activation, w @ h + b)
        return np.clip(self.weights[-1] @ h + self.biases[-1], -1.0, 1.0).astype(np.float32)

    def reset(self) -> None:
        """Start of an episode (the policy keeps no state)."""

    # -- files -------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the policy as ``.npz`` (weights in float64)."""
        arrays: dict[str, Any] = {"mean": self.mean, "var": self.var}
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            arrays[f"w{k}"], arrays[f"b{k}"] = w, b
        header = {
            "kind": KIND,
            "format": FORMAT,
            "layers": len(self.weights),
            "activation": self.activation,
            "clip_obs": self.clip_obs,
            "meta": self.meta or {},
        }
        arrays["header"] = np.array(json.dumps(header))
        with open(path, "wb") as f:
            np.savez(f, **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> MlpPolicy:
        """Read a policy :meth:`save` wrote; :class:`PolicyFileError` naming the file otherwise."""
        name = os.fspath(path)
        try:
            with np.load(name, allow_pickle=False) as data:
                header = json.loads(str(data["header"]))
                if not isinstance(header, dict) or header.get("kind") != KIND:
                    raise PolicyFileError(
                        f"{name}: not an MLP policy file (header kind {header.get('kind')!r})"
                    )
                if header.get("format") != FORMAT:
                    raise PolicyFileError(
                        f"{name}: MLP policy format {header.get('format')!r}, expected {FORMAT}"
                    )
                n = int(header["layers"])
                weights = [data[f"w{k}"] for k in range(n)]
                biases = [data[f"b{k}"] for k in range(n)]
                return cls(
                    weights,
                    biases,
                    data["mean"],
                    data["var"],
                    activation=str(header["activation"]),
                    clip_obs=float(header["clip_obs"]),
                    meta=dict(header.get("meta") or {}),
                )
        except PolicyFileError:
            raise
        except (OSError, KeyError, ValueError, TypeError, zipfile.BadZipFile, zlib.error, EOFError) as e:
            raise PolicyFileError(f"{name}: not a readable MLP policy file ({type(e).__name__}: {e})") from e

    @staticmethod
    def is_mlp_file(path: str | os.PathLike[str]) -> bool:
        """Whether ``path`` is an ``.npz`` whose header names an MLP policy (False for anything else)."""
        try:
            with np.load(os.fspath(path), allow_pickle=False) as data:
                header = json.loads(str(data["header"]))
            return isinstance(header, dict) and header.get("kind") == KIND
        except Exception:
            return False


def mlp_from_arrays(
    layers: Sequence[tuple[Any, Any]], mean: Any, var: Any, activation: str = "swish", **meta: Any
) -> MlpPolicy:
    """An :class:`MlpPolicy` from ``(kernel (in, out), bias)`` pairs as flax's Dense stores them."""
    return MlpPolicy(
        [np.asarray(k, np.float64).T for k, _ in layers],
        [np.asarray(b, np.float64) for _, b in layers],
        mean,
        var,
        activation=activation,
        meta=dict(meta) or None,
    )
