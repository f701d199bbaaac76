"""Paired speed comparison of this checkout against another git revision, in one process.

    python scripts/compare_speed.py ref=HEAD~3 [task=stage7] [blocks=40] [block_steps=300]
                                    [adapter=false] [num_envs=16] [dm_env=false] [task.crowd.count=25]

This machine's speed drifts by up to 2x over minutes, so two separate benchmark runs cannot tell
which version is faster. Here the other revision's ``mjnav`` package is exported (``git archive``)
into a temporary folder as ``mjnav_ref``, with its imports rewritten. One environment (or, with
``adapter=true``, one ``NavVecEnv`` on all cores) is built from each version. Blocks of
random-action steps then alternate between the two, swapping the order every block, and the
script prints the median and interquartile range of the paired ratio new / ref. The same task
overrides apply to both versions. One environment is the Gymnasium environment; ``dm_env=true``
times ``mjnav.make_env``'s ``composer.Environment.step`` instead.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
import re
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

import numpy as np

from mjnav.args import Parsed
from mjnav.cli import run_script
from mjnav.schema import ConfigError
from mjnav.timing import Block, time_rounds

ROOT = Path(__file__).resolve().parents[1]


@dataclasses.dataclass(frozen=True)
class CompareOptions:
    """The keys of ``scripts/compare_speed.py``.

    Attributes:
        ref: The git revision to compare this checkout against.
        task: Bundled stage name or task YAML path.
        blocks: Timed blocks per version (alternating, the order swapped every block).
        block_steps: Random-action steps per block.
        adapter: Time one ``NavVecEnv`` on all cores instead of one environment.
        dm_env: Time ``mjnav.make_env``'s ``composer.Environment.step`` instead of the Gymnasium environment.
        num_envs: Environments of the adapter.
        seed: Environment seed.
    """

    ref: str = "HEAD"
    task: str = "stage7"
    blocks: int = 40
    block_steps: int = 300
    adapter: bool = False
    dm_env: bool = False
    num_envs: int = 16
    seed: int = 0

_IMPORT = re.compile(r"\bmjnav(?=[./\s]|$)", re.MULTILINE)  # imports, entry points, gym ids


def export_revision(ref: str, folder: Path) -> str:
    """Extract ``mjnav`` and its stage files at ``ref`` into ``folder`` as package ``mjnav_ref``."""
    # The stage files live in tasks/ (until 2026-12-03, and again from issue 40 on, with the MJCF in assets/).
    paths = ["mjnav", *(top for top in ("tasks", "assets") if subprocess.run(
        ["git", "-C", str(ROOT), "cat-file", "-e", f"{ref}:{top}"], capture_output=True).returncode == 0)]
    try:
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", "--format=tar", ref, *paths], check=True, capture_output=True
        ).stdout
    except subprocess.CalledProcessError as err:
        raise ConfigError(f"ref={ref!r}: git archive failed: {err.stderr.decode().strip()}") from None
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        # Our own repository's archive; the extraction filter exists from Python 3.11.4 on.
        tar.extractall(folder, **({"filter": "tar"} if hasattr(tarfile, "tar_filter") else {}))
    (folder / "mjnav").rename(folder / "mjnav_ref")
    for path in (folder / "mjnav_ref").rglob("*.py"):
        path.write_text(_IMPORT.sub("mjnav_ref", path.read_text()))
    return subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", ref], check=True, capture_output=True, text=True
    ).stdout.strip()


def _one_env(package: str, config_args: tuple[str, list[str]], seed: int, block_steps: int):
    """A block of ``block_steps`` random-action steps of one Gymnasium environment, and its closer."""
    load_task = importlib.import_module(f"{package}.config").load_task
    gym_env = importlib.import_module(f"{package}.envs.gym_env")
    env = gym_env.NavGymEnv(load_task(*config_args), seed=seed)
    env.reset(seed=seed)
    actions = np.random.default_rng(seed).normal(size=(block_steps, 4)).astype(np.float32)

    def block() -> int:
        for a in actions:
            if any(env.step(a)[2:4]):
                env.reset()
        return len(actions)

    return block, env.close


def _one_dm_env(package: str, config_args: tuple[str, list[str]], seed: int, block_steps: int):
    """A block of ``block_steps`` random-action steps of ``make_env``'s environment, and its closer."""
    load_task = importlib.import_module(f"{package}.config").load_task
    env = importlib.import_module(f"{package}.envs.factory").make_env(load_task(*config_args), seed=seed)
    env.reset()
    actions = np.random.default_rng(seed).normal(size=(block_steps, 4)).astype(np.float32)

    def block() -> int:
        for a in actions:
            if env.step(a).last():
                env.reset()
        return len(actions)

    return block, env.close


def _adapter(package: str, config_args: tuple[str, list[str]], seed: int, block_steps: int, num_envs: int):
    """A block of about ``block_steps`` env steps of the rsl-rl adapter on all cores, and its closer."""
    import torch

    load_task = importlib.import_module(f"{package}.config").load_task
    vec_env = importlib.import_module(f"{package}.envs.vec_env")
    runner = importlib.import_module(f"{package}.train.runner")
    torch.set_num_threads(1)
    config = load_task(*config_args)
    env = vec_env.NavVecEnv(
        runner.TaskEnvFactory(config), num_envs=num_envs, seed=seed, max_episode_length=config.timing.episode_steps
    )
    steps = max(1, block_steps // num_envs)
    actions = torch.randn(steps, num_envs, 4, generator=torch.Generator().manual_seed(seed))

    def block() -> int:
        for a in actions:
            env.step(a)
        return steps * num_envs

    return block, env.close


def compare(blocks: dict[str, Block], repeats: int) -> dict[str, np.ndarray]:
    """Steps/s of each version per repetition, alternating the order (after one warm-up block each)."""
    for block in blocks.values():
        block()  # warm-up: numba caches, solver set-up
    return time_rounds(blocks, repeats)


def main(argv: list[str]) -> int:
    """Parse ``key=value`` arguments (``--help``: the keys) and compare; returns the exit code."""
    return run_script(argv, "scripts/compare_speed.py", "Paired speed comparison against another git revision.",
                      CompareOptions, _main, ("task",))


def _main(parsed: Parsed) -> int:
    """Export the revision, build both versions, time them in alternation and print the ratio."""
    opts: CompareOptions = parsed.options
    overrides = list(parsed.task)
    with tempfile.TemporaryDirectory(prefix="mjnav-ref-") as tmp:
        ref = export_revision(opts.ref, Path(tmp))
        sys.path.insert(0, tmp)
        os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [tmp, os.environ.get("PYTHONPATH")]))
        config_args = (opts.task, overrides)
        seed, steps, builds, closers = opts.seed, opts.block_steps, {}, []
        for name, package in (("ref", "mjnav_ref"), ("new", "mjnav")):
            if opts.adapter:
                block, close = _adapter(package, config_args, seed, steps, opts.num_envs)
            elif opts.dm_env:
                block, close = _one_dm_env(package, config_args, seed, steps)
            else:
                block, close = _one_env(package, config_args, seed, steps)
            builds[name] = block
            closers.append(close)
        try:
            rates = compare(builds, opts.blocks)
        finally:
            for close in closers:
                close()
    ratio = rates["new"] / rates["ref"]
    what = (f"adapter, {opts.num_envs} envs, all cores" if opts.adapter
            else "one composer environment (dm_env)" if opts.dm_env else "one Gymnasium environment")
    print(
        f"{opts.task}, {what}: {ref} median {np.median(rates['ref']):,.0f} steps/s, "
        f"this checkout {np.median(rates['new']):,.0f} steps/s"
    )
    print(
        f"paired ratio new/ref: median {np.median(ratio):.3f} "
        f"(IQR {np.percentile(ratio, 25):.3f}-{np.percentile(ratio, 75):.3f}, {len(ratio)} blocks)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
