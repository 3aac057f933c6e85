"""The process group of a training run: one process, or one of ``torchrun``'s processes.

``torchrun`` sets ``WORLD_SIZE``, ``RANK``, ``LOCAL_RANK``, ``MASTER_ADDR`` and ``MASTER_PORT``;
with ``WORLD_SIZE > 1`` :func:`_setup` initialises the default process group from them (gloo on
CPU, nccl on CUDA, each process on GPU ``LOCAL_RANK``) unless the caller already did.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass
from typing import Any

import torch
import torch.distributed as dist

from rgbd_rs.errors import InvalidArgumentError, RgbdError


def is_main_process() -> bool:
    """True in a single process and on rank 0 under torchrun (also before the process group is
    initialised, from the ``RANK`` environment variable)."""
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank() == 0
    return os.environ.get("RANK", "0") == "0"


@dataclass(frozen=True)
class _Group:
    """This process's place in the run; collectives are no-ops in a single process."""

    rank: int
    world: int
    device: torch.device
    #: _setup() initialised the process group, so close() destroys it.
    owns: bool = False

    def sum(self, values: list[float]) -> list[float]:
        """Element-wise sum of ``values`` over all processes (float64)."""
        if self.world == 1:
            return values
        t = torch.tensor(values, dtype=torch.float64, device=self.device)
        dist.all_reduce(t)
        return [float(v) for v in t.tolist()]

    def gather(self, obj: object) -> list[Any]:
        """``obj`` of every process, in rank order (pickled across processes)."""
        if self.world == 1:
            return [obj]
        out: list[Any] = [None] * self.world
        dist.all_gather_object(out, obj)
        return out

    def broadcast(self, obj: object) -> Any:
        """Rank 0's ``obj`` on every process (pickled across processes)."""
        if self.world == 1:
            return obj
        box = [obj]
        dist.broadcast_object_list(box, src=0)
        return box[0]

    def barrier(self) -> None:
        """Wait for every process."""
        if self.world == 1:
            return
        if self.device.type == "cuda":  # nccl needs to know the device, or it warns
            dist.barrier(device_ids=[self.device.index or 0])
        else:
            dist.barrier()

    def close(self) -> None:
        """Destroy the process group if :func:`_setup` created it."""
        if self.owns and dist.is_initialized():
            dist.destroy_process_group()


#: train() calls that created a process group in this process (the same count on every rank).
_CALLS = itertools.count()


def _env_int(name: str, default: int) -> int:
    raw = os.environ.get(name, str(default))
    try:
        return int(raw)
    except ValueError:
        raise RgbdError(f"environment variable {name}: got {raw!r}, expected an integer") from None


def _setup(device: str) -> _Group:
    """Resolve ``device`` (``"auto"``, ``"cpu"``, ``"cuda"``, ``"cuda:N"``) and join the process
    group when ``WORLD_SIZE > 1``."""
    world = _env_int("WORLD_SIZE", 1)
    local = _env_int("LOCAL_RANK", 0)
    if device == "auto":
        device = "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise InvalidArgumentError(f"device: got {device!r} but CUDA is not available")
    # A bare "cuda" means this process's GPU, with its index: torch.cuda.set_device refuses a
    # device without one (found on the first run on a GPU).
    dev = torch.device(f"cuda:{local}" if device == "cuda" else device)
    if dev.type == "cuda":
        if world > 1 and device != "cuda":
            raise InvalidArgumentError(
                f"device: got {device!r} with WORLD_SIZE={world}, expected 'cuda' or 'auto' "
                "(each process takes GPU LOCAL_RANK)"
            )
        count = torch.cuda.device_count()
        if dev.index is None or dev.index >= count:
            where = f" (LOCAL_RANK={local})" if device == "cuda" else ""
            raise InvalidArgumentError(
                f"device: got {str(dev)!r}{where}, expected one of this machine's {count} CUDA "
                f"device(s), cuda:0 to cuda:{count - 1}"
            )
        torch.cuda.set_device(dev)
    if world <= 1:
        return _Group(0, 1, dev)
    if not dist.is_available():
        raise RgbdError(f"WORLD_SIZE={world} but this torch build has no torch.distributed")
    owns = not dist.is_initialized()
    if owns:
        from torch.distributed.distributed_c10d import PrefixStore
        from torch.distributed.rendezvous import rendezvous

        store, rank, size = next(rendezvous("env://"))
        # torchrun's store outlives a process group, and a re-created default group reuses its
        # key prefix: a second train() in the same processes could meet the first one's stale
        # rendezvous keys and hang. A prefix per call keeps them apart.
        store = PrefixStore(f"rgbd_rs.train/{next(_CALLS)}", store)
        backend = "nccl" if dev.type == "cuda" else "gloo"
        dist.init_process_group(backend=backend, store=store, rank=rank, world_size=size)
    return _Group(dist.get_rank(), dist.get_world_size(), dev, owns)
