"""Lab diagnostic: PPO whose actor also reads the crowd's true state (not a robot's input).

    python experiments/privileged_actor.py INIT.pt OUT_DIR K [train.py arguments...]
    python experiments/privileged_actor.py eval RUN/model_N.pt EPISODES SEED_OFFSET

Question: does PPO, from a plateaued crowd policy, improve once the actor *can* see the
pedestrians' motion? ``task.observation.critic_pedestrians=K`` already gives the critic the K
nearest pedestrians' true positions, velocities and radii (``mjnav/tasks/privileged.py``); here the
actor reads them too (rsl-rl ``obs_groups``: actor = critic = policy + critic). INIT's actor and
critic get zero input columns for the 6K new values, so the run starts as INIT's policy exactly
and only learning can make it use them. Its checkpoints need those inputs: they are for reading
the training curve (sampled actions) and for this script's ``eval`` (mean action, with the true
crowd state from the environment's ``info["critic"]``), not for ``scripts/evaluate.py`` or shipping.
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from mjnav.tasks.privileged import critic_size
from mjnav.train import runner as runner_lib
from mjnav.train import session


def widen(init: Path, out: Path, extra: int) -> Path:
    """Copy ``init`` with ``extra`` zero input columns on the actor's and critic's first layers."""
    state = torch.load(str(init), map_location="cpu", weights_only=False)
    for part in ("actor_state_dict", "critic_state_dict"):
        weight = state[part]["mlp.0.weight"]
        state[part]["mlp.0.weight"] = torch.cat([weight, weight.new_zeros(weight.shape[0], extra)], dim=1)
    state.pop("optimizer_state_dict", None)
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save(state, out)
    return out


def _actor_reads_the_crowd(original):
    def rsl_config(train, label="", privileged_critic=False):
        cfg = original(train, label, privileged_critic)
        if privileged_critic:
            cfg["obs_groups"]["actor"] = ["policy", "critic"]
        return cfg

    return rsl_config


def evaluate(checkpoint: Path, episodes: int, seed_offset: int) -> float:
    """Success rate of the widened actor's mean action on held-out-range scenarios
    (``HELD_OUT_BASE + seed_offset + i``, as ``scripts/evaluate.py``) of its run's task."""
    import gymnasium as gym
    import numpy as np
    import yaml

    import mjnav  # noqa: F401  (registers the ids)
    from mjnav.policy import build_actor, policy_config, training_overrides
    from mjnav.eval.runner import held_out_seed

    weights = torch.load(str(checkpoint), map_location="cpu", weights_only=False)["actor_state_dict"]
    actor = build_actor(weights, ("relu", "relu", "hardswish"))
    stage = yaml.safe_load(policy_config(checkpoint).read_text())["run"]["task"].removeprefix("stage")
    env = gym.make(f"mjnav/Stage{stage}-v1", overrides=list(training_overrides(checkpoint)))
    wins = 0
    for i in range(episodes):
        obs, info = env.reset(options={"episode_seed": held_out_seed(i, seed_offset)})
        done = False
        while not done:
            with torch.no_grad():
                mean = actor(torch.as_tensor(np.concatenate([obs, info["critic"]]), dtype=torch.float32))
            obs, _, terminated, truncated, info = env.step(mean.numpy().astype(np.float64))
            done = terminated or truncated
        wins += info["outcome"] == "success"
    env.close()
    return wins / episodes


def main(argv: list[str]) -> int:
    if argv[:1] == ["eval"] and len(argv) == 4:
        rate = evaluate(Path(argv[1]), int(argv[2]), int(argv[3]))
        print(f"{argv[1]}: success {100 * rate:.1f} % of {argv[2]} (seed_offset {argv[3]})")
        return 0
    if len(argv) < 3:
        print(__doc__)
        return 2
    init, out, count = Path(argv[0]), Path(argv[1]), int(argv[2])
    widened = widen(init, out / "init_widened.pt", critic_size(count))
    runner_lib.rsl_config = _actor_reads_the_crowd(runner_lib.rsl_config)
    session.run([f"init={widened}", f"out={out}", f"task.observation.critic_pedestrians={count}", *argv[3:]])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
