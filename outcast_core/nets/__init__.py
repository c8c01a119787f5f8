"""PyTorch networks of OutCast: ``Z`` depth, ``S`` shadows, ``R``, ``L``, ``A`` and ablations.

:func:`build` makes any of them from a name and keyword arguments (what configs and checkpoints
store), so the trainer, the exporter and the evaluation share one table.
"""

from __future__ import annotations

from typing import Any

from torch import nn

from outcast_core.nets.depth import DepthNet
from outcast_core.nets.relight import PatchDiscriminator, Pix2PixRelightNet, RefineNet, RelightNet
from outcast_core.nets.shadow import Shadow2DNet, ShadowNet
from outcast_core.nets.sun import SunNet

#: Network kind -> class. The kinds are also the shipped ONNX names.
NETWORKS: dict[str, type[nn.Module]] = {
    "depth": DepthNet,
    "shadow": ShadowNet,
    "shadow_2d": Shadow2DNet,
    "refine": RefineNet,
    "relight": RelightNet,
    "relight_pix2pix": Pix2PixRelightNet,
    "critic": PatchDiscriminator,
    "sun": SunNet,
}


def build(kind: str, **kwargs: Any) -> nn.Module:
    """Instantiate the network ``kind`` (a key of :data:`NETWORKS`) with ``kwargs``."""
    if kind not in NETWORKS:
        raise ValueError(f"expected a network kind in {sorted(NETWORKS)}, got {kind!r}")
    return NETWORKS[kind](**kwargs)


__all__ = [
    "NETWORKS", "DepthNet", "PatchDiscriminator", "Pix2PixRelightNet", "RefineNet", "RelightNet",
    "Shadow2DNet", "ShadowNet", "SunNet", "build",
]
