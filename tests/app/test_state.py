"""Qt-free state: suns, project files, recent files, timings, time-lapse settings."""

from __future__ import annotations

import json

import pytest

from app.state import (
    PhotoIdentity,
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


def _project(**fields) -> str:
    return json.dumps({"outcast_project": 1, **fields})


@pytest.mark.parametrize(
    "data, field",
    [
        (_project(timelapse={"date": 20240101}), "timelapse.date"),
        (_project(timelapse={"date": "2024-13-01"}), "timelapse.date"),
        (_project(timelapse={"start": 5}), "timelapse.start"),
        (_project(timelapse={"end": "25:99"}), "timelapse.end"),
        (_project(timelapse={"frames": 10**12}), "timelapse.frames"),
        (_project(timelapse={"frames": 12.5}), "timelapse.frames"),
        (_project(timelapse={"latitude": "abc"}), "timelapse.latitude"),
        (_project(timelapse={"latitude": 91}), "timelapse.latitude"),
        (_project(timelapse={"longitude": [1]}), "timelapse.longitude"),
        (_project(timelapse={"heading": 10**400}), "timelapse.heading"),
        (_project(timelapse={"utc_offset": 99}), "timelapse.utc_offset"),
        (_project(timelapse={"fps": 1e-9}), "timelapse.fps"),
        (_project(timelapse={"fps": "fast"}), "timelapse.fps"),
        (_project(timelapse={"full_resolution": "yes"}), "timelapse.full_resolution"),
        (_project(timelapse={"easing": "bouncy"}), "timelapse.easing"),
        (_project(timelapse={"easing": ["linear"]}), "timelapse.easing"),
        (_project(timelapse={"kind": {}}), "timelapse.kind"),
        (_project(timelapse={"sweep_from": "east"}), "timelapse.sweep_from"),
        (_project(timelapse={"sweep_to": None}), "timelapse.sweep_to"),
        (_project(timelapse={"sweep_to": {"azimuth": 10**400, "elevation": 1}}),
         "timelapse.sweep_to"),
        (_project(timelapse=None), "timelapse"),
        (_project(timelapse=[]), "timelapse"),
        (_project(image=5), "image"),
        (_project(image_absolute=["x"]), "image_absolute"),
        (_project(depth_path={"a": 1}), "depth_path"),
        (_project(depth_source=3), "depth_source"),
        (_project(original_sun="noon"), "original_sun"),
        (_project(target_sun={"azimuth": "a", "elevation": 3}), "target_sun"),
        (_project(preset=["fast"]), "preset"),
        (_project(buffer_view={}), "buffer_view"),
        (_project(split=float("nan")), "split"),
        (_project(overlay_opacity=True), "overlay_opacity"),
        pytest.param('{"outcast_project": 1, "timelapse": ' + "[" * 100000 + "]" * 100000 + "}",
                     "nested", id="deeply-nested"),
    ],
)
def test_malformed_projects_name_the_bad_field(tmp_path, data, field):
    p = tmp_path / "x.outcast.json"
    p.write_text(data)
    with pytest.raises(ValueError) as info:
        load_project(p)
    message = str(info.value)
    assert "\n" not in message and field in message
    assert type(info.value) is ValueError


def test_oversized_project_file_is_refused(tmp_path):
    p = tmp_path / "x.outcast.json"
    p.write_text(_project(depth_source="x" * 2_000_000))
    with pytest.raises(ValueError, match="MB"):
        load_project(p)


def test_valid_timelapse_fields_still_load(tmp_path):
    p = tmp_path / "x.outcast.json"
    p.write_text(_project(timelapse={"heading": -90, "latitude": 45, "longitude": -120,
                                     "utc_offset": -8, "fps": 24, "frames": 2000,
                                     "date": "2024-06-21", "start": "06:30", "end": "",
                                     "full_resolution": True}))
    tl = load_project(p).timelapse
    assert tl.heading == 270.0 and tl.latitude == 45.0 and tl.fps == 24.0
    assert tl.frames == 2000 and tl.full_resolution is True


def test_easing_names_match_the_runtime():
    from app.state import EASING_NAMES
    from outcast_core.runtime.pipeline.timelapse import EASINGS

    assert EASING_NAMES == EASINGS


def test_exposure_names_match_the_runtime_and_bad_ones_do_not_load(tmp_path):
    from app.state import EXPOSURE_NAMES, ProjectState
    from outcast_core.runtime.pipeline.relight import EXPOSURES

    assert EXPOSURE_NAMES == EXPOSURES
    d = ProjectState(image_path="a.jpg", exposure="metered").to_dict()
    assert ProjectState.from_dict(d).exposure == "metered"
    del d["exposure"]  # a project saved before the setting: the photo's exposure
    assert ProjectState.from_dict(d).exposure == "photo"
    with pytest.raises(ValueError, match="exposure"):
        ProjectState.from_dict({**d, "exposure": "auto"})


def test_the_relighting_is_saved_and_bad_ones_do_not_load():
    """Step 2's "Relighting" travels in the project; a project saved before the choice opens
    with the learned relighting (the default then too); the names are the session's."""
    from app.state import RELIGHTINGS, ProjectState
    from outcast_core.runtime.pipeline.session import RELIGHT_MODES

    assert set(RELIGHTINGS) == set(RELIGHT_MODES) - {"auto"}
    d = ProjectState(image_path="a.jpg", relighting="physics").to_dict()
    assert ProjectState.from_dict(d).relighting == "physics"
    del d["relighting"]
    assert ProjectState.from_dict(d).relighting == "learned"
    with pytest.raises(ValueError, match="relighting"):
        ProjectState.from_dict({**d, "relighting": "auto"})


def test_a_project_records_its_photo_s_size_and_fingerprint(tmp_path):
    """What tells a project's photo from another file under its name (a user trial's project
    laid its suns over another photo); older projects, without it, still load."""
    import io

    import numpy as np
    from PIL import Image

    rng = np.random.default_rng(1)
    photo = (rng.random((48, 64, 3)) * 60 + np.linspace(0, 180, 64)[None, :, None]).astype(
        np.uint8)
    ident = PhotoIdentity.of(photo)
    assert (ident.width, ident.height) == (64, 48) and len(ident.fingerprint) == 128
    buf = io.BytesIO()
    Image.fromarray(photo).save(buf, "JPEG", quality=75)  # the same photo, saved again
    again = PhotoIdentity.of(np.asarray(Image.open(buf)))
    assert ident.mismatch(again) == ""
    assert ident.mismatch(PhotoIdentity.of(photo[:, ::-1])) == (
        "its picture is not the one the project was saved with")
    assert ident.mismatch(PhotoIdentity.of(photo.astype(np.float32) / 255.0)) == ""
    assert "48 × 64 pixels" in ident.mismatch(PhotoIdentity(48, 64, ident.fingerprint))
    assert ident.mismatch(PhotoIdentity(64, 48)) == ""  # no fingerprint: the size only
    state = ProjectState(image_path=str(tmp_path / "a.jpg"), photo=ident)
    path = save_project(state, tmp_path / "a.outcast.json")
    assert load_project(path).photo == ident
    data = json.loads(path.read_text())
    del data["photo"]
    assert ProjectState.from_dict(data).photo is None  # an older project
    for bad in ({"width": 64}, {"width": 0, "height": 48}, {"width": 64, "height": "48"},
                {"width": 64, "height": 48, "fingerprint": "zz"},
                {"width": 64, "height": 48, "fingerprint": " " * 128}, [64, 48]):
        with pytest.raises(ValueError, match="^photo: "):
            ProjectState.from_dict({**data, "photo": bad})
