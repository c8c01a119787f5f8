"""Desktop packaging files agree with each other and with pyproject."""

from __future__ import annotations

import configparser
import shutil
import subprocess
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "packaging"
APP_ID = "io.github.outcast.OutCast"


def test_desktop_entry_matches_metainfo_and_scripts():
    c = configparser.ConfigParser(interpolation=None)
    c.optionxform = str
    c.read(PKG / f"{APP_ID}.desktop")
    entry = c["Desktop Entry"]
    assert entry["Type"] == "Application" and entry["Icon"] == APP_ID
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert entry["Exec"].split()[0] in scripts
    assert scripts["outcast-gui"] == "app.main:main"
    root = ET.parse(PKG / f"{APP_ID}.metainfo.xml").getroot()
    assert root.findtext("id") == APP_ID
    assert root.find("launchable").text == f"{APP_ID}.desktop"
    assert "outcast-gui" in [b.text for b in root.iter("binary")]


def test_icons_render(qapp):
    from PySide6.QtGui import QImage
    from PySide6.QtSvg import QSvgRenderer

    for svg in (PKG / f"{APP_ID}.svg", ROOT / "app" / "resources" / "outcast.svg"):
        assert QSvgRenderer(str(svg)).isValid()
    png = QImage(str(PKG / f"{APP_ID}.png"))
    assert png.width() == png.height() == 256


@pytest.mark.skipif(shutil.which("appstreamcli") is None, reason="appstreamcli not installed")
def test_metainfo_validates():
    cmd = ["appstreamcli", "validate", "--no-net", str(PKG / f"{APP_ID}.metainfo.xml")]
    run = subprocess.run(cmd, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_pyinstaller_spec_names_existing_paths():
    spec = (PKG / "outcast-gui.spec").read_text()
    assert '"app" / "main.py"' in spec and (ROOT / "app" / "main.py").is_file()
    assert '"torch"' in spec  # excluded: the app never imports torch
