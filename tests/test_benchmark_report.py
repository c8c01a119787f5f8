"""``--report PATH`` of the benchmarks: what they print, with the run's date and machine."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.report import report_to  # noqa: E402


def test_report_copies_stdout(tmp_path, capsys):
    out = tmp_path / "deep" / "REPORT.md"
    with report_to(out, "bench_x"):
        print("drag 15.0 / s")
    assert "drag 15.0 / s" in capsys.readouterr().out  # still printed
    text = out.read_text()
    assert text.startswith("# OutCast benchmark report: bench_x\n")
    assert "CPU cores" in text and "```\ndrag 15.0 / s\n```" in text


def test_no_report_without_a_path(tmp_path, capsys):
    with report_to(None, "bench_x"):
        print("hello")
    assert capsys.readouterr().out == "hello\n" and not list(tmp_path.iterdir())
