"""Qt-free state: suns, project files, recent files, timings, time-lapse settings."""

from __future__ import annotations

import json

import pytest

from app.state import (
    ProjectState,
    RecentFiles,
    StageTimings,
    Step,
    Sun,
    TimelapseSettings,
    is_project_file,
    load_project,
    project_path_for,
    save_project,
)
from app.timelapse_dialog import samples_for


def test_sun_normalises_and_validates():
    assert Sun(-30, 20).as_tuple() == (330.0, 20.0)
    with pytest.raises(ValueError, match="elevation"):
        Sun(0, 95)
    with pytest.raises(ValueError, match="finite"):
        Sun(float("nan"), 10)
    assert Sun.from_any({"azimuth": 10, "elevation": 5}) == Sun(10, 5)
    assert Sun.from_any([10, 5]) == Sun(10, 5)
    assert Sun.from_any(None) is None
    with pytest.raises(ValueError, match="azimuth"):
        Sun.from_any({"az": 1})


def test_project_round_trip(tmp_path):
    image = tmp_path / "photos" / "beach.jpg"
    image.parent.mkdir()
    image.write_bytes(b"x")
    state = ProjectState(
        image_path=str(image),
        preset="accurate",
        depth_source="model",
        original_sun=Sun(120.5, 40.0),
        target_sun=Sun(250.0, 15.0),
        overlay_opacity=0.3,
        split=0.7,
        buffer_view="all",
        timelapse=TimelapseSettings(
            kind="sun",
            frames=20,
            latitude=7.8,
            longitude=98.3,
            heading=163.7,
            date="2019-08-21",
            start="08:00",
            end="16:30",
            format="webp",
        ),  # fmt: skip
    )
    path = save_project(state, project_path_for(image))
    assert path == image.with_name("beach.outcast.json") and is_project_file(path)
    data = json.loads(path.read_text())
    assert data["image"] == "beach.jpg"  # relative to the project file
    loaded = load_project(path)
    assert loaded == state
    assert loaded.step is Step.RELIGHT
    assert [p.name for p in path.parent.iterdir()] == sorted(["beach.jpg", "beach.outcast.json"])


def test_project_moved_with_photo_still_opens(tmp_path):
    a = tmp_path / "a"
    a.mkdir()
    (a / "p.jpg").write_bytes(b"x")
    save_project(ProjectState(image_path=str(a / "p.jpg")), a / "p.outcast.json")
    b = tmp_path / "b"
    a.rename(b)
    assert load_project(b / "p.outcast.json").image_path == str((b / "p.jpg").resolve())


@pytest.mark.parametrize(
    "data, match",
    [
        ("not json", "JSON"),
        (json.dumps({"image": "x.jpg"}), "outcast_project"),
        (json.dumps({"outcast_project": 99}), "version"),
        (json.dumps({"outcast_project": 1, "preset": "ultra"}), "preset"),
        (json.dumps({"outcast_project": 1, "split": 3}), "split"),
        (json.dumps({"outcast_project": 1, "timelapse": {"frames": 1}}), "frames"),
        (json.dumps({"outcast_project": 1, "original_sun": {"azimuth": 1}}), "elevation"),
    ],
)
def test_bad_projects_raise_value_error(tmp_path, data, match):
    p = tmp_path / "x.outcast.json"
    p.write_text(data)
    with pytest.raises(ValueError, match=match):
        load_project(p)


def test_recent_files(tmp_path):
    r = RecentFiles(limit=3)
    for name in ["a", "b", "c", "a", "d"]:
        r.add(str(tmp_path / name))
    assert [p.rsplit("/", 1)[1] for p in r.paths()] == ["d", "a", "c"]
    r.remove(str(tmp_path / "a"))
    assert RecentFiles(r.paths()).paths() == r.paths()


def test_timings_summary():
    t = StageTimings()
    t.update({"depth": 0.4123, "shadow": 0.031, "bad": float("nan")})
    assert t.summary() == "depth 0.41 s · shadow 31 ms"


def test_sweep_samples_go_the_chosen_way():
    s = TimelapseSettings(sweep_from=Sun(80, 10), sweep_to=Sun(280, 40), frames=5, easing="linear")
    shorter = [x.azimuth for x in samples_for(s)]
    assert shorter == pytest.approx([80.0, 40.0, 0.0, 320.0, 280.0])  # through the front
    s.way = "longer"
    longer = [x.azimuth for x in samples_for(s)]
    assert longer == pytest.approx([80.0, 130.0, 180.0, 230.0, 280.0])  # behind the camera
    assert longer[0] == pytest.approx(80.0) and longer[-1] == pytest.approx(280.0)


def test_sun_path_needs_place_and_heading():
    s = TimelapseSettings(kind="sun", frames=4, date="2019-08-21")
    with pytest.raises(ValueError, match="latitude"):
        samples_for(s)
    s.latitude, s.longitude = 7.83, 98.3
    with pytest.raises(ValueError, match="heading"):
        samples_for(s)
    s.heading = 163.7
    path = samples_for(s)
    assert len(path) == 4 and path[0].time is not None
