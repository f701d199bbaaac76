"""PipelinedPPO: rsl-rl's rollouts and updates bit for bit, with the actions dispatched early."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from rsl_rl.algorithms import PPO

from mjnav.envs.vec_env import NavVecEnv
from mjnav.train.config import load_train
from mjnav.train.ppo import PipelinedPPO
from mjnav.train.runner import build_runner, learn
from tests.train.test_train import TINY, fake_env_fn

STORED = ("observations", "actions", "rewards", "dones", "values", "actions_log_prob", "returns", "advantages")


def _train(tmp_path: Path, pipeline: bool, workers: int) -> tuple[dict, dict, object]:
    """Two PPO iterations on 4 fake environments; the final weights and the last rollout's storage."""
    train = load_train([*TINY, f"pipeline={str(pipeline).lower()}", "seed=3"])
    with NavVecEnv(fake_env_fn, 4, seed=3, workers=workers, max_episode_length=12) as env:
        runner = build_runner(env, train, tmp_path / f"{pipeline}-{workers}", label="fake")
        dispatched = []
        dispatch = env.dispatch
        env.dispatch = lambda actions: (dispatched.append(1), dispatch(actions))[1]
        learn(runner, 2)  # connects the pipeline to runner.env, so to the counting dispatch
        storage = runner.alg.storage
        stored = {name: getattr(storage, name).clone() for name in STORED}
        stored["observations"] = stored["observations"]["policy"]
        weights = {k: v.clone() for k, v in runner.alg.actor.state_dict().items()}
        weights.update({f"critic.{k}": v.clone() for k, v in runner.alg.critic.state_dict().items()})
        logged = (list(runner.logger.rewbuffer), list(runner.logger.lenbuffer))
        return weights, stored, (type(runner.alg), len(dispatched), logged)


@pytest.mark.parametrize("workers", [0, 2], ids=["inprocess", "main+1process"])
def test_pipelined_ppo_trains_bit_for_bit_like_rsl_rl(tmp_path: Path, workers: int) -> None:
    """Same weights after two iterations, the same last rollout (observations, actions, values,
    log-probabilities, returns) and the same logged episodes as rsl-rl's PPO; every step's actions
    went through dispatch."""
    plain_weights, plain_stored, (plain_class, plain_dispatched, plain_logged) = _train(tmp_path, False, workers)
    weights, stored, (cls, dispatched, logged) = _train(tmp_path, True, workers)
    assert plain_class is PPO and plain_dispatched == 0
    assert cls is PipelinedPPO and dispatched == 2 * 8
    assert logged == plain_logged and len(logged[0]) > 0  # the logger's episode returns and lengths
    for name in STORED:
        assert torch.equal(stored[name], plain_stored[name]), name
    assert weights.keys() == plain_weights.keys()
    for key, value in weights.items():
        assert torch.equal(value, plain_weights[key]), key


def test_pipeline_keeps_rsl_rl_order_where_it_must(tmp_path: Path) -> None:
    """No dispatch for an environment without one or for a recurrent model; connecting stores any
    step still deferred."""
    train = load_train([*TINY, "seed=3"])
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
