#!/usr/bin/env bash
# Build the sdist, build the wheel from it, install that wheel into a fresh venv and use it from a
# folder outside the checkout: every stage loads, the console scripts and `python -m mjnav.train`
# run, and the numba kernels compile although the installed package is read-only. The data folders
# come from the wheel (mjnav/_data): tasks/ (stages, recipes), assets/ (MJCF), policies/ (shipped).
# Usage: .ci/wheel_smoke.sh [PYTHON]   (TORCH=torch==2.13.0 by default, as the Makefile)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
PY="${1:-python3.11}"
TORCH="${TORCH:-torch==2.13.0}"
WORK="$(mktemp -d)"
trap 'chmod -R u+w "$WORK" 2>/dev/null; rm -rf "$WORK"' EXIT
"$PY" -m venv "$WORK/build-env"
"$WORK/build-env/bin/pip" install -q build
"$WORK/build-env/bin/python" -m build --sdist --outdir "$WORK/dist" "$ROOT" >/dev/null
tar -C "$WORK" -xzf "$WORK"/dist/mjnav-*.tar.gz
"$WORK/build-env/bin/python" -m build --wheel --outdir "$WORK/dist" "$WORK"/mjnav-*/ >/dev/null  # wheel from the sdist
"$PY" -m venv "$WORK/venv"
"$WORK/venv/bin/pip" install -q "$TORCH"
"$WORK/venv/bin/pip" install -q "$WORK"/dist/mjnav-*.whl
site="$("$WORK/venv/bin/python" -c 'import mjnav, pathlib; print(pathlib.Path(mjnav.__file__).parent)')"
chmod -R a-w "$site"   # as in a system-wide install: numba must cache elsewhere
mkdir "$WORK/elsewhere" && cd "$WORK/elsewhere"
export PATH="$WORK/venv/bin:$PATH" NUMBA_CACHE_DIR="$WORK/numba-cache"
python - <<'PY'
import gymnasium as gym, mjnav, numpy as np
assert "site-packages" in mjnav.__file__, mjnav.__file__
for env_id in mjnav.ENV_IDS:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(np.zeros(4, np.float32))
    assert env.spec.max_episode_steps == 300
    env.close()
print("all stages load from", mjnav.__file__)

import mujoco
from mjnav import resources, shipped
from mjnav.eval.policies import load_policy
from mjnav.policy import training_overrides
for folder in resources.FOLDERS:
    assert "site-packages" in str(resources.data_dir(folder)), resources.data_dir(folder)
for name in ("robot.xml", "pedestrian.xml"):
    mujoco.MjModel.from_xml_path(str(resources.asset(name)))  # plain mujoco, from the installed wheel
agent = load_policy("stage6_policy")
assert agent.input_size == 399 and "site-packages" in agent.source, agent.source
assert training_overrides("stage6_policy") == shipped.load_recipe("stage6_policy").task_overrides
assert all(shipped.get(n).path().is_file() for n in shipped.names())  # every checksum holds
print("tasks, assets and shipped policies load from", resources.data_dir("policies").parent)
PY
mjnav-train task=stage1 start=scratch train.num_envs=4 train.steps_per_env=8 train.iterations=2 out=runs | tail -1
python -m mjnav.train task=stage1 start=scratch train.num_envs=4 train.steps_per_env=8 train.iterations=1 out=runs | tail -1
mjnav-evaluate task=stage2 policy=mpc_goal episodes=2 workers=1 out=evals | tail -1
mjnav-evaluate task=stage6 policy=stage6_policy episodes=1 workers=1 out=evals | tail -1
mjnav-train recipe=stage6_policy train.num_envs=2 train.steps_per_env=8 train.minibatches=1 train.iterations=1 out=runs | tail -1
mjnav-export task=stage6 seed=1 steps=5 out=export
test -s export/scene.xml && test -n "$(ls runs/stage1-*/policy.pt)" && test -n "$(ls runs/stage6-*/checkpoint_weights.pt)"
test -n "$(find "$NUMBA_CACHE_DIR" -name '*.nbi' | head -1)"
if mjnav-train bogus=1 2>err.txt; then exit 1; fi; grep -q "^error: unknown key 'bogus'" err.txt
echo "wheel smoke test passed"
