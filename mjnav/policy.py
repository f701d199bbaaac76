"""Learned policies on disk: finding them, building their actor and loading their checkpoints.

Training (:mod:`mjnav.train`) and evaluation (:mod:`mjnav.eval`) both use this module: the actor
network is rebuilt from an rsl-rl ``actor_state_dict`` (``mlp.<i>.weight/bias`` linear layers;
``obs_normalizer._mean/_std`` if present, rsl-rl's eps 1e-2) with the hidden activations of the
run's ``config.yaml`` (``train.policy.actor_activations``) or the spec's (relu, relu, hardswish);
a TorchScript ``policy.pt`` loads as is. A policy spec is a file, a run directory (``runs/<name>``
or ``<name>`` under ``runs/``: its ``policy.pt``, else its latest checkpoint) or a baseline name
(:data:`BASELINES`), and a learned policy's training config gives the task overrides it was
trained with (:func:`training_overrides`).
"""

from __future__ import annotations

import pickle
import re
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from mjnav import shipped
from mjnav.planners import PLANNERS, is_planner_spec, resolve_planner

__all__ = [
    "BASELINES",
    "build_actor",
    "config_beside",
    "display_name",
    "find_policy",
    "input_size",
    "is_checkpoint",
    "load_actor",
    "log_std",
    "make_activation",
    "policy_config",
    "policy_name",
    "resolve_checkpoint",
    "saved_activations",
    "torch_actor",
    "training_overrides",
]

if TYPE_CHECKING:
    import torch

class _Baselines:
    """The specs accepted besides paths: every planner spec (a name of :data:`mjnav.planners.PLANNERS`,
    looked up when asked so planners registered later count, ``package.module:Class`` or
    ``file.py:Class``: :func:`mjnav.planners.is_planner_spec`) and ``random`` (random raw actions).
    Iteration lists the names."""

    def __contains__(self, name: object) -> bool:
        return name == "random" or (isinstance(name, (str, Path)) and is_planner_spec(name))

    def __iter__(self) -> Iterator[str]:
        return iter([*PLANNERS.names(), "random"])


#: Names accepted besides paths (``in`` and iteration).
BASELINES = _Baselines()
_DEFAULT_ACTIVATIONS = ("relu", "relu", "hardswish")
#: Activations besides rsl-rl's own names (``relu``, ``elu``, ``tanh``, ...).
_EXTRA_ACTIVATIONS = {"hardswish": "Hardswish", "relu6": "ReLU6", "leaky_relu": "LeakyReLU"}


def make_activation(name: str) -> torch.nn.Module:
    """Activation module by name: rsl-rl's names plus ``hardswish``, ``relu6``, ``leaky_relu``."""
    import torch  # deferred: see load_actor
    from rsl_rl.utils import resolve_nn_activation  # deferred: ~5 s more after torch (-X importtime)

    key = name.lower()
    if key in _EXTRA_ACTIVATIONS:
        return getattr(torch.nn, _EXTRA_ACTIVATIONS[key])()
    return resolve_nn_activation(key)


def log_std(state: dict) -> np.ndarray:
    """The state-independent log-std of an rsl-rl actor state dict (raises ValueError without one)."""
    for key, transform in (("distribution.log_std_param", None), ("distribution.std_param", np.log)):
        if key in state:
            value = state[key].detach().cpu().numpy().astype(np.float64)
            return transform(value) if transform else value
    raise ValueError("checkpoint actor has no distribution.log_std_param or std_param: cannot sample")


def torch_actor(module: torch.nn.Module) -> Callable[[np.ndarray], np.ndarray]:
    """The actor as ``observation -> (4,) raw action means`` (no gradients, evaluation mode)."""
    import torch  # deferred: see load_actor

    module.eval()

    def act(observation: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = torch.as_tensor(np.asarray(observation, dtype=np.float32).reshape(1, -1))
            return module(x).reshape(-1)[:4].numpy()

    return act


def saved_activations(checkpoint: Path) -> Sequence[str]:
    """The hidden activations of a checkpoint: its run config's ``train.policy.actor_activations``, else
    the spec's (relu, relu, hardswish)."""
    config = config_beside(checkpoint)
    if config is not None:
        saved = yaml.safe_load(config.read_text()) or {}
        names = (saved.get("train") or {}).get("policy", {}).get("actor_activations")
        if names:
            return tuple(names)
    return _DEFAULT_ACTIVATIONS


def build_actor(state: dict, activations: Sequence[str]) -> torch.nn.Module:
    """A ``torch.nn.Module`` (normaliser + MLP) from an rsl-rl ``actor_state_dict``.

    Raises:
        ValueError: If the state has no ``mlp.<i>.weight`` layers or the activations do not fit.
    """
    import torch  # deferred: see load_actor

    index = sorted(int(m.group(1)) for k in state if (m := re.fullmatch(r"mlp\.(\d+)\.weight", k)))
    if not index or len(activations) != len(index) - 1:
        raise ValueError(f"checkpoint actor has {len(index)} linear layers, expected {len(activations) + 1}")
    layers: list[torch.nn.Module] = []
    for i, key in enumerate(index):
        weight, bias = state[f"mlp.{key}.weight"], state[f"mlp.{key}.bias"]
        linear = torch.nn.Linear(weight.shape[1], weight.shape[0])
        linear.load_state_dict({"weight": weight, "bias": bias})
        layers.append(linear)
        if i < len(activations):
            layers.append(make_activation(activations[i]))
    mlp = torch.nn.Sequential(*layers)
    if "obs_normalizer._mean" not in state:
        return mlp

    class Normalizer(torch.nn.Module):
        """rsl-rl's EmpiricalNormalization at inference: (x − mean)/(std + 1e-2)."""

        def __init__(self, mean: torch.Tensor, std: torch.Tensor) -> None:
            super().__init__()
            self.register_buffer("mean", mean.float())
            self.register_buffer("std", std.float())

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return (x - self.mean) / (self.std + 1e-2)

    return torch.nn.Sequential(Normalizer(state["obs_normalizer._mean"], state["obs_normalizer._std"]), mlp)


def resolve_checkpoint(path: str | Path) -> Path:
    """The file to load for a path: a file itself, or a run directory's policy.pt / latest model.

    Raises:
        FileNotFoundError: No policy file found.
    """
    path = Path(path)
    if path.is_file():
        return path
    if path.is_dir():
        if (path / "policy.pt").is_file():
            return path / "policy.pt"
        found = [(int(m.group(1)), p) for p in path.glob("model_*.pt")
                 if (m := re.fullmatch(r"model_(\d+)\.pt", p.name))]
        if found:
            return max(found)[1]
    raise FileNotFoundError(f"no policy.pt or model_<it>.pt at {path}")


def display_name(path: Path) -> str:
    """``run`` for a run's policy.pt, else ``run/stem``."""
    return path.parent.name if path.name == "policy.pt" else f"{path.parent.name}/{path.stem}"


def find_policy(spec: str | Path, runs_dir: str | Path) -> Path:
    """The file of a learned policy spec: a path, or a run name under ``runs_dir``.

    Raises:
        FileNotFoundError: Neither a baseline nor an existing path.
    """
    path = Path(spec)
    if not path.exists() and (Path(runs_dir) / str(spec)).exists():
        path = Path(runs_dir) / str(spec)
    if not path.exists():
        path = shipped.resolve(spec) or path
    if not path.exists():
        known = ", ".join(BASELINES)
        raise FileNotFoundError(f"policy {str(spec)!r}: not a planner ({known}, package.module:Class or "
                                f"path/to/file.py:Class), a shipped policy ({', '.join(shipped.names())}) "
                                "nor an existing path")
    if path.suffix == ".py":
        raise FileNotFoundError(f"policy {str(spec)!r}: a Python file is a planner: name its class, "
                                f"{str(spec)}:ClassName")
    return resolve_checkpoint(path)


def policy_name(spec: str | Path, runs_dir: str | Path = "runs") -> str:
    """Display name of a policy spec: a planner's (:attr:`mjnav.planners.PlannerSource.name`),
    ``random`` or a learned policy's ``run[/model_<it>]`` (without loading the network)."""
    text = str(spec)
    if text == "random":
        return text
    return resolve_planner(text).name if text in BASELINES else display_name(find_policy(spec, runs_dir))


def load_actor(path: Path, with_log_std: bool = False) -> tuple[torch.nn.Module, np.ndarray | None]:
    """The actor of a TorchScript ``policy.pt`` or of an rsl-rl checkpoint, and its log-std.

    Args:
        path: The file (:func:`find_policy`).
        with_log_std: Also return the Gaussian's log-std (checkpoints only).

    Returns:
        ``(module, log_std)``; ``log_std`` is None unless asked for.

    Raises:
        ValueError: Not a loadable policy, or a log-std asked of an exported policy.pt.
    """
    # deferred here and in the other torch functions: torch costs ~3 s at import (python -X importtime),
    # which evaluating only baselines never needs
    import torch

    try:
        if is_checkpoint(path):
            state = torch.load(str(path), map_location="cpu", weights_only=False)
            module = build_actor(state["actor_state_dict"], saved_activations(path))
            return module, (log_std(state["actor_state_dict"]) if with_log_std else None)
        if with_log_std:
            raise ValueError(f"policy {str(path)!r}: sampling needs an rsl-rl checkpoint (model_<it>.pt or "
                             "*_checkpoint.pt); an exported policy.pt holds only the mean")
        with warnings.catch_warnings():  # TorchScript is deprecated, still the portable format
            warnings.simplefilter("ignore", DeprecationWarning)
            return torch.jit.load(str(path), map_location="cpu"), None
    except (RuntimeError, KeyError, TypeError, AttributeError, pickle.UnpicklingError) as err:
        reason = str(err).strip().split(". ")[0].splitlines()[0] if str(err).strip() else "no detail"
        raise ValueError(
            f"policy {str(path)!r}: not a loadable TorchScript policy.pt or rsl-rl model_<it>.pt "
            f"({type(err).__name__}: {reason})"
        ) from err


def input_size(module: torch.nn.Module) -> int | None:
    """Observation length the actor takes: the input width of its first 2-D weight (None if none)."""
    for tensor in module.state_dict().values():
        if tensor.ndim == 2:
            return int(tensor.shape[1])
    return None


def is_checkpoint(path: Path) -> bool:
    """An rsl-rl checkpoint by name: ``model_<it>.pt``, ``NAME_checkpoint.pt`` or a weights-only
    ``checkpoint_weights.pt`` / shipped ``NAME_weights.pt``."""
    names = ("_checkpoint.pt", "_weights.pt")
    return re.fullmatch(r"model_\d+\.pt", path.name) is not None or path.name.endswith(names)


def policy_config(spec: str | Path, runs_dir: str | Path = "runs") -> Path | None:
    """The training ``config.yaml`` of a learned policy, or None (baselines, or none found).

    Looked up next to the loaded file: the run folder's ``config.yaml``; for a shipped
    ``NAME_policy.pt`` or ``NAME_checkpoint.pt`` its ``NAME_config.yaml``; for any other
    ``NAME.pt`` its ``NAME_config.yaml`` or ``NAME.yaml``.
    """
    text = str(spec)
    if text in BASELINES:
        return None
    return config_beside(find_policy(text, runs_dir))


def config_beside(path: Path) -> Path | None:
    """The training config next to a policy file (see :func:`policy_config`), or None."""
    stem = path.stem.removesuffix("_policy").removesuffix("_checkpoint")
    for candidate in (path.parent / "config.yaml", path.with_name(f"{stem}_config.yaml"), path.with_suffix(".yaml")):
        if candidate.is_file():
            return candidate
    return None


def training_overrides(spec: str | Path, runs_dir: str | Path = "runs") -> tuple[str, ...]:
    """The dotted task overrides a learned policy was trained with (``run.task_overrides`` of its
    config; a shipped policy's recipe), so evaluation rebuilds the task it learned (design,
    reward, collision rule, ...).

    Returns:
        The overrides, or ``()`` for baselines and policies without a config.

    Raises:
        ValueError: The config exists but is not a training config.
    """
    # a shipped name first: several names may share one actor file with different recipes
    # (stage6_tracks_policy is stage6_policy's actor with the crowd shield on)
    entry = None if str(spec) in BASELINES else shipped.find(spec) or shipped.find(find_policy(spec, runs_dir))
    if entry is not None:  # a shipped policy: its recipe's overrides
        return shipped.load_recipe(entry.recipe).task_overrides
    config = policy_config(spec, runs_dir)
    if config is None:
        return ()
    saved = yaml.safe_load(config.read_text(encoding="utf-8")) or {}
    run = saved.get("run") if isinstance(saved, dict) else None
    if not isinstance(run, dict) or not isinstance(run.get("task_overrides", []), list):
        raise ValueError(f"{config}: not a training config.yaml (no run.task_overrides list)")
    return tuple(str(o) for o in run.get("task_overrides") or ())

