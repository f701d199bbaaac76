"""Export the actor for use without rsl-rl: ``policy.pt`` (TorchScript) and ``policy.onnx``.

ONNX is written when the ``onnx`` package is installed (optional).

The exported module maps observations ``(399,)`` or ``(B, 399)`` to the raw action means
``(4,)`` / ``(B, 4)``; apply the sigmoid (as the environment does) to get (α_s, β_s, α_l, β_l)::

    policy = torch.jit.load("runs/stage6-.../policy.pt")
    means = policy(torch.as_tensor(obs, dtype=torch.float32))
"""

from __future__ import annotations

import importlib.util
import math
import warnings
from pathlib import Path

import torch
from rsl_rl.models import MLPModel
from tensordict import TensorDict

from mjnav.train.config import TrainConfig
from mjnav.train.model import LayerwiseMLPModel

__all__ = ["build_actor", "export_actor", "export_checkpoint"]


def export_actor(actor: MLPModel, out_dir: str | Path, onnx: bool | None = None) -> list[Path]:
    """Write ``policy.pt`` (TorchScript) and optionally ``policy.onnx`` into ``out_dir``.

    Args:
        actor: The rsl-rl actor (``runner.alg.get_policy()``).
        out_dir: Destination folder (created).
        onnx: Also export ONNX; None: when the ``onnx`` package is installed. A failed ONNX export
            only warns.

    Returns:
        The written files.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    module = actor.as_jit().to("cpu").eval()
    with warnings.catch_warnings():
        warnings.simplefilter(
            "ignore", DeprecationWarning
        )  # TorchScript is deprecated, still the portable format
        torch.jit.script(module).save(str(out / "policy.pt"))
    written = [out / "policy.pt"]
    if onnx is None:
        onnx = importlib.util.find_spec("onnx") is not None
    if onnx:
        try:
            written.append(_export_onnx(actor, out / "policy.onnx"))
        except Exception as err:  # noqa: BLE001 - ONNX is optional
            warnings.warn(
                f"ONNX export failed ({type(err).__name__}: {err}); policy.pt is complete", stacklevel=2
            )
    return written


def _export_onnx(actor: MLPModel, path: Path) -> Path:
    module = actor.as_onnx(verbose=False).to("cpu").eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the legacy exporter is fast and quiet
        torch.onnx.export(
            module,
            module.get_dummy_inputs(),
            str(path),
            input_names=module.input_names,
            output_names=module.output_names,
            opset_version=18,
            dynamo=False,
            dynamic_axes={"obs": {0: "batch"}, "actions": {0: "batch"}},
        )
    return path


def build_actor(train: TrainConfig, obs_dim: int, num_actions: int) -> LayerwiseMLPModel:
    """A fresh actor with the architecture of ``train`` (to load a checkpoint into)."""
    policy = train.policy
    obs = TensorDict({"policy": torch.zeros(1, obs_dim)}, batch_size=[1])
    distribution = {
        "class_name": "GaussianDistribution",
        "init_std": math.exp(policy.init_log_std),
        "std_type": "log",
    }
    return LayerwiseMLPModel(
        obs,
        {"actor": ["policy"]},
        "actor",
        num_actions,
        policy.actor_hidden_dims,
        policy.actor_activations,
        policy.obs_normalization,
        distribution,
    )


def export_checkpoint(
    checkpoint: str | Path, train: TrainConfig, out_dir: str | Path, obs_dim: int = 399, num_actions: int = 4
) -> list[Path]:
    """Export the actor of a ``model_<it>.pt`` checkpoint without building environments."""
    actor = build_actor(train, obs_dim, num_actions)
    state = torch.load(str(checkpoint), map_location="cpu", weights_only=False)
    actor.load_state_dict(state["actor_state_dict"])
    return export_actor(actor, out_dir)
