"""A training session as ``mjnav train`` runs it: arguments, run folder, resume, export.

The arguments are :class:`TrainOptions` plus ``task.*``/``train.*`` overrides and ``seed=`` (the same
as ``train.seed=``), in the grammar of :mod:`mjnav.args`; ``mjnav train --help`` lists them.

Each run writes ``<out>/<task>-<YYYYmmdd-HHMMSS>-<pid>-<4 hex>/`` (:func:`mjnav.jobs.unique_stamp`: runs
of a job array started in the same second never share a folder): ``config.yaml`` (resolved task and train
configs), TensorBoard events, ``model_<it>.pt`` checkpoints, ``curriculum.yaml`` (curriculum
runs), ``.lock`` (held by the process training into the folder: a ``resume=`` of a run still
training is refused) and, at the end, ``policy.pt`` (TorchScript actor; ``policy.onnx`` when onnx
is installed) and ``checkpoint_weights.pt`` (actor with its std and critic, no optimizer state:
~2.3 MB, what a shipped policy adds besides its actor; ``init=`` and ``start=auto`` take it).

Under ``torchrun --nproc_per_node=N`` the session trains one policy data-parallel over N processes
(:mod:`mjnav.train.distributed`): ``train.num_envs`` environments per rank, rank 0 writing the run
folder (the same files), every rank loading the checkpoint on ``resume=``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import shlex
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import torch
import yaml

from mjnav import shipped
from mjnav.args import Grammar, parse
from mjnav.jobs import FolderInUse, holder, holding, unique_stamp, write_atomic
from mjnav.config import TASK_SECTIONS, TaskConfig
from mjnav.envs.vec_env import EnvError
from mjnav.policy import training_overrides
from mjnav.schema import ConfigError, apply_overrides, from_dict, to_dict
from mjnav.stages import stage_numbers
from mjnav.train import curriculum as stages
from mjnav.train import distributed
from mjnav.train.config import TrainConfig, load_train
from mjnav.train.curriculum import CurriculumState, run_curriculum, stage_name
from mjnav.train.export import export_actor
from mjnav.train.runner import (
    TrainingInterrupted,
    build_runner,
    checkpoints,
    handle_interrupts,
    learn,
    load_checkpoint,
    make_vec_env,
    save_checkpoint,
    save_weights,
)

__all__ = [
    "RunArgs", "RunPlan", "TrainOptions", "check_device", "curriculum_iterations", "grammar", "parse_args", "plan_run",
    "resolve_start", "resume_command", "run", "shipped_checkpoint",
]

START_MODES = ("auto", "shipped", "curriculum", "scratch")


@dataclasses.dataclass(frozen=True)
class RunArgs:
    """Parsed command line (see the module docstring)."""

    task: str | None = None
    task_overrides: tuple[str, ...] = ()
    train_overrides: tuple[str, ...] = ()
    resume: str | None = None
    init: str | None = None
    curriculum: bool = False
    out: str = "runs"
    start: str = "auto"
    recipe: str | None = None


@dataclasses.dataclass
class RunPlan:
    """Everything a session needs once the arguments are resolved."""

    run_dir: Path
    task: Any
    train: TrainConfig
    task_overrides: list[str]
    curriculum: CurriculumState | None = None
    checkpoint: Path | None = None
    init: Path | None = None
    start: str = "scratch"


@dataclasses.dataclass(frozen=True)
class TrainOptions:
    """The ``train`` verb's own keys (``mjnav train --help``).

    Attributes:
        task: Bundled stage name or task YAML path (not needed with curriculum or resume).
        resume: Continue this run folder from its latest checkpoint up to ``train.iterations``.
        init: Start a new run from this checkpoint's actor and critic weights.
        curriculum: Walk stage1 -> stage7 (``train.curriculum.*``); without ``train.iterations=`` the
            cap is every stage's whole budget.
        out: Parent folder of the run folders.
        start: Where a new run on stage K starts: ``shipped`` (the shipped stage K-1 policy),
            ``curriculum`` (walk stage 1 -> K), ``scratch`` or ``auto`` (shipped, else curriculum
            for K >= 2, else scratch); init=/resume=/curriculum=true win.
        recipe: Retrain this shipped policy from its recipe (``tasks/recipes/NAME.yaml``: task, task
            overrides, PPO settings, the shipped weights it starts from); task./train. keys win.
    """

    task: str | None = None
    resume: str | None = None
    init: str | None = None
    curriculum: bool = False
    out: str = "runs"
    start: str = "auto"
    recipe: str | None = None


def grammar() -> Grammar:
    """What ``train`` accepts: :class:`TrainOptions`, ``task.*`` and ``train.*`` overrides, ``seed=`` (``train.seed=``)."""
    return Grammar(TrainOptions, ("task", "train"), {"seed": "train.seed"}, TASK_SECTIONS)


def parse_args(argv: Sequence[str]) -> RunArgs:
    """Parse ``key=value`` arguments (:mod:`mjnav.args`).

    Raises:
        ConfigError: Unknown key (named in the message), malformed argument or wrong value type.
    """
    parsed = parse(argv, grammar())
    if parsed.options.start not in START_MODES:
        raise ConfigError(f"start: expected one of {', '.join(START_MODES)}, got {parsed.options.start!r}")
    return RunArgs(task_overrides=parsed.task, train_overrides=parsed.train, **dataclasses.asdict(parsed.options))


def _task_from_dict(data: dict[str, Any], overrides: list[str]) -> Any:
    """The saved run's task; a version-1 dump keeps version 1's layouts (no pedestrian clearance)."""
    if int(data.get("version", 1)) < 2:
        layout = dict(data.get("layout") or {})
        layout.setdefault("pedestrian_clearance", 0.0)
        data = {**data, "layout": layout}
    return apply_overrides(from_dict(TaskConfig, data), overrides)


def curriculum_iterations(train: TrainConfig) -> int:
    """Iterations that let a curriculum spend every stage's whole budget (the default cap of a walk).

    A curriculum stops at ``train.iterations``; without ``train.iterations=`` on the command line
    the cap is this, so ``curriculum=true`` walks to ``last_stage`` even if no stage is promoted
    early (e.g. 7 stages × ceil(3M / 16,384) = 1,288 iterations with the defaults and stage1..stage7).
    """
    cfg = train.curriculum
    per_stage = math.ceil(cfg.stage_steps / (train.num_envs * train.steps_per_env))
    return len(cfg.stages()) * per_stage


def _stage_number(task: str | None) -> int | None:
    """``3`` for the numbered stage ``stage3`` of the tasks folder; None for anything else (a YAML path)."""
    if task is None or not task.startswith("stage") or not task[5:].isdigit():
        return None
    return int(task[5:]) if int(task[5:]) in stage_numbers() else None


def shipped_checkpoint(stage: int) -> Path | None:
    """The weights-only checkpoint of stage ``stage``'s shipped policy (checked), or None where none is shipped.

    Raises:
        mjnav.shipped.ShippedError: The file is missing or its checksum does not match.
    """
    entry = shipped.stage_policy(f"stage{stage}") if stage in stage_numbers() else None
    return entry.weights_path() if entry is not None and entry.weights else None


def _previous(stage: int) -> int:
    """The numbered stage before ``stage`` (0 for the first)."""
    return max((n for n in stage_numbers() if n < stage), default=0)


def resolve_start(args: RunArgs) -> str:
    """How a new run begins: ``init`` (init= given), ``curriculum`` (curriculum=true or a walk to
    stage K), ``shipped`` (the previous stage's shipped checkpoint) or ``scratch``.

    Raises:
        ConfigError: ``start=`` combined with init=/curriculum=true, asked of a task that is not a
            bundled stage >= 2, or ``start=shipped`` without the shipped file.
    """
    explicit = args.start != "auto"
    if args.init is not None or args.curriculum:
        if explicit:
            raise ConfigError("start: cannot be combined with init= or curriculum=true")
        return "init" if args.init is not None else "curriculum"
    stage = _stage_number(args.task)
    if explicit and args.start != "scratch" and (stage is None or _previous(stage) == 0):
        raise ConfigError(f"start={args.start}: needs a numbered stage after stage1 (stage2, ...), got {args.task!r}")
    previous = _previous(stage) if stage is not None else 0
    if args.start == "shipped" and shipped_checkpoint(previous) is None:
        raise ConfigError(f"start=shipped: no shipped stage{previous} policy with weights (policies/manifest.yaml)")
    if args.start in ("auto", "shipped") and stage is not None and _previous(stage) > 0:
        found = shipped_checkpoint(_previous(stage))
        if found is not None and not _same_design(found, args):
            if explicit:
                raise ConfigError(f"start=shipped: {found} was trained with another task.design (its network "
                                  "does not fit); use start=curriculum or start=scratch")
            return "curriculum"
    if explicit:
        return args.start
    if stage is None or _previous(stage) == 0:
        return "scratch"
    return "shipped" if shipped_checkpoint(_previous(stage)) else "curriculum"


def _same_design(checkpoint: Path, args: RunArgs) -> bool:
    """The shipped checkpoint's design (observation and action sizes) is the one requested."""
    trained = stages.load_stage(args.task, list(training_overrides(checkpoint)))  # type: ignore[arg-type]
    overrides = [*training_overrides(checkpoint), *args.task_overrides]
    wanted = stages.load_stage(args.task, overrides)  # type: ignore[arg-type]
    return trained.design == wanted.design


def plan_run(args: RunArgs) -> RunPlan:
    """Resolve configs, run folder and checkpoint of a fresh or resumed run (creates nothing)."""
    if args.resume is not None:
        if args.start != "auto" or args.recipe is not None:
            raise ConfigError("start: cannot be combined with resume=" if args.recipe is None else
                              "recipe: cannot be combined with resume=")
        return _plan_resume(args)
    if args.recipe is not None:
        return _plan_recipe(args)
    if args.task is None and not args.curriculum:
        raise ConfigError("task: required (task=stage6), unless resume=RUN_DIR or curriculum=true")
    start = resolve_start(args)
    train = load_train(list(args.train_overrides))
    overrides = list(args.task_overrides)
    given_iterations = any(o.startswith("iterations=") for o in args.train_overrides)
    init = _check_init(Path(args.init)) if args.init else None
    state = None
    if start == "curriculum":
        if not args.curriculum:  # a walk up to the requested stage
            last = _stage_number(args.task)
            train = apply_overrides(train, [f"curriculum.first_stage={stage_numbers()[0]}",
                                            f"curriculum.last_stage={last}"])
        if not given_iterations:
            train = apply_overrides(train, [f"iterations={curriculum_iterations(train)}"])
        state = CurriculumState(stage=train.curriculum.stages()[0])
        task, label = stages.load_stage(stage_name(state.stage), overrides), "curriculum"
    else:
        if start == "shipped":
            entry = shipped.stage_policy(stage_name(_previous(_stage_number(args.task))))  # type: ignore[arg-type]
            recipe = shipped.load_recipe(entry.recipe)  # type: ignore[union-attr]
            init = _check_init(entry.weights_path())  # type: ignore[union-attr]
            overrides = [*recipe.task_overrides, *overrides]
            train = load_train([*recipe.train_overrides(), *args.train_overrides])
        task = stages.load_stage(args.task, overrides)  # type: ignore[arg-type]
        label = task.name
    run_dir = Path(args.out) / f"{label}-{unique_stamp()}"
    return RunPlan(run_dir, task, train, overrides, state, init=init, start=start)


def _plan_recipe(args: RunArgs) -> RunPlan:
    """A retrain of a shipped policy from its recipe (``recipe=NAME``); the command's task./train. overrides win.

    Raises:
        ConfigError: Unknown recipe, or combined with task=/init=/curriculum=true/start=.
    """
    if args.init is not None or args.curriculum or args.start != "auto" or args.task is not None:
        raise ConfigError("recipe: sets the task and the start; cannot be combined with task=, init=, "
                          "curriculum=true or start=")
    try:
        recipe = shipped.load_recipe(args.recipe)  # type: ignore[arg-type]
        init = _check_init(shipped.get(recipe.start).weights_path()) if recipe.start else None
    except shipped.ShippedError as err:
        raise ConfigError(f"recipe: {err}") from None
    overrides = [*recipe.task_overrides, *args.task_overrides]
    train = load_train([*recipe.train_overrides(), *args.train_overrides])
    task = stages.load_stage(recipe.task, overrides)
    run_dir = Path(args.out) / f"{task.name}-{unique_stamp()}"
    return RunPlan(run_dir, task, train, overrides, init=init, start="recipe")


def _check_init(path: Path) -> Path:
    """``init=``: an rsl-rl checkpoint with actor and critic weights (checked before anything starts)."""
    path = shipped.resolve(path) or path  # a shipped NAME.weights
    if not path.is_file():
        raise ConfigError(f"init: no such checkpoint file {str(path)!r} (expected runs/<run>/model_<it>.pt, "
                          "runs/<run>/checkpoint_weights.pt or a shipped NAME.weights)")
    try:
        state = torch.load(str(path), map_location="cpu", weights_only=False)
    except Exception as err:  # any unreadable file is the same user error
        raise ConfigError(f"init: {str(path)!r} is not an rsl-rl checkpoint ({type(err).__name__})") from err
    keys = state.keys() if isinstance(state, dict) else ()
    missing = [k for k in ("actor_state_dict", "critic_state_dict") if k not in keys]
    if missing:
        raise ConfigError(
            f"init: {str(path)!r} has no {' or '.join(missing)}; init= takes a model_<it>.pt checkpoint "
            "(an exported policy.pt has no critic)"
        )
    return path


def _plan_resume(args: RunArgs) -> RunPlan:
    if args.init is not None:
        raise ConfigError("init: cannot be combined with resume")
    run_dir = Path(args.resume)  # type: ignore[arg-type]
    if not (run_dir / "config.yaml").is_file():
        raise ConfigError(f"resume: {str(run_dir)!r} is not a run folder (no config.yaml)")
    if (pid := holder(run_dir)) is not None:  # every torchrun rank refuses, not rank 0 alone in _writing
        raise _in_use(run_dir, pid)
    saved = yaml.safe_load((run_dir / "config.yaml").read_text())
    train = load_train(list(args.train_overrides), base=from_dict(TrainConfig, saved["train"]))
    overrides = list(saved["run"]["task_overrides"]) + list(args.task_overrides)
    found = checkpoints(run_dir)
    if not found:
        raise ConfigError(f"resume: no model_<it>.pt checkpoint in {run_dir}")
    if saved["run"]["curriculum"]:
        state = CurriculumState.load(run_dir)
        return RunPlan(
            run_dir, stages.load_stage(stage_name(state.stage), overrides), train, overrides, state, found[-1]
        )
    task = _task_from_dict(saved["task"], list(args.task_overrides))
    return RunPlan(run_dir, task, train, overrides, None, found[-1])


def check_device(device: str) -> None:
    """Fail early, before any worker starts, when this torch build cannot use ``device``.

    Raises:
        ConfigError: CUDA/MPS not available in this torch build, or no such CUDA device index.
    """
    kind, _, index = device.partition(":")
    if kind == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0:
            raise ConfigError(
                f"train.device={device}: this torch ({torch.__version__}) sees no CUDA device; "
                "install a CUDA build (make train TORCH=torch) or use train.device=cpu"
            )
        if index and int(index) >= count:
            raise ConfigError(f"train.device={device}: only {count} CUDA device(s) (cuda:0..cuda:{count - 1})")
    if kind == "mps" and not torch.backends.mps.is_available():
        raise ConfigError(f"train.device={device}: MPS is not available on this machine; use train.device=cpu")


def _write_config(plan: RunPlan, argv: Sequence[str]) -> None:
    """Write ``config.yaml``; a resume keeps the run's first ``init`` and ``argv`` and lists its own.

    ``run.ranks`` holds the number of processes (``torchrun`` ranks) of each launch, the first and
    then each resume (None for a launch recorded before this field).
    """
    plan.run_dir.mkdir(parents=True, exist_ok=True)
    path = plan.run_dir / "config.yaml"
    ranks = distributed.current().world_size
    first = {"init": str(plan.init) if plan.init else None, "argv": list(argv), "resumes": [], "ranks": [ranks]}
    if plan.checkpoint is not None and path.is_file():
        saved = yaml.safe_load(path.read_text())["run"]
        resumes = saved.get("resumes", [])
        first = {"init": saved.get("init"), "argv": saved.get("argv", []), "resumes": [*resumes, list(argv)],
                 "ranks": [*saved.get("ranks", [None] * (1 + len(resumes))), ranks]}
    record = {
        "run": {
            "task": plan.task.name,
            "task_overrides": plan.task_overrides,
            "curriculum": plan.curriculum is not None,
            **first,
        },
        "task": to_dict(plan.task),
        "train": to_dict(plan.train),
    }
    write_atomic(path, yaml.safe_dump(record, sort_keys=False))  # a kill while writing leaves the old file whole


def run(argv: Sequence[str], make_env: Callable[..., Any] = make_vec_env) -> Path:
    """Run a training session; returns the run folder.

    Args:
        argv: ``key=value`` arguments.
        make_env: ``make_env(task, train, seed=None, num_envs=None)`` building the adapter.

    Under torchrun every rank runs this on one process group (:mod:`mjnav.train.distributed`):
    rank 0 names the run folder and alone writes into it; each rank trains on its own device.
    """
    plan = plan_run(parse_args(argv))
    check_device(distributed.rank_device(plan.train.device, distributed.ranks_from_env()))
    with distributed.process_group(plan.train.device) as ranks:
        plan.run_dir = distributed.share(plan.run_dir)
        with _writing(plan.run_dir) if ranks.main else contextlib.nullcontext():
            if ranks.main:
                _write_config(plan, argv)
            plan.train = dataclasses.replace(plan.train, device=distributed.rank_device(plan.train.device, ranks))
            return _run_rank(plan, make_env, ranks.main)


@contextlib.contextmanager
def _writing(run_dir: Path) -> Iterator[None]:
    """Hold the run folder's lock (:func:`mjnav.jobs.holding`) while training into it.

    Raises:
        ConfigError: Another live process holds it (a ``resume=`` of a run that is still training).
    """
    run_dir.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as held:
        try:
            held.enter_context(holding(run_dir))
        except FolderInUse as err:  # only the taking of the lock: the training's own errors pass as they are
            raise _in_use(run_dir, err.pid) from None
        yield


def _in_use(run_dir: Path, pid: str) -> ConfigError:
    """The error for a ``resume=`` of a run that another live process (``pid``) is training."""
    return ConfigError(f"resume: {run_dir} is being trained by another process (pid {pid}); "
                       "wait for it to end or stop it first")


def _run_rank(plan: RunPlan, make_env: Callable[..., Any], main: bool) -> Path:
    """Train ``plan`` in this process (one rank under torchrun; ``main``: rank 0, which writes)."""
    train = plan.train
    env = make_env(plan.task, train)
    runner = None
    try:
        runner = build_runner(
            env, train, plan.run_dir if main else None,
            label=plan.task.name if plan.curriculum is None else "curriculum",
        )
        critic_loaded = True
        if plan.checkpoint is not None:
            load_checkpoint(runner, plan.checkpoint)
        elif plan.init is not None:
            critic_loaded = load_checkpoint(runner, plan.init, weights_only=True)
        if main:
            _print_header(plan, env, runner.current_learning_iteration)
        if not critic_loaded and main:
            print(f"critic: not taken from {plan.init} (its inputs differ); a new critic starts, "
                  f"train.critic_warmup={train.critic_warmup} updates with the actor frozen", flush=True)
        if not _train(runner, plan, make_env) or not main:
            return plan.run_dir
        for path in (*export_actor(runner.alg.get_policy(), plan.run_dir), save_weights(runner, plan.run_dir)):
            print(f"exported {path}")
    finally:
        for vec_env in {id(env): env, id(getattr(runner, "env", env)): getattr(runner, "env", env)}.values():
            vec_env.close()
    return plan.run_dir


def _train(runner: Any, plan: RunPlan, make_env: Callable[..., Any]) -> bool:
    """Train to the end (True) or until interrupted, saving a checkpoint first (False).

    Raises:
        EnvError: An environment or its worker failed; the weights of the last completed iteration
            were saved first (when one was completed), so ``resume=`` goes on from there. Under
            torchrun the failing rank saves them; the other ranks then fail in their next all-reduce.
    """
    train = plan.train
    with handle_interrupts():
        try:
            if plan.curriculum is not None:
                plan.curriculum.save(plan.run_dir)
                run_curriculum(runner, train, plan.task_overrides, plan.curriculum, plan.run_dir, make_env)
            elif runner.current_learning_iteration < train.iterations:
                learn(
                    runner, train.iterations - runner.current_learning_iteration, train.random_initial_lengths
                )
        except TrainingInterrupted:
            path = save_checkpoint(runner, plan.run_dir)
            if distributed.current().main:
                print(f"saved {path}\ncontinue with: {resume_command(plan.run_dir, distributed.current())}",
                      flush=True)
            return False
        except EnvError:  # the weights of the iterations done since the last checkpoint are kept
            if runner.current_learning_iteration > 0:  # by this rank: the others do not know of it
                path = save_checkpoint(runner, plan.run_dir, this_rank=True)
                print(f"an environment failed (below); saved {path}, the last completed iteration\n"
                      f"continue with: {resume_command(plan.run_dir, distributed.current())}",
                      file=sys.stderr, flush=True)
            raise
    return True


def resume_command(run_dir: Path, ranks: distributed.Ranks | None = None) -> str:
    """The shell command that continues ``run_dir``: this interpreter's absolute path, so it works
    without activating the virtual environment; with several ``ranks``, under torchrun with as many
    processes per node (other nodes add their own rendezvous arguments)."""
    launch = [sys.executable, "-m", "mjnav", "train", f"resume={run_dir}"]
    if ranks is not None and ranks.distributed:
        nodes = ranks.world_size // ranks.local_world_size
        launch[1:2] = ["-m", "torch.distributed.run", f"--nproc_per_node={ranks.local_world_size}",
                       *([f"--nnodes={nodes}"] if nodes > 1 else ["--standalone"]), "-m"]
    return shlex.join(launch)


def _start_line(plan: RunPlan) -> str:
    """First line of a run: where its weights come from and what it will train."""
    t = plan.train
    if plan.checkpoint is not None:
        return f"start: resuming {plan.run_dir} from {plan.checkpoint}"
    if plan.curriculum is not None:
        c, walk = t.curriculum, t.curriculum.stages()
        return (f"start: curriculum stage{walk[0]} -> stage{walk[-1]} from random weights (promotion at "
                f"{c.threshold:.0%} deterministic success or {c.stage_steps:,} env steps per stage; "
                f"at most {t.iterations} iterations); start=shipped|scratch to change")
    steps = t.iterations * t.num_envs * t.steps_per_env * distributed.current().world_size  # all ranks
    if plan.start == "recipe":
        return (f"start: the recipe of a shipped policy, {plan.init or 'random weights'} (task overrides "
                f"{plan.task_overrides or 'none'}), {plan.task.name} for {t.iterations} iterations = "
                f"{steps:,} env steps")
    if plan.start == "shipped":
        return (f"start: the shipped policy {plan.init} (task overrides {plan.task_overrides or 'none'}), "
                f"{plan.task.name} for {t.iterations} iterations = {steps:,} env steps; "
                "start=curriculum|scratch to change")
    if plan.init is not None:
        return f"start: weights of {plan.init}, {plan.task.name} for {steps:,} env steps"
    return f"start: random weights, {plan.task.name} for {steps:,} env steps"


def _print_header(plan: RunPlan, env: Any, start: int) -> None:
    t, ranks = plan.train, distributed.current()
    batch = t.num_envs * t.steps_per_env
    per_rank = f"{ranks.world_size} ranks x " if ranks.distributed else ""
    print(_start_line(plan), flush=True)
    print(
        f"run {plan.run_dir} | task {plan.task.name} | {per_rank}{t.num_envs} envs x {t.steps_per_env} steps = "
        f"{batch * ranks.world_size} "
        f"transitions/iteration | {t.epochs} epochs x {t.minibatches} minibatches of "
        f"{batch // t.minibatches} | "
        f"workers {env.workers} | device {t.device} | iterations {start}->{t.iterations}"
        + (f" | critic: +{env.critic_dim} privileged inputs" if getattr(env, "critic_dim", 0) else ""),
        flush=True,
    )
