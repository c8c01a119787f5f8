"""Entry point of ``outcast-gui``: ``outcast-gui [PHOTO_OR_PROJECT] [--preset NAME]``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="outcast-gui", description="OutCast: relight outdoor photos with cast shadows."
    )
    p.add_argument("path", nargs="?", help="a photo or an .outcast.json project to open")
    p.add_argument(
        "--preset", choices=("fast", "balanced", "accurate"), default="balanced",
        help="quality preset (default: balanced)",
    )  # fmt: skip
    p.add_argument(
        "--classic", action="store_true",
        help="use Direct shadows and physics relighting even when learned models are installed",
    )  # fmt: skip
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Start the application; returns the exit status."""
    args = build_parser().parse_args(argv)
    from PySide6.QtWidgets import QApplication

    from app.main_window import APP_NAME, MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName(APP_NAME)
    app.setOrganizationName(APP_NAME)
    app.setApplicationDisplayName(APP_NAME)
    app.setDesktopFileName("io.github.outcast.OutCast")
    window = MainWindow(preset=args.preset, session_mode="classic" if args.classic else "auto")
    window.show()
    if args.path:
        window.open_path(args.path)
    return int(app.exec())


if __name__ == "__main__":
    sys.exit(main())
