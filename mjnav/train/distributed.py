"""Data-parallel PPO over ``torchrun`` processes, on rsl-rl's own multi-process path.

``torchrun --nproc_per_node=N scripts/train.py task=stage6 ...`` (or ``torchrun --no-python mjnav
train ...``, or ``torchrun -m mjnav train ...``) trains one policy in N processes; with
``--nnodes`` and a rendezvous endpoint it spans machines. Each process (rank):

* steps its own ``train.num_envs`` environments (``num_envs`` is per rank: one iteration collects
  ``world_size × num_envs × steps_per_env`` transitions) with its own workers, the node's cores
  shared among its ranks when ``train.workers=-1`` / ``train.update_threads=0``;
* seeds its environments and torch with :func:`rank_seed`: ``seed + rank × num_envs``, so
  environment i of rank r starts from the seed of environment ``r × num_envs + i`` of a one-process
  run with ``world_size × num_envs`` environments, and rank 0 is the one-process run;
* runs rsl-rl's PPO with ``multi_gpu`` set: parameters broadcast from rank 0 at the start of every
  ``learn``, gradients averaged over the ranks (all-reduce) before every optimizer step, the
  observation normalizer's moments and the adaptive learning rate shared, so every rank holds
  the same parameters after every update;
* writes nothing but rank 0: the run folder, ``config.yaml``, TensorBoard, checkpoints and exports
  come from rank 0 alone, with the same files as a one-process run; the other ranks learn the run
  folder's name from rank 0 and read it (``resume=`` needs it on a filesystem every node sees).

The backend is gloo on CPU and NCCL on CUDA, where ``train.device=cuda`` means ``cuda:LOCAL_RANK``.
rsl-rl's :class:`~rsl_rl.runners.OnPolicyRunner` asks for ``cuda:LOCAL_RANK`` and NCCL;
:class:`DistributedRunner` only replaces that setup step and reads the ranks from the process group
that :func:`process_group` opened. Without ``WORLD_SIZE > 1`` nothing here changes a run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
from collections.abc import Iterator, Mapping
from typing import Any, TypeVar

import torch
import torch.distributed as dist
from rsl_rl.runners import OnPolicyRunner

from mjnav.jobs import usable_cores
from mjnav.schema import ConfigError

__all__ = [
    "DistributedRunner",
    "Ranks",
    "any_rank",
    "backend",
    "current",
    "process_group",
    "rank_cores",
    "rank_device",
    "rank_seed",
    "ranks_from_env",
    "share",
]

T = TypeVar("T")

#: How long a collective waits for a missing rank before failing (a rank that died, a stuck node).
TIMEOUT = datetime.timedelta(minutes=30)


@dataclasses.dataclass(frozen=True)
class Ranks:
    """Where this process stands among the training processes (torchrun's variables).

    Attributes:
        rank: Global rank, 0 .. world_size - 1 (``RANK``); rank 0 writes the run folder.
        local_rank: Rank on this node (``LOCAL_RANK``): picks the GPU ``cuda:local_rank``.
        world_size: Processes in all (``WORLD_SIZE``).
        local_world_size: Processes on this node (``LOCAL_WORLD_SIZE``): they share its cores.
    """

    rank: int = 0
    local_rank: int = 0
    world_size: int = 1
    local_world_size: int = 1

    @property
    def distributed(self) -> bool:
        """More than one process trains."""
        return self.world_size > 1

    @property
    def main(self) -> bool:
        """This process writes the run folder (rank 0)."""
        return self.rank == 0


def ranks_from_env(environ: Mapping[str, str] = os.environ) -> Ranks:
    """The ranks torchrun announces in ``environ`` (one process when it sets none)."""
    world = int(environ.get("WORLD_SIZE", "1"))
    return Ranks(
        rank=int(environ.get("RANK", "0")),
        local_rank=int(environ.get("LOCAL_RANK", "0")),
        world_size=world,
        local_world_size=int(environ.get("LOCAL_WORLD_SIZE", str(world))),
    )


def current() -> Ranks:
    """This process's ranks while a process group is open, else one process."""
    if not (dist.is_available() and dist.is_initialized()):
        return Ranks()
    return dataclasses.replace(ranks_from_env(), rank=dist.get_rank(), world_size=dist.get_world_size())


def backend(device: str) -> str:
    """The collective backend of a torch device: ``nccl`` for CUDA, ``gloo`` otherwise."""
    return "nccl" if device.startswith("cuda") else "gloo"


def rank_device(device: str, ranks: Ranks) -> str:
    """The device a rank trains on: ``cuda`` (or any ``cuda:K``) becomes ``cuda:LOCAL_RANK`` when
    distributed; ``cpu`` stays; one process keeps ``device`` as given.

    Raises:
        ConfigError: ``mps`` with several processes (no collective backend for it).
    """
    if not ranks.distributed:
        return device
    if device.startswith("mps"):
        raise ConfigError("train.device=mps: data-parallel training runs on cpu (gloo) or cuda (nccl)")
    return f"cuda:{ranks.local_rank}" if device.startswith("cuda") else device


def rank_seed(seed: int, num_envs: int, ranks: Ranks) -> int:
    """Seed of a rank's environments and torch: ``seed + rank × num_envs`` (``seed`` on rank 0)."""
    return seed + ranks.rank * num_envs


def rank_cores(ranks: Ranks) -> int:
    """CPU cores of one rank: this process's usable cores shared by the ranks of its node (>= 1)."""
    return max(1, usable_cores() // max(1, ranks.local_world_size))


@contextlib.contextmanager
def process_group(device: str) -> Iterator[Ranks]:
    """Open the process group torchrun asks for (``WORLD_SIZE > 1``) for ``device``; close it after.

    Gloo on CPU, NCCL on CUDA with this rank's GPU made current. Without torchrun (or with a group
    already open) it opens nothing and yields :func:`current`.
    """
    ranks = ranks_from_env()
    if not ranks.distributed or dist.is_initialized():
        yield current()
        return
    local = rank_device(device, ranks)
    if local.startswith("cuda"):
        torch.cuda.set_device(local)
    dist.init_process_group(backend(local), rank=ranks.rank, world_size=ranks.world_size, timeout=TIMEOUT)
    try:
        yield current()
    finally:
        dist.destroy_process_group()


def share(value: T) -> T:
    """Rank 0's ``value`` on every rank (a picklable object; ``value`` itself in one process)."""
    if not current().distributed:
        return value
    box: list[Any] = [value]
    dist.broadcast_object_list(box, src=0)
    return box[0]


def any_rank(flag: bool, device: str) -> bool:
    """Whether ``flag`` is set on any rank (every rank must call it at the same point)."""
    if not current().distributed:
        return flag
    tensor = torch.tensor([int(flag)], device=device)
    dist.all_reduce(tensor, op=dist.ReduceOp.MAX)
    return bool(tensor.item())


class DistributedRunner(OnPolicyRunner):
    """rsl-rl's runner with its multi-process setup taken from the open process group.

    rsl-rl's own ``_configure_multi_gpu`` requires ``device == cuda:LOCAL_RANK`` and opens an NCCL
    group itself; here :func:`process_group` has opened the group (gloo on CPU, NCCL on CUDA) and
    this only fills in what PPO and the logger read (``cfg["multi_gpu"]``, ranks and world size).
    Everything else (parameter broadcast, gradient all-reduce, rank-0-only logging and saving) is
    rsl-rl's. In one process it sets what rsl-rl sets: ``cfg["multi_gpu"] = None``.
    """

    def _configure_multi_gpu(self) -> None:
        """Read ranks and world size from the process group; check the rank's device."""
        ranks = current()
        self.gpu_world_size, self.is_distributed = ranks.world_size, ranks.distributed
        self.gpu_local_rank, self.gpu_global_rank = ranks.local_rank, ranks.rank
        if not ranks.distributed:
            self.gpu_local_rank = self.gpu_global_rank = 0
            self.cfg["multi_gpu"] = None
            return
        self.cfg["multi_gpu"] = {"global_rank": ranks.rank, "local_rank": ranks.local_rank,
                                 "world_size": ranks.world_size}
        expected = rank_device(self.device, ranks)
        if self.device != expected:
            raise ValueError(f"device {self.device!r} on local rank {ranks.local_rank}: expected {expected!r}")
