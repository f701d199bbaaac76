"""PipelinedPPO: rsl-rl's rollouts and updates bit for bit, with the actions dispatched early."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from rsl_rl.algorithms import PPO

from mjnav.envs.vec_env import NavVecEnv
from mjnav.train.config import load_train
from mjnav.train.ppo import PipelinedPPO, RolloutActor, _blocks_agree
from mjnav.train.runner import build_runner, learn
from tests.train.test_train import TINY, fake_env_fn

STORED = ("observations", "actions", "rewards", "dones", "values", "actions_log_prob", "returns", "advantages")


MODES = {"rsl-rl": ["pipeline=false"], "pipeline": ["pipeline=true", "rollouts=false"],
         "rollouts": ["pipeline=true", "rollouts=true"],
         "rollouts in parts": ["pipeline=true", "rollouts=true", "rollout_envs=4"]}


def _train(tmp_path: Path, mode: str, workers: int, iterations: int = 2, num_envs: int = 8) -> tuple:
    """PPO iterations on fake environments; the final weights, the last rollout's storage, the
    algorithm's class, the adapter calls counted and the logged episodes."""
    train = load_train([*TINY, *MODES[mode], "seed=3"])
    with NavVecEnv(fake_env_fn, num_envs, seed=3, workers=workers, max_episode_length=12,
                   rollout_envs=train.rollout_envs) as env:
        runner = build_runner(env, train, tmp_path / f"{mode}-{workers}", label="fake")
        calls = {"dispatch": 0, "rollout": 0}
        for name in calls:
            setattr(env, name, _counting(getattr(env, name), calls, name))
        learn(runner, iterations)  # connects the pipeline to runner.env, so to the counting methods
        storage = runner.alg.storage
        stored = {name: getattr(storage, name).clone() for name in STORED}
        stored["observations"] = stored["observations"]["policy"]
        weights = {k: v.clone() for k, v in runner.alg.actor.state_dict().items()}
        weights.update({f"critic.{k}": v.clone() for k, v in runner.alg.critic.state_dict().items()})
        logged = (list(runner.logger.rewbuffer), list(runner.logger.lenbuffer))
        return weights, stored, (type(runner.alg), calls, logged, getattr(runner.alg, "rollout_fallbacks", 0))


def _counting(method, calls: dict[str, int], name: str):
    """``method`` counting its calls in ``calls[name]``."""

    def counted(*args, **kwargs):
        calls[name] += 1
        return method(*args, **kwargs)

    return counted


@pytest.mark.parametrize("mode", ["pipeline", "rollouts", "rollouts in parts"])
@pytest.mark.parametrize("workers", [0, 2], ids=["inprocess", "main+1process"])
def test_pipelined_ppo_trains_bit_for_bit_like_rsl_rl(tmp_path: Path, workers: int, mode: str) -> None:
    """Same weights after three iterations, the same last rollout (observations, actions, values,
    log-probabilities, returns) and the same logged episodes as rsl-rl's PPO; every step's actions
    went through dispatch, or every iteration through one rollout of the workers."""
    plain_weights, plain_stored, (plain_class, plain_calls, plain_logged, _) = _train(tmp_path, "rsl-rl", workers, 3)
    weights, stored, (cls, calls, logged, fallbacks) = _train(tmp_path, mode, workers, 3)
    assert plain_class is PPO and plain_calls == {"dispatch": 0, "rollout": 0}
    expected = {"dispatch": 3 * 8, "rollout": 0} if mode == "pipeline" else {"dispatch": 0, "rollout": 3}
    assert cls is PipelinedPPO and calls == expected and fallbacks == 0
    assert logged == plain_logged and len(logged[0]) > 0  # the logger's episode returns and lengths
    for name in STORED:
        assert torch.equal(stored[name], plain_stored[name]), name
    assert weights.keys() == plain_weights.keys()
    for key, value in weights.items():
        assert torch.equal(value, plain_weights[key]), key


def test_rollouts_fall_back_where_a_block_would_differ(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where a block's actions would differ in the last bits from the whole batch's (another
    matrix-product kernel for few rows; forced here), the first rollout is refused with a warning
    and counted, and training goes on step by step, bit for bit rsl-rl's."""
    plain_weights, plain_stored, *_ = _train(tmp_path, "rsl-rl", 2)
    monkeypatch.setattr("mjnav.train.ppo._blocks_agree", lambda model, latent, output, blocks: False)
    with pytest.warns(UserWarning, match="fall back to the per-step pipeline"):
        weights, stored, (_, calls, _, fallbacks) = _train(tmp_path, "rollouts", 2)
    assert fallbacks == 1 and calls == {"dispatch": 2 * 8, "rollout": 0}
    for name in STORED:
        assert torch.equal(stored[name], plain_stored[name]), name
    for key, value in weights.items():
        assert torch.equal(value, plain_weights[key]), key


def test_rollouts_fall_back_where_the_record_does_not_fit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A rollout record larger than the shared memory: a warning saying so, and step by step."""
    monkeypatch.setattr(NavVecEnv, "can_record", lambda self, steps, aux_dim=0: False)
    with pytest.warns(UserWarning, match="does not fit in the shared memory"):
        _, _, (_, calls, _, fallbacks) = _train(tmp_path, "rollouts", 2, iterations=1)
    assert fallbacks == 1 and calls == {"dispatch": 8, "rollout": 0}


def test_rollouts_stop_after_one_whose_outputs_differ(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A rollout whose first recorded outputs differ from the trainer's (forced: the in-process
    policy's values shifted) is served to its end, then a warning and step by step."""
    shifted = RolloutActor.__call__
    monkeypatch.setattr(RolloutActor, "__call__", lambda self, *a: (lambda r: (r[0], r[1] + 1e-3))(shifted(self, *a)))
    with pytest.warns(UserWarning, match="differed in the last bits from the trainer's"):
        _, _, (_, calls, _, fallbacks) = _train(tmp_path, "rollouts", 0, iterations=2)
    assert fallbacks == 1 and calls == {"dispatch": 8, "rollout": 1}


def test_connect_resets_an_environment_left_serving_a_rollout(tmp_path: Path) -> None:
    """An environment still serving a rollout (an earlier learn() stopped part-way) is reset on connect."""
    with NavVecEnv(fake_env_fn, 8, seed=3, workers=0, max_episode_length=12) as env:
        alg = build_runner(env, load_train([*TINY, "seed=3"]), tmp_path, label="fake").alg
        with torch.inference_mode():
            alg.act(env.get_observations())
        assert env.replaying
        with pytest.warns(UserWarning, match="still serving a rollout"):
            alg.connect(env)
        assert not env.replaying


def test_the_block_check_compares_each_block_with_the_batch(tmp_path: Path) -> None:
    """The check before a rollout: equal for the batch's own rows, not for a changed row."""
    with NavVecEnv(fake_env_fn, 8, seed=3, workers=0, max_episode_length=12) as env:
        alg = build_runner(env, load_train([*TINY, "seed=3"]), tmp_path, label="fake").alg
        with torch.inference_mode():
            latent = alg.critic.get_latent(env.get_observations())
            values = alg.critic.mlp(latent)
            blocks = [range(0, 4), range(4, 8)]
            assert _blocks_agree(alg.critic, latent, values, blocks)
            values[5, 0] += 1e-6
            assert not _blocks_agree(alg.critic, latent, values, blocks)


def test_pipeline_keeps_rsl_rl_order_where_it_must(tmp_path: Path) -> None:
    """No dispatch for an environment without one or for a recurrent model; connecting stores any
    step still deferred."""
    train = load_train([*TINY, "seed=3", "rollouts=false"])
    with NavVecEnv(fake_env_fn, 4, seed=3, workers=0, max_episode_length=12) as env:
        alg = build_runner(env, train, tmp_path, label="fake").alg
        assert isinstance(alg, PipelinedPPO) and alg.pipelined
        obs = env.get_observations()
        actions = alg.act(obs)
        result = env.step(actions)
        alg.process_env_step(result[0], result[1], result[2], result[3])
        assert alg.storage.step == 0  # kept until the next act
        alg.connect(object())
        assert not alg.pipelined and alg.storage.step == 1
        alg.connect(env)
        assert alg.pipelined
        alg.actor.is_recurrent = True
        alg.connect(env)
        assert not alg.pipelined
