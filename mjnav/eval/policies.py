"""Load a policy for evaluation by ``PATH_OR_NAME``.

Accepted specs:

* a TorchScript actor ``policy.pt`` (obs (399,) → the 4 raw action means);
* an rsl-rl checkpoint ``model_<it>.pt``: the actor is rebuilt from ``actor_state_dict``
  (``mlp.<i>.weight/bias`` linear layers; ``obs_normalizer._mean/_std`` if present, rsl-rl's
  eps 1e-2), with the hidden activations from the run's ``config.yaml``
  (``train.policy.actor_activations``) or the spec's (relu, relu, hardswish);
* a run directory (``runs/<name>`` or just ``<name>`` under ``runs/``): its ``policy.pt``, else
  its latest checkpoint;
* a shipped policy's name (``stage6_policy``; ``stage5_policy.weights`` for its weights-only
  checkpoint), looked up and checksum-checked in ``policies/manifest.yaml`` (:mod:`mjnav.shipped`);
* a baseline name: ``mpc_goal``, ``teb``, ``dwa``, ``random_jerk`` (planners, see
  :mod:`mjnav.baselines`) or ``random`` (random raw actions through the learned action path).

Learned policies act through the normal action path, deterministically: the raw action is the
network's mean (the environment applies the sigmoid). Every loaded policy is an :class:`Agent`:
``begin(task, episode_seed)`` before each episode, then ``act(observation)`` every step.
"""

from __future__ import annotations

import pickle
import re
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mjnav import shipped
from mjnav.baselines import PLANNERS, RandomActionPolicy, make_planner
from mjnav.schema import ConfigError

__all__ = [
    "ACTION_MODES",
    "BASELINES",
    "Agent",
    "TimedPlanner",
    "build_actor",
    "load_policy",
    "policy_name",
    "policy_config",
    "resolve_checkpoint",
    "training_overrides",
]

if TYPE_CHECKING:
    import torch

    from mjnav.config import TaskConfig
    from mjnav.tasks.core import Planner, PlannerInput
    from mjnav.tasks.nav import CrowdNavTask

#: Evaluation action modes (see :func:`load_policy`).
ACTION_MODES = ("mean", "expected", "sample")
#: Names accepted besides paths.
BASELINES = (*PLANNERS, "random")
_DEFAULT_ACTIVATIONS = ("relu", "relu", "hardswish")


class TimedPlanner:
    """Wraps a planner and records the wall time of each ``act`` call (seconds)."""

    def __init__(self, planner: Planner) -> None:
        """Wrap ``planner`` (a :class:`mjnav.tasks.core.Planner`)."""
        self.planner = planner
        self.times: list[float] = []

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Forward to the planner and clear the timings."""
        self.times = []
        self.planner.reset(config, rng)

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Forward to the planner, timing it."""
        start = time.perf_counter()
        jerk = self.planner.act(inp)
        self.times.append(time.perf_counter() - start)
        return jerk


class Agent:
    """A policy bound to the evaluation loop (learned actor or baseline planner).

    Attributes:
        name: Display name (baseline name or the loaded file's run/name).
        kind: ``learned``, ``random`` or ``planner``.
        source: What was loaded (a path or the baseline name).
    """

    def __init__(
        self, name: str, kind: str, source: str, actor: Callable | None = None,
        planner: Planner | None = None,
    ) -> None:
        """Use :func:`load_policy` rather than this constructor."""
        self.name, self.kind, self.source = name, kind, source
        self._actor = actor
        self.action_size = 4  # the task's, from begin()
        self.planner = TimedPlanner(planner) if planner is not None else None
        self.input_size: int | None = None  # observation length a learned actor takes

    def begin(self, task: CrowdNavTask, episode_seed: int) -> None:
        """Install on ``task`` (a CrowdNavTask) before its reset for ``episode_seed``.

        Raises:
            ValueError: A learned actor whose input size is not the task's observation size
                (trained with another ``design``, frame count or polygon resolution).
        """
        size = task.core.observation_size
        if self.input_size is not None and self.input_size != size:
            raise ValueError(f"policy {self.source!r} takes {self.input_size} observation values, task "
                             f"{task.config.name} (design {task.config.design}) gives {size}: evaluate it with the "
                             "task overrides it was trained with")
        task.planner = self.planner
        self.action_size = task.core.design.action_size
        if isinstance(self._actor, RandomActionPolicy):
            self._actor.size = self.action_size
        if isinstance(self._actor, (RandomActionPolicy, _SampledActor)):
            self._actor.reset(np.random.default_rng([episode_seed, 1]))

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The float32 raw action (zeros for planners: the task ignores it)."""
        if self._actor is None:
            return np.zeros(self.action_size, dtype=np.float32)
        return np.asarray(self._actor(observation), dtype=np.float32).reshape(-1)

    def plan_times_ms(self) -> list[float]:
        """Planner wall times of the current episode, ms (empty for learned policies)."""
        return [1e3 * t for t in self.planner.times] if self.planner is not None else []


# ---------------------------------------------------------------------------- torch actors


class _SampledActor:
    """The policy's Gaussian: mean + exp(log_std)·N(0, 1) on the raw action (as in training)."""

    def __init__(self, mean: Callable[[np.ndarray], np.ndarray], log_std: np.ndarray) -> None:
        self._mean, self._std = mean, np.exp(np.asarray(log_std, dtype=np.float64))
        self._rng = np.random.default_rng(0)

    def reset(self, rng: np.random.Generator) -> None:
        """Start an episode with its own generator (paired across policies by episode seed)."""
        self._rng = rng

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        mean = self._mean(observation)
        return (mean + self._std * self._rng.standard_normal(mean.shape)).astype(np.float32)


class _ExpectedActor:
    """The expected squashed action of the policy's Gaussian, as one deterministic raw action.

    The environment squashes with a sigmoid, and sigmoid(mean) is not the mean of the squashed
    actions the policy was trained with: a raw mean far out on the sigmoid turns into a point on
    the polygon's edge, where sampling would have spread it inwards. E[sigmoid(μ + σε)] is
    approximated by sigmoid(μ / √(1 + πσ²/8)) (the probit approximation; within 0.02 of the
    quadrature value), so this returns μ / √(1 + πσ²/8).
    """

    def __init__(self, mean: Callable[[np.ndarray], np.ndarray], log_std: np.ndarray) -> None:
        std = np.exp(np.asarray(log_std, dtype=np.float64))
        self._mean, self._scale = mean, 1.0 / np.sqrt(1.0 + np.pi * std**2 / 8.0)

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        return (self._mean(observation) * self._scale).astype(np.float32)


def _log_std(state: dict) -> np.ndarray:
    """The state-independent log-std of an rsl-rl actor state dict."""
    for key, transform in (("distribution.log_std_param", None), ("distribution.std_param", np.log)):
        if key in state:
            value = state[key].detach().cpu().numpy().astype(np.float64)
            return transform(value) if transform else value
    raise ValueError("checkpoint actor has no distribution.log_std_param or std_param: cannot sample")


def _torch_actor(module: torch.nn.Module) -> Callable[[np.ndarray], np.ndarray]:
    import torch

    module.eval()

    def act(observation: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = torch.as_tensor(np.asarray(observation, dtype=np.float32).reshape(1, -1))
            return module(x).reshape(-1)[:4].numpy()

    return act


def _activations(checkpoint: Path) -> Sequence[str]:
    config = _config_beside(checkpoint)
    if config is not None:
        import yaml

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
    import torch

    from mjnav.train.model import make_activation

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


def _display_name(path: Path) -> str:
    return path.parent.name if path.name == "policy.pt" else f"{path.parent.name}/{path.stem}"


def _find(spec: str | Path, runs_dir: str | Path) -> Path:
    path = Path(spec)
    if not path.exists() and (Path(runs_dir) / str(spec)).exists():
        path = Path(runs_dir) / str(spec)
    if not path.exists():
        path = shipped.resolve(spec) or path
    if not path.exists():
        known = ", ".join(BASELINES)
        raise FileNotFoundError(f"policy {str(spec)!r}: not a baseline ({known}), a shipped policy "
                                f"({', '.join(shipped.names())}) nor an existing path")
    return resolve_checkpoint(path)


def policy_name(spec: str | Path, runs_dir: str | Path = "runs") -> str:
    """Display name of a policy spec without loading it (baseline name or ``run[/model_<it>]``)."""
    return str(spec) if str(spec) in BASELINES else _display_name(_find(spec, runs_dir))


def _load_learned(path: Path, mode: str = "mean") -> Agent:
    import torch

    name = _display_name(path)
    log_std = None
    try:
        if _is_checkpoint(path):
            state = torch.load(str(path), map_location="cpu", weights_only=False)
            module = build_actor(state["actor_state_dict"], _activations(path))
            log_std = _log_std(state["actor_state_dict"]) if mode != "mean" else None
        elif mode != "mean":
            raise ValueError(f"policy {str(path)!r}: action={mode} needs an rsl-rl checkpoint (model_<it>.pt or "
                             "*_checkpoint.pt); an exported policy.pt holds only the mean")
        else:
            with warnings.catch_warnings():  # TorchScript is deprecated, still the portable format
                warnings.simplefilter("ignore", DeprecationWarning)
                module = torch.jit.load(str(path), map_location="cpu")
    except (RuntimeError, KeyError, TypeError, AttributeError, pickle.UnpicklingError) as err:
        reason = str(err).strip().split(". ")[0].splitlines()[0] if str(err).strip() else "no detail"
        raise ValueError(
            f"policy {str(path)!r}: not a loadable TorchScript policy.pt or rsl-rl model_<it>.pt "
            f"({type(err).__name__}: {reason})"
        ) from err
    actor = _torch_actor(module)
    if log_std is not None:
        actor = (_SampledActor if mode == "sample" else _ExpectedActor)(actor, log_std)
    agent = Agent(name, "learned", str(path), actor=actor)
    agent.input_size = _input_size(module)
    return agent


def _input_size(module: torch.nn.Module) -> int | None:
    """Observation length the actor takes: the input width of its first 2-D weight (None if none)."""
    for tensor in module.state_dict().values():
        if tensor.ndim == 2:
            return int(tensor.shape[1])
    return None


def _is_checkpoint(path: Path) -> bool:
    """An rsl-rl checkpoint by name: ``model_<it>.pt``, ``NAME_checkpoint.pt`` or a weights-only
    ``checkpoint_weights.pt`` / shipped ``NAME_weights.pt``."""
    names = ("_checkpoint.pt", "_weights.pt")
    return re.fullmatch(r"model_\d+\.pt", path.name) is not None or path.name.endswith(names)


def load_policy(spec: str | Path, runs_dir: str | Path = "runs", mode: str = "mean",
                planner: Sequence[str] = ()) -> Agent:
    """Load a policy by ``PATH_OR_NAME`` (see the module docstring).

    Args:
        spec: Baseline name, file or run directory (or a run name under ``runs_dir``).
        runs_dir: Where run names are looked up.
        mode: ``mean`` (deterministic, sigmoid of the mean, spec §8), ``expected`` (deterministic,
            the expected squashed action of the Gaussian, :class:`_ExpectedActor`) or ``sample``
            (the training Gaussian, noise seeded by the episode seed); the last two need a
            checkpoint.
        planner: ``["w_clearance=0.8", ...]`` parameter overrides of a baseline planner
            (:func:`mjnav.baselines.make_planner`); rejected for anything else.

    Returns:
        The :class:`Agent`.

    Raises:
        FileNotFoundError: Neither a baseline nor an existing file/run.
        ValueError: The file is not a TorchScript policy or an rsl-rl checkpoint of a known actor.
        ConfigError: Planner overrides for a policy that is not a configurable planner.
    """
    text = str(spec)
    if planner and text not in PLANNERS:
        raise ConfigError(f"planner overrides {list(planner)} need a baseline planner, not {text!r}")
    if text == "random":
        return Agent("random", "random", "random", actor=RandomActionPolicy())
    if text in PLANNERS:
        return Agent(text, "planner", text, planner=make_planner(text, planner))
    if mode not in ACTION_MODES:
        raise ValueError(f"action: expected one of {ACTION_MODES}, got {mode!r}")
    return _load_learned(_find(text, runs_dir), mode)


def policy_config(spec: str | Path, runs_dir: str | Path = "runs") -> Path | None:
    """The training ``config.yaml`` of a learned policy, or None (baselines, or none found).

    Looked up next to the loaded file: the run folder's ``config.yaml``; for a shipped
    ``NAME_policy.pt`` or ``NAME_checkpoint.pt`` its ``NAME_config.yaml``; for any other
    ``NAME.pt`` its ``NAME_config.yaml`` or ``NAME.yaml``.
    """
    text = str(spec)
    if text in BASELINES:
        return None
    return _config_beside(_find(text, runs_dir))


def _config_beside(path: Path) -> Path | None:
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
    entry = None if str(spec) in BASELINES else shipped.find(_find(spec, runs_dir))
    if entry is not None:  # a shipped policy: its recipe's overrides
        return shipped.load_recipe(entry.recipe).task_overrides
    config = policy_config(spec, runs_dir)
    if config is None:
        return ()
    import yaml

    saved = yaml.safe_load(config.read_text(encoding="utf-8")) or {}
    run = saved.get("run") if isinstance(saved, dict) else None
    if not isinstance(run, dict) or not isinstance(run.get("task_overrides", []), list):
        raise ValueError(f"{config}: not a training config.yaml (no run.task_overrides list)")
    return tuple(str(o) for o in run.get("task_overrides") or ())

