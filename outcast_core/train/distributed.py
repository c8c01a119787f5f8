"""Training on several processes: ``torchrun`` + DistributedDataParallel, one data stream.

``torchrun --nproc_per_node=N`` (one process per GPU, or per group of CPU cores; add
``--nnodes``/``--rdzv-endpoint`` for several machines) starts ``N`` copies of ``outcast train``
with ``WORLD_SIZE``, ``RANK`` and ``LOCAL_RANK`` set. :func:`setup` reads them and joins the
process group (NCCL when the run is on CUDA, gloo on the CPU); a plain ``outcast train`` gets a
:class:`DistContext` of one process whose helpers do nothing, so single-process training is
unchanged.

How a run with ``W`` processes equals one process with the same global batch ``B``:

* **Sampler**: every rank holds the same :class:`~outcast_core.train.data.PairSampler` (same
  seed, same views, same generator state) and draws the whole global batch each step, exactly as
  one process does, but makes only its own contiguous ``B / W`` items (:meth:`DistContext.part`,
  :meth:`~outcast_core.train.data.PairSampler.skip` for the others' draws).
  The ranks see disjoint parts of each global batch that together are that batch; every random
  decision of a step (which depth ``S`` sees, the augmentations) is the one a single process
  makes, and the generator state in a checkpoint is the same on every rank, so a run resumes
  under any ``W``, or in one process. Each rank makes ``B / W`` items (numpy: 3.4 ms each at
  128 px on this 2-core machine, 4.4 ms with clouds); drawing another rank's item costs
  0.14 ms (1 ms with clouds, whose noise is drawn at the image's size).
* **Gradients**: DDP averages gradients over ranks. Losses that are means over items
  (``L1``, DSSIM, LSGAN, the scale-invariant log loss) then give the single-process gradient;
  losses normalised by a count over the batch (the shadow stage's weighted BCE, ``change_loss``)
  take the count summed over all ranks (:meth:`DistContext.global_sum`) and are scaled by ``W``.
* **Checkpoints**: rank 0 writes ``last.pt`` and ``log.jsonl``; every rank reads the checkpoint
  when it starts (resuming), and the logged losses are averaged over ranks first.
* **Stopping**: SIGTERM, the time limit and non-finite losses are agreed on by all ranks each
  step, so no rank waits in a collective for one that has left.
"""

from __future__ import annotations

import datetime
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import torch
import torch.distributed as tdist
from torch import nn
from torch.nn.parallel import DistributedDataParallel

#: How long a collective may wait for the slowest rank (data loading on a loaded machine).
TIMEOUT = datetime.timedelta(minutes=30)


def _env_int(name: str, default: int) -> int:
    value = os.environ.get(name, "")
    try:
        return int(value) if value else default
    except ValueError as exc:
        raise ValueError(f"expected an integer in ${name}, got {value!r}") from exc


def resolve_device(name: str, local_rank: int = 0) -> torch.device:
    """The training device of a config's ``device`` setting.

    Args:
        name: ``auto`` (CUDA when available, else the CPU), ``cpu``, ``cuda``, or ``cuda:I``.
        local_rank: the process's rank on its machine: ``cuda`` means ``cuda:LOCAL_RANK``.

    Returns:
        The device.

    Raises:
        ValueError: an unknown name, or CUDA asked for where there is none.
    """
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cpu":
        return torch.device("cpu")
    if name == "cuda" or name.startswith("cuda:"):
        if not torch.cuda.is_available():
            raise ValueError(f"expected a machine with CUDA for device {name!r}, got none")
        return torch.device(f"cuda:{local_rank}" if name == "cuda" else name)
    raise ValueError(f"expected device auto, cpu, cuda or cuda:I, got {name!r}")


@dataclass
class DistContext:
    """Where this process stands in a (possibly one-process) run, and its collectives.

    Attributes:
        rank: global rank (0 writes checkpoints and logs).
        world: number of processes.
        local_rank: rank on this machine (its GPU).
        device: the device this process trains on.
    """

    rank: int = 0
    world: int = 1
    local_rank: int = 0
    device: torch.device = field(default_factory=lambda: torch.device("cpu"))

    @property
    def enabled(self) -> bool:
        """More than one process: collectives run."""
        return self.world > 1

    @property
    def is_main(self) -> bool:
        """Rank 0: the one checkpoint and log writer."""
        return self.rank == 0

    def check_batch(self, batch: int) -> None:
        """Raise ``ValueError`` unless the global batch splits evenly over the ranks."""
        if batch % self.world:
            raise ValueError(
                f"expected a global batch divisible by the {self.world} processes, got {batch}"
            )

    def part(self, batch: int) -> slice | None:
        """This rank's items ``[rank * B / W, (rank + 1) * B / W)`` of a global batch ``B``
        (``None``, the whole batch, in one process)."""
        if not self.enabled:
            return None
        self.check_batch(batch)
        n = batch // self.world
        return slice(self.rank * n, (self.rank + 1) * n)

    def global_sum(self, x: torch.Tensor) -> torch.Tensor:
        """``x`` summed over ranks, without gradient (``x`` itself, detached, in one process)."""
        x = x.detach()
        if not self.enabled:
            return x
        x = x.clone()
        tdist.all_reduce(x)
        return x

    def mean_logs(self, logs: dict[str, float]) -> dict[str, float]:
        """Each logged value averaged over ranks (the global batch's value for mean losses).

        Every rank must log the same keys in a step (they take the same branches).
        """
        if not self.enabled or not logs:
            return logs
        keys = sorted(logs)
        t = torch.tensor([logs[k] for k in keys], dtype=torch.float64, device=self.device)
        tdist.all_reduce(t)
        return dict(zip(keys, (t / self.world).tolist(), strict=True))

    def any(self, flag: bool) -> bool:
        """True on every rank when ``flag`` is true on any of them."""
        if not self.enabled:
            return flag
        t = torch.tensor([1.0 if flag else 0.0], device=self.device)
        tdist.all_reduce(t, op=tdist.ReduceOp.MAX)
        return bool(t.item() > 0)

    def broadcast(self, obj: Any) -> Any:
        """Rank 0's ``obj`` (picklable) on every rank."""
        if not self.enabled:
            return obj
        box = [obj]
        tdist.broadcast_object_list(box, src=0, device=self.device)
        return box[0]

    def on_main(self, fn: Callable[[], Any]) -> Any:
        """``fn()`` run on rank 0 and its result (picklable) handed to every rank; an exception
        it raises is raised on every rank (none waits for a result that never comes)."""
        if not self.enabled:
            return fn()
        result: tuple[bool, Any] = (True, None)
        if self.is_main:
            try:
                result = (True, fn())
            except Exception as exc:  # noqa: BLE001 - re-raised on every rank below
                result = (False, exc)
        ok, value = self.broadcast(result)
        if not ok:
            raise value
        return value

    def barrier(self) -> None:
        """Wait for every rank (nothing in one process)."""
        if self.enabled:
            if self.device.type == "cuda":
                tdist.barrier(device_ids=[self.device.index or 0])
            else:
                tdist.barrier()

    def wrap(self, module: nn.Module, find_unused_parameters: bool = False) -> nn.Module:
        """``module`` under DistributedDataParallel (``module`` itself in one process).

        Every parameter that requires a gradient must get one in each backward through the
        wrapper, or ``find_unused_parameters`` must be set.
        """
        if not self.enabled:
            return module
        ids = [self.device.index or 0] if self.device.type == "cuda" else None
        return DistributedDataParallel(module, device_ids=ids,
                                       find_unused_parameters=find_unused_parameters)


def setup(device: str = "auto") -> DistContext:
    """Join the ``torchrun`` process group when there is one, and pick the device.

    Reads ``WORLD_SIZE``, ``RANK``, ``LOCAL_RANK`` (set by ``torchrun``; a plain process has
    none and gets a one-process context). The backend is NCCL on CUDA, gloo on the CPU; a group
    that is already initialised (a second trainer in one job) is reused; :func:`shutdown`
    leaves it.

    Args:
        device: the config's ``device`` (see :func:`resolve_device`).

    Returns:
        The context.
    """
    world = _env_int("WORLD_SIZE", 1)
    rank = _env_int("RANK", 0)
    local_rank = _env_int("LOCAL_RANK", 0)
    dev = resolve_device(device, local_rank if world > 1 else 0)
    if dev.type == "cuda":
        torch.cuda.set_device(dev)
    if world <= 1:
        return DistContext(device=dev)
    if not tdist.is_initialized():
        backend = "nccl" if dev.type == "cuda" else "gloo"
        tdist.init_process_group(backend=backend, timeout=TIMEOUT,
                                 **({"device_id": dev} if dev.type == "cuda" else {}))
    if tdist.get_world_size() != world or tdist.get_rank() != rank:
        raise RuntimeError(
            f"expected the process group to match WORLD_SIZE={world} RANK={rank}, got "
            f"{tdist.get_world_size()} and {tdist.get_rank()}"
        )
    return DistContext(rank=rank, world=world, local_rank=local_rank, device=dev)


def is_main_process() -> bool:
    """Rank 0 of a ``torchrun`` job (``RANK``), or a plain process."""
    return _env_int("RANK", 0) == 0


def shutdown() -> None:
    """Leave the process group, if this process joined one (the end of ``outcast train``)."""
    if tdist.is_available() and tdist.is_initialized():
        tdist.destroy_process_group()


def param_names_without_grad(modules: Sequence[nn.Module]) -> list[str]:
    """Names of trainable parameters whose ``.grad`` is ``None`` (after a backward): the ones
    DistributedDataParallel would need ``find_unused_parameters`` for."""
    return [f"{i}.{name}" for i, m in enumerate(modules)
            for name, p in m.named_parameters() if p.requires_grad and p.grad is None]
