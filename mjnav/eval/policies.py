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
* a planner: a registered name (``mpc_goal``, ``teb``, ``dwa``, ``random_jerk``, entry points of
  the ``mjnav.planners`` group), ``package.module:Class`` or ``path/to/file.py:Class``
  (:func:`mjnav.planners.resolve_planner`; the planners guide of the documentation);
* ``random`` (random raw actions through the learned action path).

Learned policies act through the normal action path, deterministically: the raw action is the
network's mean (the environment applies the sigmoid). Every loaded policy is an :class:`Agent`:
``begin(task, episode_seed)`` before each episode, then ``act(observation)`` every step.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mjnav.planners import RandomActionPolicy, is_planner_spec, resolve_planner
from mjnav.policy import display_name, find_policy, input_size, is_checkpoint, load_actor, torch_actor
from mjnav.planners.base import declared_privileged, declared_tracks
from mjnav.schema import ConfigError

__all__ = ["ACTION_MODES", "Agent", "TimedPlanner", "load_policy", "planner_record"]

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.planners.base import Planner, PlannerInput
    from mjnav.tasks.nav import CrowdNavTask

#: Evaluation action modes (see :func:`load_policy`).
ACTION_MODES = ("mean", "expected", "sample")


class TimedPlanner:
    """Wraps a planner and records the wall time of each ``act`` call (seconds)."""

    def __init__(self, planner: Planner) -> None:
        """Wrap ``planner`` (a :class:`mjnav.planners.base.Planner`)."""
        self.planner = planner
        self.times: list[float] = []

    @property
    def privileged(self) -> frozenset[str]:
        """The wrapped planner's declared ground truth (:func:`mjnav.planners.base.declared_privileged`)."""
        return declared_privileged(self.planner)

    @property
    def uses_tracks(self) -> bool:
        """Whether the wrapped planner reads the LiDAR tracks (:func:`mjnav.planners.base.declared_tracks`)."""
        return declared_tracks(self.planner)

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
        privileged: The ground truth a planner declared (empty for learned policies).
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
        self.privileged = declared_privileged(planner) if planner is not None else frozenset()

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


# ---------------------------------------------------------------------------- sampled actors


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


def _load_learned(path: Path, mode: str = "mean") -> Agent:
    """The :class:`Agent` of a learned policy file, acting with ``mode``."""
    if mode != "mean" and not is_checkpoint(path):
        raise ValueError(f"policy {str(path)!r}: action={mode} needs an rsl-rl checkpoint (model_<it>.pt or "
                         "*_checkpoint.pt); an exported policy.pt holds only the mean")
    module, std = load_actor(path, with_log_std=mode != "mean")
    actor = torch_actor(module)
    if std is not None:
        actor = (_SampledActor if mode == "sample" else _ExpectedActor)(actor, std)
    agent = Agent(display_name(path), "learned", str(path), actor=actor)
    agent.input_size = input_size(module)
    return agent


def load_policy(spec: str | Path, runs_dir: str | Path = "runs", mode: str = "mean",
                planner: Sequence[str] = ()) -> Agent:
    """Load a policy by ``PATH_OR_NAME`` (see the module docstring).

    Args:
        spec: Planner spec (registered name, ``module:Class``, ``file.py:Class``), file or run
            directory (or a run name under ``runs_dir``).
        runs_dir: Where run names are looked up.
        mode: ``mean`` (deterministic, sigmoid of the mean, spec §8), ``expected`` (deterministic,
            the expected squashed action of the Gaussian, :class:`_ExpectedActor`) or ``sample``
            (the training Gaussian, noise seeded by the episode seed); the last two need a
            checkpoint.
        planner: ``["w_clearance=0.8", ...]`` parameter overrides of a planner with a config
            class (:meth:`mjnav.planners.resolve.PlannerSource.make`); rejected for anything else.

    Returns:
        The :class:`Agent`.

    Raises:
        FileNotFoundError: Neither a planner nor an existing file/run.
        mjnav.planners.PlannerError: A planner module or file that cannot be loaded, or not a Planner
            (a ValueError).
        ValueError: The file is not a TorchScript policy or an rsl-rl checkpoint of a known actor.
        ConfigError: Planner overrides for a policy that is not a configurable planner.
    """
    text = str(spec)
    if planner and not is_planner_spec(text):
        raise ConfigError(f"planner overrides {list(planner)} need a planner, not {text!r}")
    if text == "random":
        return Agent("random", "random", "random", actor=RandomActionPolicy())
    if is_planner_spec(text):
        found = resolve_planner(text)
        return Agent(found.name, "planner", found.source, planner=found.make(planner))
    if mode not in ACTION_MODES:
        raise ValueError(f"action: expected one of {ACTION_MODES}, got {mode!r}")
    return _load_learned(find_policy(text, runs_dir), mode)


def planner_record(spec: str | Path, overrides: Sequence[str] = ()) -> dict[str, object]:
    """What an evaluation's JSONL records about the planner of ``spec`` (all None for other policies).

    Returns:
        ``planner_source`` (registered name, ``module:Class`` or ``<absolute path>:Class``),
        ``planner_sha256`` (its source files, :meth:`mjnav.planners.PlannerSource.sha256`),
        ``planner_params`` (its resolved parameters, ``{}`` without a config class) and
        ``planner_privileged`` (the sorted ground truth it declared).

    Raises:
        mjnav.planners.PlannerError, ConfigError: As :func:`load_policy`.
    """
    text = str(spec)
    if text == "random" or not is_planner_spec(text):
        return {"planner_source": None, "planner_sha256": None, "planner_params": None, "planner_privileged": None}
    found = resolve_planner(text)
    return {"planner_source": found.source, "planner_sha256": found.sha256(), "planner_params": found.params(overrides),
            "planner_privileged": sorted(found.privileged)}
