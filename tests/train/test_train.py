"""PPO training with rsl-rl on a fake navigation env (no MuJoCo): runner, resume, export, CLI."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from rsl_rl.algorithms import PPO
from rsl_rl.runners import OnPolicyRunner

from mjnav.config import load_task
from mjnav.envs.vec_env import EnvError, NavVecEnv
from mjnav.schema import ConfigError
from mjnav.train import curriculum, session
from mjnav.train.config import TrainConfig, load_train
from mjnav.train.evaluate import evaluate
from mjnav.train.export import export_actor, export_checkpoint
from mjnav.train.runner import (
    TrainingInterrupted,
    build_runner,
    checkpoints,
    handle_interrupts,
    learn,
    load_checkpoint,
    make_vec_env,
    request_stop,
    rsl_config,
    save_checkpoint,
)
from tests.train._dying import kill_a_worker_at

OBS_DIM, ACT_DIM = 399, 4
TINY = [
    "num_envs=4",
    "workers=0",
    "steps_per_env=8",
    "epochs=1",
    "minibatches=2",
    "save_interval=1",
    "policy.actor_hidden_dims=[32, 32, 32]",
    "policy.critic_hidden_dims=[32, 32, 32]",
]


class FakeNavEnv(gym.Env):
    """A point pushed toward the origin: success within 0.4, collision outside [-3, 3]², 12-step limit."""

    def __init__(self) -> None:
        """Spaces as the real env."""
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (OBS_DIM,), np.float32)
        self.action_space = gym.spaces.Box(-np.inf, np.inf, (ACT_DIM,), np.float32)
        self._pos, self._t = np.zeros(2), 0

    def _obs(self) -> np.ndarray:
        obs = np.zeros(OBS_DIM, np.float32)
        obs[:2], obs[2] = self._pos / 3.0, self._t / 12
        return obs

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start anywhere in [-2, 2]²."""
        super().reset(seed=seed)
        self._pos, self._t = self.np_random.uniform(-2.0, 2.0, 2), 0
        return self._obs(), {"outcome": "running"}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Move by the squashed action."""
        before = np.linalg.norm(self._pos)
        self._pos = self._pos + 0.8 * (1.0 / (1.0 + np.exp(-action[:2])) - 0.5)
        self._t += 1
        dist = np.linalg.norm(self._pos)
        outcome = "success" if dist < 0.4 else "collision" if np.abs(self._pos).max() > 3 else "running"
        truncated = outcome == "running" and self._t >= 12
        terms = {"approach": float(before - dist), "success": 5.0 * (outcome == "success")}
        info = {
            "outcome": "timeout" if truncated else outcome,
            "reward_terms": terms,
            "mpc": {"fallback": 0.0},
        }
        return self._obs(), sum(terms.values()), outcome != "running", truncated, info


def fake_env_fn(index: int) -> FakeNavEnv:
    """Picklable factory of the fake env."""
    return FakeNavEnv()


def make_fake_env(
    task: object, train: TrainConfig, seed: int | None = None, num_envs: int | None = None
) -> NavVecEnv:
    """Drop-in for :func:`mjnav.train.runner.make_vec_env` building fake envs in-process."""
    return NavVecEnv(
        fake_env_fn,
        num_envs or train.num_envs,
        seed=train.seed if seed is None else seed,
        workers=0,
        max_episode_length=12,
    )


@dataclasses.dataclass(frozen=True)
class StubTask:
    """Stands in for TaskConfig in session tests."""

    name: str = "fake"


@pytest.fixture()
def tiny() -> TrainConfig:
    """A train config small enough for a unit test."""
    return load_train(TINY)


def _trained(tiny: TrainConfig, log_dir: Path, iterations: int = 2) -> OnPolicyRunner:
    env = make_fake_env(None, tiny)
    runner = build_runner(env, tiny, log_dir, label="fake")
    learn(runner, iterations)
    return runner


def test_two_iterations_write_checkpoints_and_events(tiny: TrainConfig, tmp_path: Path) -> None:
    """Two PPO iterations save model_0/model_1 and TensorBoard events with the adapter's log keys."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    runner = _trained(tiny, tmp_path)
    runner.env.close()
    assert [p.name for p in checkpoints(tmp_path)] == ["model_0.pt", "model_1.pt"]
    assert runner.current_learning_iteration == 2
    events = EventAccumulator(str(tmp_path)).Reload()
    tags = set(events.Tags()["scalars"])
    assert {
        "Loss/value",
        "Perf/collection_time",
        "reward/approach",
        "mpc/fallback",
        "perf/env_step_ms",
        "perf/own_block_ms",
        "perf/wait_ms",
    } <= tags
    assert "episode/success" in tags and not any(t.startswith("Episode/") for t in tags)


def test_update_runs_with_update_threads_and_collection_with_torch_threads(
    tiny: TrainConfig, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each PPO update runs with train.update_threads; collection gets torch_threads back."""
    seen: list[int] = []
    original = PPO.update

    def spy(self, *args, **kwargs):
        seen.append(torch.get_num_threads())
        return original(self, *args, **kwargs)

    monkeypatch.setattr(PPO, "update", spy)
    before = torch.get_num_threads()
    try:
        train = dataclasses.replace(tiny, torch_threads=1, update_threads=2)
        runner = build_runner(make_fake_env(None, train), train, tmp_path)
        learn(runner, 2)
        runner.env.close()
        assert seen == [2, 2]
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)


def test_critic_warmup_freezes_the_actor_for_its_iterations(tiny: TrainConfig, tmp_path: Path) -> None:
    """train.critic_warmup=2: iterations 0 and 1 move only the critic, iteration 2 the actor too."""
    train = dataclasses.replace(tiny, critic_warmup=2)
    runner = build_runner(make_fake_env(None, train), train, None)

    def weights(name: str) -> list[torch.Tensor]:
        return [p.detach().clone() for p in getattr(runner.alg, name).parameters()]

    actor, critic = weights("actor"), weights("critic")
    learn(runner, 2)
    assert all(torch.equal(a, b) for a, b in zip(actor, weights("actor"), strict=True))
    assert not all(torch.equal(a, b) for a, b in zip(critic, weights("critic"), strict=True))
    assert all(p.requires_grad for p in runner.alg.actor.parameters())
    learn(runner, 1)
    runner.env.close()
    assert not all(torch.equal(a, b) for a, b in zip(actor, weights("actor"), strict=True))
    with pytest.raises(ConfigError, match="critic_warmup"):
        load_train(["critic_warmup=-1"])


def test_resume_continues_iteration_count(tiny: TrainConfig, tmp_path: Path) -> None:
    """Loading the latest checkpoint continues at the next iteration and restores the weights."""
    first = _trained(tiny, tmp_path)
    first.env.close()
    weights = first.alg.get_policy().state_dict()
    env = make_fake_env(None, tiny)
    runner = build_runner(env, dataclasses.replace(tiny, seed=99), tmp_path)
    load_checkpoint(runner, checkpoints(tmp_path)[-1])
    assert runner.current_learning_iteration == 2
    assert all(torch.equal(v, runner.alg.get_policy().state_dict()[k]) for k, v in weights.items())
    learn(runner, 2)
    env.close()
    assert [p.name for p in checkpoints(tmp_path)][-2:] == ["model_2.pt", "model_3.pt"]
    assert torch.load(tmp_path / "model_3.pt", weights_only=False)["iter"] == 3


def test_init_loads_weights_only(tiny: TrainConfig, tmp_path: Path) -> None:
    """init= copies actor and critic weights into a fresh run that starts at iteration 0."""
    first = _trained(tiny, tmp_path, iterations=1)
    first.env.close()
    env = make_fake_env(None, tiny)
    runner = build_runner(env, dataclasses.replace(tiny, seed=5), None)
    env.close()
    load_checkpoint(runner, checkpoints(tmp_path)[-1], weights_only=True)
    assert runner.current_learning_iteration == 0
    for name in ("actor", "critic"):
        ours, theirs = getattr(runner.alg, name).state_dict(), getattr(first.alg, name).state_dict()
        assert all(torch.equal(v, ours[k]) for k, v in theirs.items())
    assert not runner.alg.optimizer.state_dict()["state"], "optimizer state starts fresh"


class PrivilegedFakeNavEnv(FakeNavEnv):
    """The fake env with a 2-value privileged critic input (its true position)."""

    critic_size = 2

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """As the fake env, plus ``info['critic']``."""
        obs, info = super().reset(seed=seed, options=options)
        return obs, {**info, "critic": self._pos.astype(np.float32)}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """As the fake env, plus ``info['critic']``."""
        *out, info = super().step(action)
        return (*out, {**info, "critic": self._pos.astype(np.float32)})


def privileged_env_fn(index: int) -> PrivilegedFakeNavEnv:
    """Picklable factory of the privileged fake env."""
    return PrivilegedFakeNavEnv()


def test_privileged_critic_reads_more_than_the_actor(tiny: TrainConfig, tmp_path: Path) -> None:
    """With a critic group the critic reads 399 + 2 values, the actor 399; init= from a plain
    checkpoint takes the actor and reports that the critic was not taken."""
    plain = _trained(tiny, tmp_path, iterations=1)
    plain.env.close()
    env = NavVecEnv(privileged_env_fn, 4, seed=0, workers=0, max_episode_length=12)
    runner = build_runner(env, dataclasses.replace(tiny, seed=5), None)
    assert runner.alg.critic.mlp[0].in_features == OBS_DIM + 2
    assert runner.alg.actor.mlp[0].in_features == OBS_DIM
    assert load_checkpoint(runner, checkpoints(tmp_path)[-1], weights_only=True) is False
    ours, theirs = runner.alg.actor.state_dict(), plain.alg.actor.state_dict()
    assert all(torch.equal(v, ours[k]) for k, v in theirs.items())
    learn(runner, 1)
    env.close()
    assert export_actor(runner.alg.get_policy(), tmp_path / "out")  # the exported actor needs no critic input


def test_stop_request_saves_after_the_iteration(tiny: TrainConfig, tmp_path: Path) -> None:
    """A stop request (as SIGTERM sends) ends learn after one iteration; the checkpoint resumes at 1."""
    env = make_fake_env(None, tiny)
    runner = build_runner(env, tiny, tmp_path / "log")
    with handle_interrupts():
        request_stop()
        with pytest.raises(TrainingInterrupted):
            learn(runner, 5)
    env.close()
    assert runner.current_learning_iteration == 1
    path = save_checkpoint(runner, tmp_path)
    assert path.name == "model_0.pt" and torch.load(path, weights_only=False)["iter"] == 0


def test_actor_and_critic_match_the_paper(tmp_path: Path) -> None:
    """Default networks and PPO values: paper's actor/critic, log-std -0.5, AdamW, γ=λ=0.98, tuned entropy."""
    train = load_train(["num_envs=2", "workers=0", "steps_per_env=4", "minibatches=1"])
    env = make_fake_env(None, train)
    runner = build_runner(env, train, None)
    env.close()
    actor, critic = runner.alg.get_policy(), runner.alg.critic
    layers = [type(m).__name__ for m in actor.mlp]
    assert layers == ["Linear", "ReLU", "Linear", "ReLU", "Linear", "Hardswish", "Linear"]
    assert actor.mlp[0].in_features == OBS_DIM and actor.mlp[6].out_features == ACT_DIM
    assert torch.allclose(actor.distribution.log_std_param, torch.full((ACT_DIM,), -0.5))
    assert [m.out_features for m in critic.mlp if isinstance(m, torch.nn.Linear)] == [320, 320, 320, 1]
    assert isinstance(runner.alg.optimizer, torch.optim.AdamW) and runner.alg.learning_rate == 1e-4
    assert runner.alg.gamma == 0.98 and runner.alg.lam == 0.98 and runner.alg.entropy_coef == 0.005
    assert runner.alg.schedule == "adaptive" and runner.alg.desired_kl == 0.01


def test_torchscript_export_matches_policy_mean(tiny: TrainConfig, tmp_path: Path) -> None:
    """policy.pt loads with torch.jit.load and reproduces the policy mean for (399,) and (B, 399) inputs."""
    runner = _trained(tiny, tmp_path, iterations=1)
    obs = runner.env.get_observations()
    runner.env.close()
    written = export_actor(runner.alg.get_policy(), tmp_path / "export")
    scripted = torch.jit.load(str(tmp_path / "export" / "policy.pt"))
    with torch.no_grad():
        mean = runner.get_inference_policy()(obs)
        assert torch.allclose(scripted(obs["policy"]), mean, atol=1e-6)
        assert scripted(obs["policy"][0]).shape == (ACT_DIM,)
    from_checkpoint = export_checkpoint(checkpoints(tmp_path)[-1], tiny, tmp_path / "ckpt")
    assert torch.allclose(torch.jit.load(str(from_checkpoint[0]))(obs["policy"]), mean, atol=1e-6)
    if any(p.suffix == ".onnx" for p in written):
        assert (tmp_path / "export" / "policy.onnx").stat().st_size > 0


def test_evaluate_counts_the_requested_episodes(tiny: TrainConfig) -> None:
    """Deterministic evaluation counts exactly the requested episodes; outcome rates sum to 1."""
    env = make_fake_env(None, tiny)
    result = evaluate(lambda obs: torch.zeros(obs.batch_size[0], ACT_DIM), env, episodes=10)
    env.close()
    assert result.episodes == 10
    assert math.isclose(result.success + result.collision + result.timeout, 1.0)


def test_override_rejection() -> None:
    """Unknown top-level, train and task keys are rejected with the key's name; bad values too."""
    with pytest.raises(ConfigError, match="bogus"):
        session.parse_args(["bogus=1"])
    with pytest.raises(ConfigError, match="num_env"):
        load_train(["num_env=4"])
    with pytest.raises(ConfigError, match="minibatches"):
        load_train(["num_envs=3", "steps_per_env=3", "minibatches=4"])
    with pytest.raises(ConfigError, match="update_threads"):
        load_train(["update_threads=-1"])
    with pytest.raises(ConfigError, match="curriculum"):
        session.parse_args(["curriculum=maybe"])
    args = session.parse_args(["task=stage6", "task.crowd.count=25", "train.num_envs=8", "seed=3"])
    assert args.task_overrides == ("crowd.count=25",) and args.train_overrides == ("num_envs=8", "seed=3")
    with pytest.raises(ConfigError, match="policy.widths"):
        session.plan_run(session.parse_args(["task=stage6", "train.policy.widths=1"]))


def test_bad_or_unavailable_device_is_a_config_error(tmp_path: Path) -> None:
    """A misspelt device fails in the config; an unavailable one before any worker starts."""
    with pytest.raises(ConfigError, match="device"):
        load_train(["device=gpu"])
    assert load_train(["device=cuda:1"]).device == "cuda:1"
    session.check_device("cpu")
    if not torch.cuda.is_available():
        with pytest.raises(ConfigError, match="no CUDA device"):
            session.run(["task=stage1", "train.device=cuda", f"out={tmp_path}"], make_env=_never_called)
        assert not any(tmp_path.iterdir())  # nothing written, no environment built


def _never_called(*args, **kwargs):
    raise AssertionError("the environment must not be built")


def test_bad_resume_or_init_fails_before_anything_starts(tmp_path: Path) -> None:
    """resume= of a non-run folder and init= of a missing, foreign or actor-only file are ConfigErrors."""
    with pytest.raises(ConfigError, match="not a run folder"):
        session.plan_run(session.parse_args([f"resume={tmp_path}"]))
    with pytest.raises(ConfigError, match="no such checkpoint"):
        session.plan_run(session.parse_args(["task=stage1", f"init={tmp_path / 'model_9.pt'}"]))
    text = tmp_path / "notes.txt"
    text.write_text("# not a checkpoint")
    with pytest.raises(ConfigError, match="not an rsl-rl checkpoint"):
        session.plan_run(session.parse_args(["task=stage1", f"init={text}"]))
    actor_only = tmp_path / "model_1.pt"
    torch.save({"actor_state_dict": {}}, actor_only)
    with pytest.raises(ConfigError, match="critic_state_dict"):
        session.plan_run(session.parse_args(["task=stage1", f"init={actor_only}"]))
    both = tmp_path / "model_2.pt"
    torch.save({"actor_state_dict": {}, "critic_state_dict": {}}, both)
    assert session.plan_run(session.parse_args(["task=stage1", f"init={both}"])).init == both


def test_curriculum_cap_defaults_to_every_stage_budget() -> None:
    """curriculum=true without train.iterations runs long enough to spend all seven budgets."""
    plan = session.plan_run(session.parse_args(["curriculum=true"]))
    assert plan.train.iterations == 7 * math.ceil(3_000_000 / 16384) == 1288
    two = ["curriculum=true", "train.curriculum.first_stage=6", "train.curriculum.stage_steps=16385"]
    assert session.plan_run(session.parse_args(two)).train.iterations == 2 * 2
    assert session.plan_run(session.parse_args([*two, "train.iterations=3"])).train.iterations == 3
    assert session.plan_run(session.parse_args(["task=stage1"])).train.iterations == 1000


def test_session_fresh_resume_and_curriculum(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The scripts/train.py session: a fresh run, its resume and a two-stage curriculum export policy.pt."""
    monkeypatch.setattr(curriculum, "load_stage", lambda name, overrides: StubTask(name))
    monkeypatch.setattr(session, "_task_from_dict", lambda data, overrides: StubTask(data["name"]))
    tiny = [f"train.{o}" for o in TINY]
    run_dir = session.run(
        ["task=fake", "train.iterations=2", f"out={tmp_path}", *tiny], make_env=make_fake_env
    )
    assert run_dir.name.startswith("fake-") and (run_dir / "policy.pt").exists()
    saved = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert saved["train"]["num_envs"] == 4 and saved["task"] == {"name": "fake"}
    session.run([f"resume={run_dir}", "train.iterations=3"], make_env=make_fake_env)
    run = yaml.safe_load((run_dir / "config.yaml").read_text())["run"]
    assert run["argv"][0] == "task=fake" and run["resumes"] == [[f"resume={run_dir}", "train.iterations=3"]]
    assert checkpoints(run_dir)[-1].name == "model_2.pt"
    plan = [
        "curriculum=true",
        "train.curriculum.first_stage=6",
        "train.curriculum.eval_interval=1",
        "train.curriculum.eval_episodes=4",
        "train.curriculum.stage_steps=1",
        f"out={tmp_path}",
    ]
    run_dir = session.run([*plan, *tiny], make_env=make_fake_env)
    state = curriculum.CurriculumState.load(run_dir)
    assert state.finished and [e["stage"] for e in state.evaluations] == [6, 7]
    assert [e["decision"] for e in state.evaluations] == ["budget", "budget"] or state.evaluations[0][
        "success"
    ] >= 0.9
    assert (run_dir / "policy.pt").exists()


def _stub_tasks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(curriculum, "load_stage", lambda name, overrides: StubTask(name))
    monkeypatch.setattr(session, "_task_from_dict", lambda data, overrides: StubTask(data["name"]))


def _dying_worker_env(after_steps: int):
    """A ``make_env`` whose adapter has one worker process, SIGKILLed at step ``after_steps``."""
    def make(task: object, train: TrainConfig, seed: int | None = None, num_envs: int | None = None) -> NavVecEnv:
        env = NavVecEnv(fake_env_fn, train.num_envs, seed=train.seed, workers=2, max_episode_length=12)
        return kill_a_worker_at(env, after_steps)
    return make


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_a_dead_worker_ends_training_with_the_last_iteration_saved(tmp_path, monkeypatch, capsys) -> None:
    """A worker killed in iteration 3 (0-based) ends the run with EnvError, after saving the weights of
    iteration 2 (not only the periodic checkpoint of iteration 0); resume goes on from there."""
    _stub_tasks(monkeypatch)
    argv = ["task=fake", "train.iterations=6", f"out={tmp_path}", *(f"train.{o}" for o in TINY),
            "train.save_interval=50"]
    with pytest.raises(EnvError, match=r"worker 1 .*died \(exit code -9\)"):
        session.run(argv, make_env=_dying_worker_env(after_steps=3 * 8 + 2))
    (run_dir,) = tmp_path.iterdir()
    assert [p.name for p in checkpoints(run_dir)] == ["model_0.pt", "model_2.pt"]
    assert torch.load(run_dir / "model_2.pt", weights_only=False)["iter"] == 2
    assert f"saved {run_dir / 'model_2.pt'}" in capsys.readouterr().err
    session.run([f"resume={run_dir}"], make_env=make_fake_env)
    assert checkpoints(run_dir)[-1].name == "model_5.pt" and (run_dir / "policy.pt").exists()


def test_a_worker_dead_before_the_first_update_saves_nothing(tmp_path, monkeypatch) -> None:
    _stub_tasks(monkeypatch)
    argv = ["task=fake", "train.iterations=6", f"out={tmp_path}", *(f"train.{o}" for o in TINY)]
    with pytest.raises(EnvError):
        session.run(argv, make_env=_dying_worker_env(after_steps=3))
    (run_dir,) = tmp_path.iterdir()
    assert checkpoints(run_dir) == []


def test_main_command_starts_from_the_shipped_previous_stage_or_walks_the_curriculum(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``task=stage6`` alone: the shipped stage-5 policy's weights with its recipe (task overrides, PPO
    settings, budget); without it, the curriculum from stage 1 up to stage 6; the choice can be forced or refused."""
    from mjnav import shipped

    plan = session.plan_run(session.parse_args(["task=stage6", "task.crowd.count=12"]))
    assert plan.start == "shipped" and plan.init == shipped.resolve("stage5_policy.weights")
    assert plan.task.collision == "scan" and plan.task.crowd.count == 12  # the command's overrides win
    recipe = shipped.load_recipe("stage5_policy")
    assert plan.train.iterations == recipe.train["iterations"] and plan.train.schedule == "fixed"  # its recipe
    assert "shipped policy" in session._start_line(plan)
    short = session.plan_run(session.parse_args(["task=stage6", "train.iterations=7", "train.workers=1"]))
    assert short.train.iterations == 7 and short.train.workers == 1  # the recipe, then the command's
    scratch = session.plan_run(session.parse_args(["task=stage6", "start=scratch"]))
    assert scratch.init is None and scratch.task.name == "stage6" and scratch.curriculum is None
    assert session.plan_run(session.parse_args(["task=stage1"])).start == "scratch"
    with pytest.raises(ConfigError, match="start: expected one of"):
        session.parse_args(["task=stage6", "start=later"])
    with pytest.raises(ConfigError, match="cannot be combined"):
        session.plan_run(session.parse_args(["task=stage6", "start=scratch", "init=stage5_policy.weights"]))
    design = session.plan_run(session.parse_args(["task=stage6", "task.design=design1"]))
    assert design.start == "curriculum"  # the shipped network does not fit design 1's observation
    with pytest.raises(ConfigError, match="another task.design"):
        session.plan_run(session.parse_args(["task=stage6", "task.design=design1", "start=shipped"]))
    monkeypatch.setattr(shipped, "stage_policy", lambda stage: None)  # nothing shipped
    walk = session.plan_run(session.parse_args(["task=stage6"]))
    assert walk.start == "curriculum" and walk.task.name == "stage1"
    assert (walk.train.curriculum.first_stage, walk.train.curriculum.last_stage) == (1, 6)
    assert "curriculum stage1 -> stage6" in session._start_line(walk)
    with pytest.raises(ConfigError, match="start=shipped: no shipped stage6"):
        session.plan_run(session.parse_args(["task=stage7", "start=shipped"]))


def test_value_clip_is_configurable() -> None:
    """``train.value_clip`` reaches rsl-rl's PPO (on by default, as rsl-rl)."""
    assert rsl_config(TrainConfig())["algorithm"]["use_clipped_value_loss"] is True
    assert rsl_config(TrainConfig(value_clip=False))["algorithm"]["use_clipped_value_loss"] is False
    assert load_train(["value_clip=false"]).value_clip is False


def test_resumed_version_1_task_keeps_its_layouts() -> None:
    """A run saved before task version 2 resumes on its own layouts (pedestrians unconstrained)."""
    from mjnav.config import TaskConfig, load_task

    saved = dataclasses.asdict(load_task("stage7"))
    del saved["layout"]["pedestrian_clearance"]
    old = session._task_from_dict({**saved, "version": 1}, [])
    assert old.version == 1 and old.layout.pedestrian_clearance == 0.0
    new = session._task_from_dict(dataclasses.asdict(load_task("stage7")), [])
    assert new.version == TaskConfig().version == 2 and new.layout.pedestrian_clearance == 1.95


def test_main_envs_sets_the_trainer_block() -> None:
    """train.main_envs reaches the adapter: the trainer steps that many environments, the worker the rest."""
    env = make_vec_env(load_task("stage1"), load_train(["num_envs=3", "workers=2", "main_envs=1"]))
    try:
        assert env.blocks == [range(0, 1), range(1, 3)]
    finally:
        env.close()


def test_main_envs_that_leave_a_worker_nothing_is_a_config_error() -> None:
    """Checked with the other PPO settings, before a run folder is written; with workers=-1 (known
    only when the adapter is built) the adapter's refusal is a ConfigError too: one error line."""
    with pytest.raises(ConfigError, match="must leave each of the other 2 workers an environment"):
        load_train(["num_envs=4", "workers=3", "main_envs=3"])
    load_train(["num_envs=4", "workers=3", "main_envs=2"])
    with pytest.raises(ConfigError, match="main_envs must be in"):
        NavVecEnv(fake_env_fn, num_envs=4, seed=0, workers=3, main_envs=3)


def test_the_train_verb_says_a_failed_environment_in_one_error_line(monkeypatch, capsys) -> None:
    from mjnav.cli import main
    from mjnav.verbs import train as train_verb

    def fail(argv: list[str]) -> None:
        raise EnvError("worker 1 (environments 2-3) died (exit code -9)")

    monkeypatch.setattr(train_verb, "run_session", fail)
    assert main(["train", "task=stage1"]) == 1
    assert capsys.readouterr().err == "error: worker 1 (environments 2-3) died (exit code -9)\n"


def test_a_run_still_training_is_not_resumed_twice(tmp_path, monkeypatch) -> None:
    """The training process holds its run folder's lock; a ``resume=`` of that folder meanwhile is
    refused before anything starts, and goes on once the lock is free."""
    from mjnav.jobs import holding

    _stub_tasks(monkeypatch)
    run_dir = session.run(["task=fake", "train.iterations=1", f"out={tmp_path}", *(f"train.{o}" for o in TINY)],
                          make_env=make_fake_env)
    with holding(run_dir), pytest.raises(ConfigError, match=f"{run_dir} is being trained by another process"):
        session.run([f"resume={run_dir}", "train.iterations=2"], make_env=make_fake_env)
    session.run([f"resume={run_dir}", "train.iterations=2"], make_env=make_fake_env)
    assert checkpoints(run_dir)[-1].name == "model_1.pt"
    assert not [*run_dir.glob("*.partial"), *run_dir.glob(".*.tmp")]  # config.yaml, checkpoints: whole, renamed


def test_an_error_inside_the_locked_run_is_not_called_a_busy_folder(tmp_path, monkeypatch) -> None:
    _stub_tasks(monkeypatch)

    def no_fork(*args: object, **kwargs: object) -> NavVecEnv:
        raise BlockingIOError(11, "Resource temporarily unavailable")  # a fork at a process limit

    with pytest.raises(BlockingIOError, match="temporarily unavailable"):
        session.run(["task=fake", "train.iterations=1", f"out={tmp_path}", *(f"train.{o}" for o in TINY)],
                    make_env=no_fork)
