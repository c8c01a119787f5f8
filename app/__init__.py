"""OutCast's desktop app (PySide6). Imports ``outcast_core.runtime`` only; never torch."""
