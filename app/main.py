"""Entry point of ``outcast-gui``: ``outcast-gui [PHOTO_OR_PROJECT] [--preset NAME]``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any


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
    # Packaging smoke tests (app/self_test.py): open PATH, align from EXIF, export a still.
    p.add_argument("--self-test", metavar="OUT.png", default=None, help=argparse.SUPPRESS)
    return p


def quit_on_sigterm(app: Any, window: Any) -> Any:
    """Make SIGTERM quit like File > Quit without questions, then exit with status 143.

    Running work is cancelled, so an export removes its partial files (``.NAME.part*``) as
    Ctrl+C does for the command line. Qt's event loop runs in C++, so a Python signal handler
    only runs when Python gets control: a timer gives it that 5 times a second.

    Returns:
        The timer (keep a reference).
    """
    import signal

    from PySide6.QtCore import QTimer

    def quit_now() -> None:
        window.close_without_asking()
        app.exit(143)

    def handler(signum: int, frame: object) -> None:
        # Python runs the handler between any two bytecodes of the GUI thread, in the middle of
        # a slot too (a photo that has just loaded, asking the worker for its overlay): the
        # window closes once that slot has returned, from the event loop.
        QTimer.singleShot(0, quit_now)

    signal.signal(signal.SIGTERM, handler)
    timer = QTimer(window)
    timer.timeout.connect(lambda: None)
    timer.start(200)
    return timer


def main(argv: Sequence[str] | None = None) -> int:
    """Start the application; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        from PySide6.QtWidgets import QApplication
    except ImportError as exc:
        print(f"outcast-gui: error: the desktop app needs PySide6 ({exc}); install it with "
              "pip install 'outcast[gui]'", file=sys.stderr)
        return 2
    if args.self_test:
        from app.self_test import main_self_test

        return main_self_test(args.path, args.self_test, args.preset)

    from app.main_window import APP_NAME, MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName(APP_NAME)
    app.setOrganizationName(APP_NAME)
    app.setApplicationDisplayName(APP_NAME)
    app.setDesktopFileName("io.github.outcast.OutCast")
    window = MainWindow(preset=args.preset, session_mode="classic" if args.classic else "auto")
    window.show()
    timer = quit_on_sigterm(app, window)
    if args.path:
        # Opened from inside the event loop: a file that cannot be opened shows a modal error,
        # and a SIGTERM then ends that dialog's loop and this one together. Opened before
        # app.exec(), the signal ended only the dialog's loop, and the app ran on with no
        # window (a user trial: `outcast-gui text.jpg`, then SIGTERM).
        from PySide6.QtCore import QTimer

        QTimer.singleShot(0, lambda: window.open_path(args.path))
    status = int(app.exec())
    timer.stop()
    return status


if __name__ == "__main__":
    sys.exit(main())
