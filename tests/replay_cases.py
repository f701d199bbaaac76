"""Fixed sample of episodes whose trajectories must never change (see ``tests/test_replay.py``).

The digests in ``tests/data/replay_digests.json`` were recorded at commit b578b34, before the
house reorganisation (issue 40); re-record only for an intended change of behaviour, and say so in
the commit: ``python tests/replay_cases.py record``.

The learned policies' float32 arithmetic (torch, MKL) takes other code paths on other CPUs (an
AVX-512 machine gives other last bits than the one that recorded), and a closed-loop episode
carries such a difference on. Those cases are also recorded per *numerics class*: the digest of
the stage-2 policy's outputs on fixed probe inputs (:func:`numerics_fingerprint`), in
``tests/data/replay_numerics.json``. A machine of a recorded class must reproduce its own digests
bit for bit; one of an unknown class must reproduce the primary ones (or fails, naming its class).
Record a new class only from a commit whose behaviour is unchanged (its other cases pass):
``python tests/replay_cases.py record-numerics``.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

DIGESTS = Path(__file__).parent / "data" / "replay_digests.json"
NUMERICS = Path(__file__).parent / "data" / "replay_numerics.json"

#: (case name, task, policy, held-out index, task overrides).
CASES: list[tuple[str, str, str, int, tuple[str, ...]]] = [
    *[(f"stage{k}-mpc_goal", f"stage{k}", "mpc_goal", k, ()) for k in range(1, 8)],
    *[(f"stage{k}-policy", f"stage{k}", f"stage{k}_policy", k + 10, ()) for k in range(2, 8)],
    ("stage7-teb", "stage7", "teb", 3, ()),
    ("stage6-dwa", "stage6", "dwa", 4, ()),
    ("stage7-mpc_crowd", "stage7", "mpc_crowd", 5, ()),
    ("stage5-mpc_gap", "stage5", "mpc_gap", 6, ()),
    ("stage3-random_jerk", "stage3", "random_jerk", 7, ()),
    ("stage6-social_force", "stage6", "mpc_goal", 8, ("crowd.model=social_force",)),
    ("stage4-mujoco_lidar", "stage4", "mpc_goal", 9, ("lidar.backend=mujoco",)),
    ("stage4-design2", "stage4", "stage4_design2", 2, ()),
    ("stage7-r_t3", "stage7", "stage7_r_t3", 12, ()),
    ("stage6-scan_rule", "stage6", "stage6_policy", 21, ("collision=scan",)),
]


def _digest(*arrays: np.ndarray, outcome: str) -> str:
    h = hashlib.sha256(outcome.encode())
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


def run_case(task: str, policy: str, index: int, overrides: tuple[str, ...]) -> dict:
    """Trajectory digest and outcome of one held-out episode."""
    from mjnav.eval.runner import episode_setup, run_episode

    env, agent, seed = episode_setup({"task": task, "policy": _policy_spec(policy), "seed": str(index)},
                                     list(overrides))
    try:
        metrics, _, trace = run_episode(env, agent, seed)
    finally:
        env.close()
    plans = [np.concatenate([np.ravel(p[k]) for k in ("q_s", "q_l", "predicted")]) for p in trace.plans]
    arrays = [trace.positions, trace.velocities, np.nan_to_num(trace.pedestrians, nan=-1.0)]
    if plans:
        arrays.append(np.concatenate(plans))
    return {"outcome": metrics.outcome, "steps": int(len(trace.positions) - 1),
            "digest": _digest(*arrays, outcome=metrics.outcome)}


#: A short PPO run whose final parameters must never change (scratch start, in-process workers).
TRAIN_ARGS = ["task=stage1", "train.iterations=2", "train.num_envs=4", "train.steps_per_env=16",
              "train.minibatches=2", "train.workers=0", "start=scratch"]


def train_case(out: Path) -> dict:
    """Digest of the actor and critic parameters after :data:`TRAIN_ARGS`."""
    import subprocess

    import torch

    script = Path(__file__).parents[1] / "scripts" / "train.py"
    subprocess.run([sys.executable, str(script), *TRAIN_ARGS, f"out={out}"], check=True, capture_output=True)
    (model,) = sorted(out.glob("*/model_1.pt"))
    state = torch.load(model, map_location="cpu", weights_only=False)
    weights = state.get("actor_state_dict") or state["model_state_dict"]
    critic = state.get("critic_state_dict", {})
    arrays = [v.detach().double().numpy() for d in (weights, critic) for _, v in sorted(d.items())]
    return {"digest": _digest(*arrays, outcome="train")}


def numerics_fingerprint() -> str:
    """The numerics class of this machine's torch: digest of the shipped stage-2 actor's outputs,
    one probe row at a time as an episode runs it (16 hex digits)."""
    import torch

    from mjnav.shipped import resolve

    actor = torch.jit.load(str(resolve("stage2_policy")), map_location="cpu")
    size = next(p for p in actor.parameters() if p.dim() == 2).shape[1]
    probes = torch.from_numpy(np.random.default_rng(0).normal(size=(8, size)).astype(np.float32))
    with torch.no_grad():
        out = [actor(probes[i : i + 1]).numpy() for i in range(len(probes))]
    return hashlib.sha256(b"".join(o.tobytes() for o in out)).hexdigest()[:16]


def expected(name: str) -> dict:
    """The recorded result of case ``name`` for this machine's numerics class (primary otherwise)."""
    primary = json.loads(DIGESTS.read_text())[name]
    classes = json.loads(NUMERICS.read_text()) if NUMERICS.exists() else {}
    return classes.get(numerics_fingerprint(), {}).get("cases", {}).get(name, primary)


def _policy_spec(policy: str) -> str:
    """A shipped policy's name as evaluation takes it (one place to change when the API moves):
    the manifest name itself (``stage6_policy``, policies/manifest.yaml)."""
    return policy


if __name__ == "__main__" and sys.argv[1:] == ["record"]:
    import tempfile

    out = {name: run_case(task, policy, index, ov) for name, task, policy, index, ov in CASES}
    with tempfile.TemporaryDirectory() as tmp:
        out["train-stage1"] = train_case(Path(tmp))
    DIGESTS.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__" and sys.argv[1:2] == ["record-numerics"]:
    import platform
    import subprocess
    import tempfile

    primary = json.loads(DIGESTS.read_text())
    out = {name: run_case(task, policy, index, ov) for name, task, policy, index, ov in CASES}
    with tempfile.TemporaryDirectory() as tmp:
        out["train-stage1"] = train_case(Path(tmp))
    differing = {name: result for name, result in out.items() if result != primary[name]}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    classes = json.loads(NUMERICS.read_text()) if NUMERICS.exists() else {}
    classes[numerics_fingerprint()] = {"recorded_at": commit, "machine": " ".join(sys.argv[2:]) or platform.processor(),
                                       "cases": differing}
    NUMERICS.write_text(json.dumps(classes, indent=1, sort_keys=True) + "\n")
    print(json.dumps(differing, indent=1))
