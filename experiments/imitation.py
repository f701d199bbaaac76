"""Imitation warm start for Ours from mpc_gap (lab tool, not in mjnav).

    python experiments/imitation.py teacher STAGE N SEED0            # success of the teacher acting through Ours' action layer
    python experiments/imitation.py collect OUT.npz STAGES N SEED0 [STUDENT_CKPT BETA]   # (obs, target logits); DAgger if student
    python experiments/imitation.py fit OUT_DIR BASE_CKPT DATA.npz [DATA2.npz ...]       # BC of the actor -> OUT_DIR/model_0.pt
    python experiments/imitation.py student CKPT STAGE N SEED0       # success of the student (mean action)
    python experiments/imitation.py widen OUT.pt BASE_CKPT K         # BASE for observation.tracks=K (zero columns)

The teacher's Q_l is mpc_gap's; its action keeps (α_s, β_s) = (0.5, 0.3) (Q_s a little behind the
robot, where it hardly moves the MPC, as the PPO policies do), so α_l ≈ 0.5 for a Q_l ahead: no
wrap-around at "straight on". Targets are logits of the action clipped to [0.02, 0.98].
IMIT_OVERRIDES (comma-separated task overrides, e.g. action.heading=goal,observation.frame=goal)
adds to the task's overrides.

IMIT_TEACHER=vo swaps mpc_gap's Q_l for the privileged one of ``mpc_crowd``
(:mod:`mjnav.planners.mpc_crowd`: the pedestrians' true positions, velocities differenced over the
control period), which the student never sees; IMIT_VO overrides its MpcCrowdConfig fields (e.g.
``margin=0.5,weight=4``). Through Ours' layer (goal frame, margin 0.1) it succeeds in 97.0 / 90.5 /
72.0 % of stage 5 / 6 / 7 tuning scenarios (200 each; held-out, 1,000 each: 97.2 / 86.8 / 72.2 %).
IMIT_CONSISTENT=w (with IMIT_TEACHER=vo, in DAgger collection) adds w·cos(candidate, the acting
student's Q_l direction) to the teacher's score, so that among near-equal detours it labels the
student's own (docs/results.md: no gain at w = 0.3).

"Ours + tracks" (``observation.tracks=K``, :mod:`mjnav.tasks.observation`): put
``observation.tracks=K`` in IMIT_OVERRIDES, so that the student sees the K nearest tracks of the
robot's own LiDAR tracker (not privileged) after the 399 values, and start from ``widen``'s copy
of a shipped checkpoint (5K zero input columns: it acts exactly as the shipped policy). The
teacher may stay privileged (IMIT_TEACHER=vo): it labels at training time only. BC_NEW_INPUTS=399
makes ``fit`` move only the first layer's columns 399 and up (the tracks' weights): the student is
the base policy plus what the tracks add.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

OVERRIDES = ["collision=scan", "region.margin=0.1"] + [
    o for o in os.environ.get("IMIT_OVERRIDES", "").split(",") if o
]
A_S, B_S = 0.5, 0.3
TEACHER = os.environ.get("IMIT_TEACHER", "gap")  # gap: mpc_gap's Q_l; vo: the crowd-aware one below
R_INF = 0.325
CONSISTENT = float(os.environ.get("IMIT_CONSISTENT", "0"))  # bonus for the student's own direction
VO = {k: float(v) for k, v in (kv.split("=") for kv in os.environ.get("IMIT_VO", "").split(",") if kv)}
_PREV = {}


def logit(x):
    x = np.clip(x, 0.02, 0.98)
    return np.log(x / (1 - x))


def crowd_q_l(env, p, goal, prefer=None):
    """Privileged teacher: mjnav's ``mpc_crowd`` choice of Q_l (robot frame) from the pedestrians'
    true positions, their velocities differenced over the control period (``prefer``: a unit
    direction: ``CONSISTENT``·cos(candidate, ``prefer``) is added to every moving candidate's score,
    so that among near-equal detours the teacher labels the student's own)."""
    from mjnav.planners.mpc_crowd import CrowdTracker, MpcCrowdConfig, best_long_point, crowd_scores

    task = env.task
    circles = task.sim.pedestrian_circles()
    key = (id(env), task.episode_seed)
    if _PREV.get("key") != key:  # a new episode: no motion seen yet
        _PREV.update(key=key, tracker=CrowdTracker())
    velocities = _PREV["tracker"].update(float(env._env.physics.data.time), circles[:, :2])
    v = task.sim.robot_state(env._env.physics)[1][:2]
    relative = np.column_stack([circles[:, :2] - p[:2], circles[:, 2]])
    config = MpcCrowdConfig(**VO)
    candidates, reach, score = crowd_scores(task.core.region, goal, v, relative, velocities, R_INF, 1.0, config)
    if prefer is not None:
        speeds = np.hypot(candidates[:, 0], candidates[:, 1])
        moving = speeds > 0
        score[moving] += CONSISTENT * (candidates[moving] @ prefer) / speeds[moving]
    return best_long_point(candidates, reach, score, goal)


def student_direction(env, action) -> np.ndarray | None:
    """Unit direction (robot frame) of the Q_l that ``action`` (logits) maps to; None if degenerate."""
    from mjnav.control.action import map_action_values
    from mjnav.tasks.core import sigmoid

    task = env.task
    p, v, a = task.sim.robot_state(env._env.physics)
    goal = np.asarray(task.core.goal) - p
    values = sigmoid(np.asarray(action, float))
    motion = [float(x) for x in (*v[:2], *a[:2], *goal[:2])]
    q_l = map_action_values([*map(float, values), *motion], task.core.region, task.core.config.action).q_l
    n = float(np.hypot(*q_l))
    return q_l / n if n > 1e-6 else None


def teacher_action(env, prefer=None) -> np.ndarray:
    from mjnav.planners.mpc_goal import MpcGapConfig, reference_points
    from mjnav.control.action import map_action_values, radii

    task = env.task
    physics = env._env.physics
    p, v, a = task.sim.robot_state(physics)
    core = task.core
    region = core.region
    goal = np.asarray(core.goal) - p
    cfg = core.config.action
    r_s, _ = radii(v, a, cfg)
    if TEACHER == "vo":
        q_l = crowd_q_l(env, p, goal, prefer)
    else:
        _, q_l, _ = reference_points(region, goal, r_s, 0.9, MpcGapConfig())
    motion = [float(x) for x in (*v, *a, *goal)]
    pts = map_action_values([A_S, B_S, 0.0, 1.0, *motion], region, cfg)
    w = q_l - pts.q_s
    n = float(np.hypot(*w))
    if n < 1e-6:
        return logit(np.array([A_S, B_S, 0.5, 0.02]))
    a_l = ((math.atan2(w[1], w[0]) - pts.theta_s) % (2 * math.pi)) / (2 * math.pi)
    pts2 = map_action_values([A_S, B_S, a_l, 1.0, *motion], region, cfg)
    b_l = n / max(pts2.d_theta_l, 1e-9)
    return logit(np.array([A_S, B_S, a_l, b_l]))


def make_env(stage):
    from mjnav.envs.gym_env import NavGymEnv

    return NavGymEnv(stage, overrides=OVERRIDES, seed=0)


def load_student(ckpt):
    import torch

    from mjnav.policy import build_actor

    state = torch.load(ckpt, map_location="cpu", weights_only=False)["actor_state_dict"]
    net = build_actor(state, ("relu", "relu", "hardswish")).eval()
    return lambda obs: net(torch.as_tensor(obs, dtype=torch.float32)[None]).detach().numpy()[0]


def _new_columns_only(net, first: int) -> list:
    """Freeze ``net`` except its first layer's weight columns ``first:`` (the inputs a widened
    checkpoint added, e.g. the tracks): the fit can only add what those inputs say to the base policy."""
    import torch

    weight = next(m.weight for m in net.modules() if isinstance(m, torch.nn.Linear))
    for p in net.parameters():
        p.requires_grad_(False)
    weight.requires_grad_(True)
    mask = torch.zeros_like(weight)
    mask[:, first:] = 1.0
    weight.register_hook(lambda grad: grad * mask)
    return [weight]


def run(stage, n, seed0, act, record=None, teacher_label=False):
    env = make_env(stage)
    outcomes = {}
    for ep in range(n):
        obs, _ = env.reset(options={"episode_seed": seed0 + ep})
        for _ in range(300):
            action = act(env, obs)
            if record is not None:
                record[0].append(obs.copy())
                prefer = student_direction(env, action) if CONSISTENT > 0 else None
                record[1].append(teacher_action(env, prefer) if teacher_label else action)
            obs, _, term, trunc, info = env.step(action.astype(np.float32))
            if term or trunc:
                break
        outcomes[info["outcome"]] = outcomes.get(info["outcome"], 0) + 1
    env.close()
    return outcomes


def main(argv):
    mode = argv[0]
    if mode == "teacher":
        stage, n, seed0 = argv[1], int(argv[2]), int(argv[3])
        print(stage, run(stage, n, seed0, lambda env, obs: teacher_action(env)), flush=True)
    elif mode == "student":
        ckpt, stage, n, seed0 = argv[1], argv[2], int(argv[3]), int(argv[4])
        pol = load_student(ckpt)
        print(stage, run(stage, n, seed0, lambda env, obs: pol(obs)), flush=True)
    elif mode == "widen":
        import torch

        from mjnav.tasks.observation import TRACK_FEATURES
        from mjnav.train.runner import widen_columns

        out, base, count = Path(argv[1]), argv[2], int(argv[3])
        ckpt = torch.load(base, map_location="cpu", weights_only=False)
        width = ckpt["actor_state_dict"]["mlp.0.weight"].shape[1]
        for part in ("actor_state_dict", "critic_state_dict"):
            ckpt[part] = widen_columns(ckpt[part], width, TRACK_FEATURES * count)
        ckpt.pop("optimizer_state_dict", None)
        out.parent.mkdir(parents=True, exist_ok=True)
        torch.save(ckpt, out)
        print("wrote", out, f"({width} -> {width + TRACK_FEATURES * count} inputs)")
    elif mode == "collect":
        out, stages, n, seed0 = argv[1], argv[2].split(","), int(argv[3]), int(argv[4])
        student = load_student(argv[5]) if len(argv) > 5 else None
        beta = float(argv[6]) if len(argv) > 6 else 1.0
        rng = np.random.default_rng(seed0)
        obs_l, act_l = [], []
        for stage in stages:
            if student is None:
                act = lambda env, obs: teacher_action(env)  # noqa: E731
            else:
                act = lambda env, obs: teacher_action(env) if rng.random() < beta else student(obs)  # noqa: E731
            res = run(stage, n, seed0, act, (obs_l, act_l), teacher_label=True)
            print(stage, res, len(obs_l), flush=True)
        np.savez_compressed(out, obs=np.array(obs_l, np.float32), act=np.array(act_l, np.float32))
    elif mode == "fit":
        import torch

        from mjnav.policy import build_actor

        out_dir, base = Path(argv[1]), argv[2]
        data = [np.load(f) for f in argv[3:]]
        obs = torch.as_tensor(np.concatenate([d["obs"] for d in data]))
        act = torch.as_tensor(np.concatenate([d["act"] for d in data]))
        ckpt = torch.load(base, map_location="cpu", weights_only=False)
        net = build_actor(ckpt["actor_state_dict"], ("relu", "relu", "hardswish"))
        epochs = int(os.environ.get("BC_EPOCHS", "30"))
        params = list(net.parameters())
        if "BC_NEW_INPUTS" in os.environ:  # fit only the first layer's columns from this input on
            params = _new_columns_only(net, int(os.environ["BC_NEW_INPUTS"]))
        opt = torch.optim.Adam(params, lr=1e-3)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
        torch.manual_seed(0)
        n = len(obs)
        perm = torch.randperm(n)
        val, tr = perm[: n // 10], perm[n // 10:]
        for epoch in range(epochs):
            net.train()
            for idx in tr[torch.randperm(len(tr))].split(1024):
                loss = ((net(obs[idx]) - act[idx]) ** 2).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
            sched.step()
            if epoch % 5 == 4 or epoch == epochs - 1:
                with torch.no_grad():
                    err = ((net(obs[val]) - act[val]) ** 2).mean(0)
                print(f"epoch {epoch + 1}: val mse per output {err.numpy().round(4)}", flush=True)
        state = {f"mlp.{k}": v for k, v in net.state_dict().items()}
        ckpt["actor_state_dict"].update(state)
        ckpt["actor_state_dict"]["distribution.log_std_param"] = torch.full((4,), -1.5)
        ckpt["iter"] = 0
        ckpt.pop("optimizer_state_dict", None)
        out_dir.mkdir(parents=True, exist_ok=True)
        torch.save(ckpt, out_dir / "model_0.pt")
        print("wrote", out_dir / "model_0.pt")


if __name__ == "__main__":
    main(sys.argv[1:])
