"""Stage curriculum (spec §9, proposal): the numbered stages of the tasks folder in order
(stage1 -> stage7 today; :func:`mjnav.stages.stage_numbers`).

Training on a stage is interrupted every ``eval_interval`` iterations for a deterministic
evaluation over ``eval_episodes`` episodes in separately seeded environments (base seed offset by
``eval_seed_offset``; their episode seeds come from the same < 2**31 space as training, unlike the
held-out set of ``scripts/evaluate.py``, which is kept for final results). The curriculum promotes to the next
stage when the success rate reaches ``threshold`` or when the stage's env-step budget is spent.
One runner (networks, optimizer, iteration count, TensorBoard run) lives through all stages;
only its environment is swapped. The state is kept in ``curriculum.yaml`` for resuming.
Under torchrun every rank evaluates with the same weights on the same evaluation seeds, so all
ranks take the same decisions; rank 0 alone prints them and writes ``curriculum.yaml``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from rsl_rl.runners import OnPolicyRunner

from mjnav import stages
from mjnav.envs.vec_env import NavVecEnv
from mjnav.train import distributed
from mjnav.train.config import TrainConfig
from mjnav.train.evaluate import EvalResult, evaluate
from mjnav.train.runner import learn, make_vec_env, save_checkpoint

if TYPE_CHECKING:
    from mjnav.config import TaskConfig

__all__ = ["CurriculumState", "load_stage", "promotion", "run_curriculum", "stage_name"]

EnvMaker = Callable[..., NavVecEnv]
STATE_FILE = "curriculum.yaml"


def stage_name(stage: int) -> str:
    """Task name of a stage number (``3`` -> ``stage3``), checked against the tasks folder."""
    return stages.stage_name(stage)


def load_stage(name: str, overrides: list[str]) -> TaskConfig:
    """:func:`mjnav.stages.load_stage`: the stage of that name with dotted overrides."""
    return stages.load_stage(name, overrides)


@dataclasses.dataclass
class CurriculumState:
    """Where the curriculum stands.

    Attributes:
        stage: Current stage number.
        stage_start: Iteration at which the current stage began.
        finished: The last stage was completed.
        evaluations: One record per evaluation (stage, iteration, rates, decision).
    """

    stage: int
    stage_start: int = 0
    finished: bool = False
    evaluations: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    def save(self, run_dir: str | Path) -> None:
        """Write ``curriculum.yaml`` into ``run_dir`` (rank 0 only under torchrun)."""
        if not distributed.current().main:
            return
        Path(run_dir, STATE_FILE).write_text(yaml.safe_dump(dataclasses.asdict(self), sort_keys=False))

    @classmethod
    def load(cls, run_dir: str | Path) -> CurriculumState:
        """Read ``curriculum.yaml`` from ``run_dir``."""
        return cls(**yaml.safe_load(Path(run_dir, STATE_FILE).read_text()))


def promotion(result: EvalResult, stage_steps: int, train: TrainConfig) -> str | None:
    """``"success"`` (rate >= threshold), ``"budget"`` (steps spent) or None (keep training)."""
    if result.success >= train.curriculum.threshold:
        return "success"
    if stage_steps >= train.curriculum.stage_steps:
        return "budget"
    return None


def run_curriculum(
    runner: OnPolicyRunner,
    train: TrainConfig,
    task_overrides: list[str],
    state: CurriculumState,
    run_dir: str | Path,
    make_env: EnvMaker = make_vec_env,
) -> CurriculumState:
    """Train through the stages until the last one is passed or ``train.iterations`` is reached.

    Args:
        runner: A runner whose environment is already the current stage's.
        train: The training config (curriculum settings in ``train.curriculum``).
        task_overrides: Dotted task overrides applied to every stage.
        state: Curriculum state (fresh or loaded for a resume); updated in place and saved.
        run_dir: Run folder (checkpoints, ``curriculum.yaml``).
        make_env: ``make_env(task, train, seed=None, num_envs=None)`` builds an adapter.

    Returns:
        The final state.
    """
    first = True
    while not state.finished and runner.current_learning_iteration < train.iterations:
        task = load_stage(stage_name(state.stage), task_overrides)
        if not first:
            _swap_env(runner, make_env(task, train))
        first = False
        eval_env = _eval_env(task, train, state.stage, make_env)
        try:
            _train_stage(runner, train, state, eval_env, run_dir)
        finally:
            eval_env.close()
    return state


def _eval_env(task: TaskConfig, train: TrainConfig, stage: int, make_env: EnvMaker) -> NavVecEnv:
    cfg = train.curriculum
    seed = train.seed + cfg.eval_seed_offset + 10_000 * stage
    return make_env(task, train, seed=seed, num_envs=min(train.num_envs, cfg.eval_episodes))


def _swap_env(runner: OnPolicyRunner, env: NavVecEnv) -> None:
    """Give the runner the next stage's environment (same sizes) and close the old one."""
    old = runner.env
    runner.env = env
    runner.logger.cur_reward_sum.zero_()
    runner.logger.cur_episode_length.zero_()
    old.close()


def _train_stage(
    runner: OnPolicyRunner,
    train: TrainConfig,
    state: CurriculumState,
    eval_env: NavVecEnv,
    run_dir: str | Path,
) -> None:
    """Alternate training chunks and evaluations until promotion or the iteration limit."""
    cfg = train.curriculum
    batch = train.num_envs * train.steps_per_env
    budget_iterations = math.ceil(cfg.stage_steps / batch)
    while runner.current_learning_iteration < train.iterations:
        done = runner.current_learning_iteration - state.stage_start
        chunk = min(
            cfg.eval_interval,
            max(1, budget_iterations - done),
            train.iterations - runner.current_learning_iteration,
        )
        learn(runner, chunk, train.random_initial_lengths)
        result = evaluate(runner.get_inference_policy(train.device), eval_env, cfg.eval_episodes)
        steps = (runner.current_learning_iteration - state.stage_start) * batch
        decision = promotion(result, steps, train)
        _record(state, runner.current_learning_iteration, steps, result, decision)
        if decision is not None:
            save_checkpoint(runner, run_dir)
            following = stages.next_stage(state.stage)
            state.finished = following is None or following not in cfg.stages()
            if not state.finished:
                state.stage, state.stage_start = following, runner.current_learning_iteration
        state.save(run_dir)
        if decision is not None:
            return


def _record(
    state: CurriculumState, iteration: int, steps: int, result: EvalResult, decision: str | None
) -> None:
    entry = {
        "stage": state.stage,
        "iteration": iteration,
        "stage_steps": steps,
        **dataclasses.asdict(result),
        "decision": decision,
    }
    state.evaluations.append(entry)
    verdict = {"success": "promoted (success)", "budget": "promoted (step budget spent)", None: "stays"}[
        decision
    ]
    if distributed.current().main:  # every rank evaluates alike (same weights and evaluation seeds)
        print(f"[curriculum] {stage_name(state.stage)} eval at iteration {iteration}: {result.summary()}"
              f" -> {verdict}", flush=True)
