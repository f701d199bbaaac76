"""Kill a stage-1 training run with SIGKILL at random moments and resume it each time.

    python scripts/kill_resume.py [kills=5] [iterations=40] [save_interval=5] [seed=0] [out=/tmp/kill_resume]

Each round waits until the run has logged a randomly chosen iteration (plus a random fraction of
that iteration's duration, so kills also land inside collection, update and checkpoint writes of the
next one, however fast the iterations are), kills the whole
process group with SIGKILL, checks that every ``model_<it>.pt`` loads and that the newest is at
most ``save_interval`` iterations behind the last logged one, then continues with
``resume=RUN_DIR``. After the last kill the run trains to its end. Prints one line per kill and a
JSON report; exit code 1 when a check fails.
"""

from __future__ import annotations

import dataclasses
import json
import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import torch

from mjnav.args import Parsed
from mjnav.cli import run_script
from mjnav.train.runner import checkpoints

_LINE = re.compile(r"\] it (\d+)/\d+ ")
_TIMES = re.compile(r"collect\s+([\d.]+)s .*\| update\s+([\d.]+)s")


def _logged(log: Path) -> int:
    """Index of the last iteration the run has logged (-1 before the first)."""
    found = _LINE.findall(log.read_text(errors="replace")) if log.is_file() else []
    return int(found[-1]) - 1 if found else -1


def _iteration_seconds(log: Path) -> float:
    """Collection plus update time of the last logged iteration, seconds (0.1 if none is logged)."""
    found = _TIMES.findall(log.read_text(errors="replace")) if log.is_file() else []
    return sum(map(float, found[-1])) if found else 0.1


def _start(argv: list[str], log: Path, python: str, cwd: Path) -> subprocess.Popen:
    with open(log, "w") as stream:  # the child keeps its own descriptor
        return subprocess.Popen([python, "scripts/train.py", *argv], cwd=cwd, stdout=stream,
                                stderr=subprocess.STDOUT, start_new_session=True)


def _wait_for(proc: subprocess.Popen, log: Path, iteration: int, timeout: float = 600.0) -> None:
    end = time.monotonic() + timeout
    while _logged(log) < iteration:
        if proc.poll() is not None:
            raise RuntimeError(f"training exited (code {proc.returncode}) before iteration {iteration}:\n"
                               f"{log.read_text()[-2000:]}")
        if time.monotonic() > end:
            raise RuntimeError(f"iteration {iteration} not reached within {timeout:.0f} s")
        time.sleep(0.05)


def _all_load(run_dir: Path) -> bool:
    for path in checkpoints(run_dir):
        state = torch.load(path, map_location="cpu", weights_only=False)
        if "actor_state_dict" not in state:
            return False
    return True


def run(kills: int, out: Path, rng: random.Random, iterations: int = 40, save_interval: int = 5,
        python: str = sys.executable, cwd: Path | None = None) -> dict[str, Any]:
    """Train, kill and resume ``kills`` times, then finish; returns the report (see the module docstring)."""
    cwd = cwd or Path(__file__).resolve().parents[1]
    out.mkdir(parents=True, exist_ok=True)
    argv = ["task=stage1", "start=scratch", "train.num_envs=8", "train.steps_per_env=16", "train.workers=2",
            f"train.iterations={iterations}", f"train.save_interval={save_interval}", f"out={out}"]
    report: dict[str, Any] = {"kills": [], "finished": False}
    log = out / "round0.log"
    proc, run_dir = _start(argv, log, python, cwd), None
    for k in range(kills):
        done = _logged(log)
        target = rng.randint(max(done + 1, 0), max(done + 1, iterations - 2 - (kills - k)))
        _wait_for(proc, log, target)
        time.sleep(rng.uniform(0.0, 1.0) * _iteration_seconds(log))
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        run_dir = run_dir or next(out.glob("stage1-*"))
        logged, found = _logged(log), checkpoints(run_dir)
        last = int(found[-1].stem.split("_")[1]) if found else -1
        record = {"kill": k + 1, "logged_iteration": logged, "last_checkpoint": last,
                  "lost_iterations": logged - last, "checkpoints_load": _all_load(run_dir)}
        report["kills"].append(record)
        print(json.dumps(record), flush=True)
        if not found:
            raise RuntimeError(f"no checkpoint after kill {k + 1}: {log.read_text()[-2000:]}")
        log = out / f"round{k + 1}.log"
        proc = _start([f"resume={run_dir}"], log, python, cwd)
    if proc.wait() != 0:
        raise RuntimeError(f"the last round failed:\n{log.read_text()[-2000:]}")
    run_dir = run_dir or next(out.glob("stage1-*"))
    report["final_checkpoint"] = checkpoints(run_dir)[-1].name
    report["finished"] = (run_dir / "policy.pt").is_file() and _all_load(run_dir)
    return report


@dataclasses.dataclass(frozen=True)
class KillResumeOptions:
    """The keys of ``scripts/kill_resume.py``.

    Attributes:
        kills: SIGKILLs, each followed by a resume.
        iterations: PPO iterations of the stage-1 run.
        save_interval: Iterations between checkpoints.
        seed: Seed of the kill moments.
        out: Parent folder of the run.
    """

    kills: int = 5
    iterations: int = 40
    save_interval: int = 5
    seed: int = 0
    out: str = "/tmp/kill_resume"


def main(argv: list[str]) -> int:
    """Parse arguments (``--help``: the keys), run, print the report; 1 if a resume failed or lost
    more than one interval."""
    return run_script(argv, "scripts/kill_resume.py", "Kill a stage-1 training run at random moments and resume it.",
                      KillResumeOptions, _main)


def _main(parsed: Parsed) -> int:
    opts: KillResumeOptions = parsed.options
    interval = opts.save_interval
    report = run(opts.kills, Path(opts.out), random.Random(opts.seed), opts.iterations, interval)
    print(json.dumps(report, indent=1))
    ok = report["finished"] and all(k["lost_iterations"] <= interval and k["checkpoints_load"] for k in report["kills"])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
