"""Test-wide settings: hypothesis is derandomised on CI so a run is reproducible; locally it
explores new examples on every run (and keeps failures in its database)."""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
