"""rsl-rl model with one activation per hidden layer.

rsl-rl 5's :class:`~rsl_rl.models.MLPModel` takes a single ``activation`` name for every hidden
layer and its resolver knows no ``hardswish``. The runner config can name any class
(``"class_name": "mjnav.train.model:LayerwiseMLPModel"``), so this subclass builds the stock
model and swaps the activation modules of its :class:`~rsl_rl.modules.MLP` in place. Everything
else (distribution, TorchScript/ONNX export, checkpoint keys) is rsl-rl's.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from rsl_rl.models import MLPModel
from tensordict import TensorDict

from mjnav.policy import make_activation

__all__ = ["LayerwiseMLPModel"]

class LayerwiseMLPModel(MLPModel):
    """:class:`~rsl_rl.models.MLPModel` with per-layer activations and an optional output gain."""

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        hidden_dims: Sequence[int] = (256, 256, 256),
        activation: str | Sequence[str] = "elu",
        obs_normalization: bool = False,
        distribution_cfg: dict | None = None,
        output_gain: float = 0.0,
    ) -> None:
        """Build the model.

        Args:
            obs: Example observations (``TensorDict`` of groups).
            obs_groups: Observation sets to groups (``{"actor": ["policy"], ...}``).
            obs_set: This model's set (``actor`` or ``critic``).
            output_dim: Output size (actions, or 1 for the critic).
            hidden_dims: Hidden layer widths.
            activation: One name for all hidden layers, or one name per hidden layer.
            obs_normalization: Normalise observations with running statistics.
            distribution_cfg: rsl-rl distribution config (stochastic output), or None.
            output_gain: Orthogonal gain of the output layer with zero bias; 0 keeps the default init.

        Raises:
            ValueError: The activation list does not match ``hidden_dims``.
        """
        names = [activation] * len(hidden_dims) if isinstance(activation, str) else list(activation)
        if len(names) != len(hidden_dims):
            raise ValueError(f"{len(names)} activations for {len(hidden_dims)} hidden layers")
        super().__init__(
            obs,
            obs_groups,
            obs_set,
            output_dim,
            tuple(hidden_dims),
            "relu",
            obs_normalization,
            distribution_cfg,
        )
        for layer, name in enumerate(names):
            self.mlp[2 * layer + 1] = make_activation(name)  # MLP = [Linear, act] * hidden + [Linear]
        if output_gain > 0:
            last = self.mlp[2 * len(names)]
            torch.nn.init.orthogonal_(last.weight, gain=output_gain)
            torch.nn.init.zeros_(last.bias)
