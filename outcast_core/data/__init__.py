"""Synthetic outdoor scenes and path-traced training data (Mitsuba 3, imported lazily).

``load_view`` and the data-set helpers need only numpy; scene rendering imports Mitsuba on use.
"""

from outcast_core.data.dataset import (
    STANDARD_SETS,
    cache_dir,
    default_set_dir,
    iter_views,
    list_views,
    load_view,
    make_dataset,
)

__all__ = [
    "STANDARD_SETS",
    "cache_dir",
    "default_set_dir",
    "iter_views",
    "list_views",
    "load_view",
    "make_dataset",
]
