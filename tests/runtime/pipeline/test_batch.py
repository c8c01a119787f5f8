"""``outcast batch``: a folder of photos relit, de-shadowed or made into time-lapses."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.io.imageio import read_image
from outcast_core.runtime.pipeline.batch import (
    PROJECT_SUFFIX,
    RECORD_NAME,
    BatchJob,
    BatchOptions,
    plan_batch,
    project_suns,
    read_targets_csv,
    run_batch,
    run_job,
)
from outcast_core.runtime.pipeline.timelapse import exif_sun

ROOT = Path(__file__).resolve().parents[3]
SAMPLE = ROOT / "samples" / "exif_003_th_pool.jpg"
#: The sample's sun from its EXIF (README: azimuth 273, elevation 67 relative to the camera).
SAMPLE_SUN = (273.5, 66.8)


def _photo(path: Path, seed: int, size: tuple[int, int] = (64, 48)) -> Path:
    """A small outdoor-ish photo: sky on top, ground below, a dark patch."""
    rng = np.random.default_rng(seed)
    w, h = size
    img = np.empty((h, w, 3), np.float32)
    img[: h // 2] = (0.5, 0.65, 0.95)
    img[h // 2 :] = (0.6, 0.5, 0.4)
    img[3 * h // 4 :, w // 4 : w // 2] *= 0.4
    img = np.clip(img + rng.normal(0, 0.02, img.shape), 0, 1)
    Image.fromarray((img * 255).astype(np.uint8)).save(path)
    return path


def _exif_photo(path: Path) -> Path:
    """The sample photo, small, with its EXIF (GPS, time, heading)."""
    with Image.open(SAMPLE) as im:
        exif = im.info["exif"]
        im.resize((80, 60)).save(path, exif=exif)
    return path


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """Ten photos, one of them a corrupt JPEG, and a text file that is not a photo."""
    d = tmp_path / "in"
    d.mkdir()
    for i in range(9):
        _photo(d / f"p{i}.{'png' if i % 3 else 'jpg'}", i)
    (d / "p9.jpg").write_bytes(b"\xff\xd8\xff\xe0 this is not a JPEG")
    (d / "notes.txt").write_text("not a photo")
    return d


def _mtimes(folder: Path) -> dict[str, int]:
    return {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}


def test_folder_with_a_corrupt_photo_is_done_and_resumable(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    args = ["batch", str(folder), "-o", str(out), "--from", "200,40", "--to", "90,30",
            "--preset", "fast", "--workers", "2"]
    assert main(args) == 2
    err = capsys.readouterr().err
    names = sorted(p.name for p in out.iterdir())
    assert names == [RECORD_NAME] + [f"p{i}.jpg" for i in range(9)]
    failed = [line for line in err.splitlines() if ": failed: " in line]
    assert len(failed) == 1 and "p9.jpg" in failed[0] and "cannot read image" in failed[0]
    assert "9 done, 0 skipped (already done), 1 failed" in err
    assert err.strip().splitlines()[-1] == "outcast batch: error: 1 of 10 photos failed: p9.jpg"
    assert "Traceback" not in err
    # A file that is not a photo is named, not passed over in silence (a user trial).
    assert "outcast batch: note: 1 file is not a photo and was left alone: notes.txt\n" in err
    assert "sub-folder" not in err

    before = _mtimes(out)
    del before[RECORD_NAME]  # the record may be rewritten; the outputs may not
    assert main(args) == 2  # resumed: the finished photos are skipped
    err = capsys.readouterr().err
    assert "0 done, 9 skipped (already done), 1 failed" in err
    assert {k: v for k, v in _mtimes(out).items() if k != RECORD_NAME} == before

    _photo(folder / "p9.jpg", 9)  # the photo is fixed: only it is done
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "1 done, 9 skipped (already done), 0 failed" in err
    # The header counts as the lines do ([1/10] to [10/10]; a user trial read "processing 1
    # photo" above them as a contradiction).
    assert "processing 1 of 10 photos (relight) with 1 worker(s); 9 already done" in err
    assert "[10/10]" in err
    after = {k: v for k, v in _mtimes(out).items() if k not in ("p9.jpg", RECORD_NAME)}
    assert after == before
    hidden = [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert hidden == [RECORD_NAME]  # no partial files

    assert main([*args, "--force", "--workers", "1", "-q"]) == 0  # --force redoes them all
    assert capsys.readouterr().err == ""
    assert all(_mtimes(out)[k] != v for k, v in before.items())


def test_a_rerun_with_other_settings_keeps_the_outputs_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    photos, out = tmp_path / "in", tmp_path / "out"
    photos.mkdir()
    for i in range(2):
        _photo(photos / f"p{i}.jpg", i)
    args = ["batch", str(photos), "-o", str(out), "--from", "200,40", "--preset", "fast", "-q"]
    assert main([*args, "--to", "90,30"]) == 0
    before = _mtimes(out)
    assert main([*args, "--to", "180,20"]) == 2  # another sun: not "already done"
    err = capsys.readouterr().err
    assert "0 done, 0 skipped (already done), 2 kept (made otherwise)" in err
    assert "use --force to redo them" in err.strip().splitlines()[-1]
    # Each photo's line says what was different, from the record (a user trial: "other
    # settings" said too little).
    assert main([*args[:-1], "--to", "180,20"]) == 2
    kept = [line for line in capsys.readouterr().err.splitlines() if ": kept: " in line]
    assert len(kept) == 2 and all(line.endswith(
        "the output exists and was made with --to 90,30 instead of 180,20; use --force to "
        "redo it") for line in kept)
    assert _mtimes(out) == before  # nothing overwritten
    assert main([*args, "--to", "90,30"]) == 0  # the first settings: done already
    assert main([*args, "--to", "180,20", "--force"]) == 0
    assert main([*args, "--to", "180,20"]) == 0  # now recorded with the new sun
    (out / "p0.jpg").write_bytes((out / "p1.jpg").read_bytes())  # no record says how: kept
    (out / RECORD_NAME).write_text("not json")
    assert main([*args, "--to", "180,20"]) == 2


def test_adding_from_redoes_only_the_photos_it_gives_a_sun(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A photo with an EXIF sun was done; one without failed ("no --from"). Rerun with
    ``--from``, as the message says: the EXIF photo's output is still done (``--from`` does
    not decide its sun), only the other is made; a project then would come before both."""
    photos, out = tmp_path / "in", tmp_path / "out"
    photos.mkdir()
    _exif_photo(photos / "exif.jpg")
    _photo(photos / "plain.png", 1)
    args = ["batch", str(photos), "-o", str(out), "--to", "90,30", "--preset", "fast",
            "--mode", "classic", "--sources", "project,exif,given"]  # no automatic sun
    assert main(args) == 2
    assert "1 done, 0 skipped (already done), 1 failed" in capsys.readouterr().err
    before = _mtimes(out)
    assert main([*args, "--from", "120,39"]) == 0
    err = capsys.readouterr().err
    assert "1 done, 1 skipped (already done)" in err and "kept (made otherwise)" not in err
    assert _mtimes(out)["exif.jpg"] == before["exif.jpg"]
    assert main([*args, "--from", "200,20"]) == 2  # the plain photo's sun came from --from
    err = capsys.readouterr().err
    assert "1 kept (made otherwise)" in err and "plain.png" in err.strip().splitlines()[-1]


def test_from_counts_for_an_output_only_when_it_could_decide_its_sun() -> None:
    from dataclasses import replace

    from outcast_core.runtime.pipeline.batch import (
        FROM_SUN_NOT_USED,
        job_settings,
        settings_for_source,
    )

    opts = BatchOptions(kind="deshadow", from_sun=(120.0, 39.0))  # project, exif, given, auto
    job = BatchJob("a.jpg", "out/a.jpg")
    job = replace(job, settings=job_settings(job, opts))

    def used(source: str, options: BatchOptions = opts) -> bool:
        return FROM_SUN_NOT_USED not in settings_for_source(job, options, source)

    assert not used("project") and not used("exif") and not used("csv")
    assert used("given") and used("auto") and used("")  # after given; unknown: used
    assert not used("sun in the frame")  # stands where exif stands
    auto_first = replace(opts, sources=("auto", "given", "exif"))
    assert not used("auto", auto_first) and used("exif", auto_first)
    assert used("sun in the frame", replace(opts, sources=("given", "exif")))


def test_sun_sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from app.state import ProjectState, Sun, save_project

    d = tmp_path / "in"
    d.mkdir()
    plain = _photo(d / "plain.png", 1)
    aligned = _photo(d / "aligned.png", 2)
    save_project(ProjectState(image_path=str(aligned), original_sun=Sun(120.0, 35.0),
                              target_sun=Sun(300.0, 20.0)), d / f"aligned{PROJECT_SUFFIX}")
    exif = _exif_photo(d / "exif.jpg")
    opts = BatchOptions(kind="relight", from_sun=(200.0, 40.0), preset="fast", mode="classic")
    jobs, early = plan_batch(d, tmp_path / "out", opts)
    assert early == [] and [Path(j.image).name for j in jobs] == [
        "aligned.png", "exif.jpg", "plain.png"]
    got = {Path(r.image).name: r for r in run_batch(jobs, opts)}
    assert got["aligned.png"].sun_source == "project"
    assert got["aligned.png"].from_sun == (120.0, 35.0)
    assert got["aligned.png"].to_sun == (300.0, 20.0)  # the project's new sun
    assert got["exif.jpg"].status == "failed" and "no new sun" in got["exif.jpg"].message
    # The EXIF sun in the camera's frame: its tilt from the ground plane (this thumbnail is
    # too small to hold one: a found plane stands in).
    from outcast_core.runtime.pipeline import auto_sun

    monkeypatch.setattr(auto_sun, "ground_plane_tilt",
                        lambda session: (-12.0, 3.0, "ground plane"))
    r = run_job(BatchJob(str(exif), str(tmp_path / "o" / "e.png"), to_sun=(90.0, 30.0)), opts)
    assert (r.status, r.sun_source) == ("done", "exif")
    cam = r.details["camera"]
    assert (cam["source"], cam["pitch"], cam["roll"]) == ("ground plane", -12.0, 3.0)
    tilted = exif_sun(read_image(exif).exif, tilt=(cam["pitch"], cam["roll"]))
    assert r.from_sun == pytest.approx(tilted, abs=0.2)
    assert exif_sun(read_image(exif).exif) == pytest.approx(SAMPLE_SUN, abs=0.2)  # level
    assert got["plain.png"].status == "failed"
    assert got["aligned.png"].status == "done"
    with Image.open(tmp_path / "out" / "aligned.jpg") as im:
        assert im.size == (64, 48)

    given = BatchOptions(kind="relight", sources=("given",), from_sun=(10.0, 50.0),
                         to_sun=(90.0, 30.0), preset="fast", mode="classic", force=True)
    r = run_job(BatchJob(str(exif), str(tmp_path / "o" / "x.png")), given)
    assert (r.status, r.sun_source, r.from_sun) == ("done", "given", (10.0, 50.0))
    none = BatchOptions(kind="deshadow", sources=("project", "exif"), preset="fast")
    r = run_job(BatchJob(str(plain), str(tmp_path / "o" / "y.png")), none)
    assert r.status == "failed" and r.message.startswith("no original sun: no plain")
    assert not (tmp_path / "o" / "y.png").exists()


def test_project_reader_matches_the_app(tmp_path: Path) -> None:
    from app import state

    assert state.PROJECT_SUFFIX == PROJECT_SUFFIX
    photo = _photo(tmp_path / "a.png", 0)
    depth = tmp_path / "maps" / "a_depth.npy"
    project = state.ProjectState(image_path=str(photo), original_sun=state.Sun(-30.0, 12.5),
                                 depth_path=str(depth))
    state.save_project(project, state.project_path_for(photo))
    assert project_suns(photo) == ((330.0, 12.5), None, str(depth))
    assert project_suns(_photo(tmp_path / "b.png", 1)) == (None, None, "")
    state.project_path_for(photo).write_text(json.dumps({"outcast_project": 1, "image": "c.png"}))
    with pytest.raises(ValueError, match="is for 'c.png'"):
        project_suns(photo)


def test_batch_refuses_a_project_saved_with_another_picture(tmp_path: Path) -> None:
    """The app asks before laying a project's suns and corrections over another picture of
    the same name (Cancel by default); batch did not check at all (a review). Now the photo
    fails, saying why, before the slow part; the same photo, or a project from before the
    app recorded the photo, relights."""
    from app import state

    photo = _photo(tmp_path / "a.png", 0)
    identity = state.PhotoIdentity.of(read_image(photo, keep_uint8=True).image_srgb)
    project = state.ProjectState(image_path=str(photo), photo=identity,
                                 original_sun=state.Sun(200.0, 40.0),
                                 target_sun=state.Sun(90.0, 30.0))
    state.save_project(project, state.project_path_for(photo))
    opts = BatchOptions(kind="relight", preset="fast", mode="classic", force=True)
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "same.png")), opts)
    assert r.status == "done", r.message
    with Image.open(photo) as im:  # another picture under the same name: upside down
        im.transpose(Image.Transpose.FLIP_TOP_BOTTOM).save(photo)
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "other.png")), opts)
    assert r.status == "failed" and "does not look like the one project" in r.message
    assert "(its picture" not in r.message  # (said once: a user trial read it twice)
    assert "a.outcast.json" in r.message and not (tmp_path / "o" / "other.png").exists()
    _photo(photo, 0, size=(48, 64))  # another size
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "other.png")), opts)
    assert r.status == "failed" and "48 × 64 pixels" in r.message
    state.save_project(dataclasses.replace(project, photo=None),
                       state.project_path_for(photo))  # saved before identities: not checked
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "old.png")), opts)
    assert r.status == "done", r.message
    data = json.loads(state.project_path_for(photo).read_text())
    data["photo"] = {"width": -1, "height": 2}
    state.project_path_for(photo).write_text(json.dumps(data))
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "bad.png")), opts)
    assert r.status == "failed" and "photo:" in r.message


def test_batch_takes_the_projects_exposure_unless_told(tmp_path: Path,
                                                       exposures_relit) -> None:
    """A project saved with "Meter the new light" is batch-relit metered, as its suns are
    taken from it; `--exposure` says otherwise (a user trial's came out unmetered)."""
    from app import state
    from outcast_core.runtime.pipeline import batch

    photo = _photo(tmp_path / "a.png", 0)
    assert batch.project_exposure(photo) is None
    state.save_project(state.ProjectState(image_path=str(photo), original_sun=state.Sun(
        200.0, 40.0), target_sun=state.Sun(90.0, 30.0), exposure="metered"),
        state.project_path_for(photo))
    assert batch.project_exposure(photo) == "metered"
    seen = exposures_relit
    for exposure, name in ((None, "x.png"), ("photo", "y.png")):
        opts = BatchOptions(kind="relight", preset="fast", exposure=exposure)
        r = run_job(BatchJob(str(photo), str(tmp_path / "o" / name)), opts)
        assert r.status == "done", r.message
    assert seen == ["metered", "photo"]
    state.project_path_for(photo).write_text(json.dumps(
        {"outcast_project": 1, "image": "a.png", "exposure": "auto"}))
    with pytest.raises(ValueError, match="exposure"):
        batch.project_exposure(photo)


def _photo_with_old_project(tmp_path: Path) -> tuple[Path, Path, Path, dict]:
    """A folder (``in``) with one photo and its project as the app saved it before the step-2
    settings were kept (suns only): ``(folder, photo, project file, its JSON)``."""
    from app import state

    d = tmp_path / "in"
    d.mkdir()
    photo = _photo(d / "a.png", 0)
    project = state.project_path_for(photo)
    data = {"outcast_project": 1, "image": "a.png",
            "original_sun": {"azimuth": 200.0, "elevation": 40.0},
            "target_sun": {"azimuth": 90.0, "elevation": 30.0}}
    project.write_text(json.dumps(data))
    return d, photo, project, data


def test_batch_takes_the_projects_light_unless_told(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A project saved with step 2's "Keep the photo's light" is batch-relit and time-lapsed
    in the photo's light, as its suns are taken from it; `--keep-light` / `--no-keep-light`
    override it; a light the app does not write is refused."""
    from app import state
    from outcast_core.runtime.pipeline import batch, timelapse
    from outcast_core.runtime.pipeline.session import RelightSession

    seen: list[bool] = []  # the session's daylight at each relighting / time-lapse
    real = RelightSession.relight_full
    monkeypatch.setattr(RelightSession, "relight_full",
                        lambda self, w, **kw: seen.append(self.daylight) or real(self, w, **kw))
    monkeypatch.setattr(timelapse, "render_timelapse",
                        lambda session, *a, **kw: seen.append(session.daylight))
    d, photo, project, data = _photo_with_old_project(tmp_path)
    assert batch.read_project(photo).daylight is None  # a project from before the setting

    def save(daylight: bool) -> None:
        state.save_project(state.ProjectState(
            image_path=str(photo), original_sun=state.Sun(200.0, 40.0),
            target_sun=state.Sun(90.0, 30.0), daylight=daylight), project)

    save(daylight=False)
    assert batch.read_project(photo).daylight is False
    for i, keep_light in enumerate((None, False, True)):
        opts = BatchOptions(kind="relight", preset="fast", keep_light=keep_light)
        r = run_job(BatchJob(str(photo), str(tmp_path / "o" / f"{i}.png")), opts)
        assert r.status == "done", r.message
    assert seen == [False, True, False]
    sweep = ((0.0, 30.0), (90.0, 30.0))
    for keep_light in (None, False):
        opts = BatchOptions(kind="timelapse", sweep=sweep, frames=2, keep_light=keep_light)
        r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "t.mp4")), opts)
        assert r.status == "done", r.message
    assert seen[3:] == [False, True]
    # The command line: --keep-light over a project in the new sun's daylight, and back.
    save(daylight=True)
    seen.clear()
    args = ["batch", str(d), "--preset", "fast", "-q"]
    assert main([*args, "-o", str(tmp_path / "day")]) == 0
    assert main([*args, "-o", str(tmp_path / "kept"), "--keep-light"]) == 0
    save(daylight=False)
    assert main([*args, "-o", str(tmp_path / "kept2")]) == 0
    assert main([*args, "-o", str(tmp_path / "day2"), "--no-keep-light"]) == 0
    assert seen == [True, False, False, True]
    # A rerun after the light was changed is other settings (kept until --force); unchanged, done.
    capsys.readouterr()
    assert main([*args, "-o", str(tmp_path / "day")]) == 2
    assert "made otherwise" in capsys.readouterr().err
    assert main([*args, "-o", str(tmp_path / "kept")]) == 0
    assert seen == [True, False, False, True]
    for bad in ("off", None):  # null too: the app refuses it
        data["daylight"] = bad
        project.write_text(json.dumps(data))
        with pytest.raises(ValueError, match="'a.outcast.json' daylight: expected true or fal"):
            batch.read_project(photo)


def test_batch_applies_the_projects_shadow_corrections(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The app's "Not a shadow" / "Mark shadow" clicks, saved in the project, act on a batch
    job as in the app; changed corrections are other settings (the output is redone), and a
    project without any keeps its record key (records from before them still match)."""
    from outcast_core.runtime.pipeline import batch
    from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit
    from outcast_core.runtime.pipeline.session import RelightSession

    photo = _photo(tmp_path / "a.png", 0)
    project = photo.with_name("a" + PROJECT_SUFFIX)
    data = {"outcast_project": 1, "image": "a.png",
            "original_sun": {"azimuth": 200.0, "elevation": 40.0}}
    project.write_text(json.dumps(data))
    opts = BatchOptions(kind="deshadow", preset="fast", mode="classic")
    job = BatchJob(str(photo), str(tmp_path / "o" / "a.png"))
    before = batch.job_settings(job, opts)
    assert batch.read_project(photo).shadow_edits == ()
    data["shadow_edits"] = [{"x": 0.5, "y": 0.5, "shadow": False},
                            {"x": 0.25, "y": 0.75, "shadow": True}]
    project.write_text(json.dumps(data))
    edits = (ShadowEdit(0.5, 0.5, False), ShadowEdit(0.25, 0.75, True))
    assert batch.read_project(photo).shadow_edits == edits
    assert batch.job_settings(job, opts) != before
    seen = []
    real = RelightSession.set_shadow_edits
    monkeypatch.setattr(RelightSession, "set_shadow_edits",
                        lambda self, e: seen.append(tuple(e)) or real(self, e))
    assert run_job(job, opts).status == "done"
    assert seen == [edits]
    data["shadow_edits"] = [{"x": 2.0, "y": 0.5, "shadow": True}]
    project.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="shadow_edits: expected a point inside the photo"):
        batch.read_project(photo)


def test_targets_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path / "in"
    d.mkdir()
    _photo(d / "a.png", 0)
    _photo(d / "b.png", 1)
    table = tmp_path / "targets.csv"
    with open(table, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["image", "to_az", "to_el", "from_az", "from_el", "output"])
        w.writerow(["a.png", "90", "30", "200", "40", "a_morning.png"])
        w.writerow(["a.png", "270", "60", "200", "40", "a_noon.png"])
        w.writerow(["b.png", "45", "20", "", "", ""])
        w.writerow(["b.png", "45", "25", "", "", ""])  # same output name as the row above
        w.writerow(["missing.png", "45", "20", "", "", ""])
    rows = read_targets_csv(table)
    assert rows[0] == {"image": "a.png", "to_sun": (90.0, 30.0), "from_sun": (200.0, 40.0),
                       "output": "a_morning.png"}
    out = tmp_path / "out"
    code = main(["batch", str(d), "-o", str(out), "--targets", str(table), "--from", "10,45",
                 "--mode", "classic", "--preset", "fast", "--format", "png",
                 "--report", str(tmp_path / "report.json")])
    err = capsys.readouterr().err
    assert code == 2
    assert sorted(p.name for p in out.iterdir()) == [RECORD_NAME, "a_morning.png", "a_noon.png",
                                                     "b.png"]
    assert "is also the output of 'b.png'" in err and "'missing.png' is not a photo" in err
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["counts"] == {"done": 3, "skipped": 0, "stale": 0, "failed": 2}
    by_out = {Path(r["output"]).name: r for r in report["results"]}
    assert by_out["a_noon.png"]["sun_source"] == "csv"
    assert by_out["a_noon.png"]["to_sun"] == [270.0, 60.0]
    assert by_out["b.png"]["sun_source"] == "given"
    # A de-shadow batch with the same table uses its photos, suns and names, and says that
    # the new suns go unused (a user trial: they were ignored without a word).
    good = tmp_path / "good.csv"
    good.write_text("image,to_az,to_el,from_az,from_el,output\na.png,90,30,200,40,a_clean.png\n"
                    "b.png,,,,,\n")
    code = main(["batch", str(d), "-o", str(tmp_path / "clean"), "--targets", str(good),
                 "--deshadow", "--from", "10,45", "--mode", "classic", "--preset", "fast"])
    err = capsys.readouterr().err
    assert code == 0 and (tmp_path / "clean" / "a_clean.png").is_file()
    assert ("note: --deshadow uses no new sun: the targets CSV's to_az, to_el of 1 photo are "
            "left unused") in err

    bad = tmp_path / "bad.csv"
    bad.write_text("photo,to_az\nx,1\n")
    assert main(["batch", str(d), "-o", str(out), "--targets", str(bad)]) == 2
    assert capsys.readouterr().err.strip() == ("outcast batch: error: bad.csv: expected a header "
                                               "row with an 'image' column, got ['photo', "
                                               "'to_az']")


def test_photos_named_alike_all_get_an_output(tmp_path: Path) -> None:
    """IMG_1.jpg, IMG_1.png and IMG_1.JPEG in one folder: each gets its own output (one was
    relit and the others failed, found by a user trial); a lone name keeps its plain output."""
    d = tmp_path / "in"
    d.mkdir()
    for i, name in enumerate(["IMG_1.jpg", "IMG_1.png", "IMG_1.JPEG", "IMG_2.jpg", "img_2.png"]):
        _photo(d / name, i)
    options = BatchOptions(kind="relight", to_sun=(90.0, 30.0), fmt="jpg")
    jobs, results = plan_batch(d, tmp_path / "out", options)
    assert results == []
    # IMG_2 and img_2 are one name on a case-insensitive disk (exFAT, NTFS, macOS).
    assert sorted(Path(j.output).name for j in jobs) == [
        "IMG_1_JPEG.jpg", "IMG_1_jpg.jpg", "IMG_1_png.jpg", "IMG_2_jpg.jpg", "img_2_png.jpg"]


def test_deshadow_and_timelapse(tmp_path: Path) -> None:
    d = tmp_path / "in"
    d.mkdir()
    _photo(d / "a.png", 0)
    assert main(["batch", str(d), "-o", str(tmp_path / "ds"), "--deshadow", "--from", "200,40",
                 "--preset", "fast", "--format", "tif", "-q"]) == 0
    with Image.open(tmp_path / "ds" / "a.tif") as im:
        assert im.size == (64, 48)
    assert main(["batch", str(d), "-o", str(tmp_path / "tl"), "--sweep", "80,15:280,50",
                 "--frames", "3", "--size", "working", "--format", "gif", "--from", "200,40",
                 "--preset", "fast", "--mode", "classic", "-q"]) == 0
    with Image.open(tmp_path / "tl" / "a.gif") as im:
        assert im.n_frames == 3


def test_command_errors(tmp_path: Path, folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "empty").mkdir()
    cases = [
        (["batch", str(folder), "-o", str(folder), "--to", "1,2"], "other than the input folder"),
        (["batch", str(tmp_path / "nope"), "-o", str(tmp_path / "o")], "is not a folder"),
        (["batch", str(folder), "-o", str(tmp_path / "o"), "--deshadow", "--format", "mp4"],
         "expected --format in jpg, png, tif, webp for deshadow"),
        (["batch", str(tmp_path / "empty"), "-o", str(tmp_path / "o")], "no photos in"),
    ]
    for argv, message in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err
        assert err.startswith("outcast batch: error: ")
    with pytest.raises(SystemExit) as stop:
        main(["batch", str(folder), "-o", str(tmp_path / "o"), "--to", "10,-5"])
    assert stop.value.code == 2 and "horizon" in capsys.readouterr().err


def test_job_settings_name_what_decides_an_output(tmp_path: Path) -> None:
    from dataclasses import replace

    from outcast_core.runtime.pipeline.batch import job_settings

    photo = _photo(tmp_path / "p.jpg", 0)
    job = BatchJob(str(photo), str(tmp_path / "out" / "p.jpg"))
    relight = BatchOptions(kind="relight", to_sun=(-90.0, 30.0), from_sun=(200.0, 40.0))
    key = job_settings(job, relight)
    assert key == job_settings(job, replace(relight, to_sun=(270.0, 30.0)))  # the same sun
    assert key == job_settings(job, replace(relight, frames=12, force=True, threads=3))
    assert key != job_settings(job, replace(relight, to_sun=(90.0, 30.0)))
    assert key != job_settings(job, replace(relight, preset="fast"))
    (tmp_path / "other").mkdir()
    other = _photo(tmp_path / "other" / "p.jpg", 1)  # another photo of the same name
    assert key != job_settings(replace(job, image=str(other)), relight)
    _photo(photo, 2)  # the photo itself changed
    os.utime(photo, ns=(1, 1))
    assert key != job_settings(job, relight)
    deshadow = BatchOptions(kind="deshadow", from_sun=(200.0, 40.0))
    assert job_settings(job, deshadow) == job_settings(job, replace(deshadow, to_sun=(1.0, 2.0)))
    # A metered relighting or time-lapse is another output; a de-shadowed photo is not.
    key = job_settings(job, relight)
    assert key != job_settings(job, replace(relight, exposure="metered"))
    assert "exposure" not in key  # records of the default made before the option still match
    timelapse = BatchOptions(kind="timelapse", sweep=((0.0, 30.0), (90.0, 30.0)))
    assert job_settings(job, timelapse) != job_settings(job, replace(timelapse,
                                                                     exposure="metered"))
    assert job_settings(job, deshadow) == job_settings(job, replace(deshadow, exposure="metered"))
    # The project counts by what a batch reads of it: saved again with the same suns (the
    # step-1 dial moved, say), the same job; another new sun or exposure, another.
    from app import state

    def save(**kw):
        state.save_project(state.ProjectState(image_path=str(photo), original_sun=state.Sun(
            200.0, 40.0), **kw), state.project_path_for(photo))

    save(align_sun=state.Sun(10.0, 10.0))
    key = job_settings(job, relight)
    save(align_sun=state.Sun(20.0, 30.0), split=0.3)
    assert job_settings(job, relight) == key
    save(target_sun=state.Sun(90.0, 30.0))
    assert job_settings(job, relight) != key
    save(exposure="metered")
    assert job_settings(job, relight) != key
    # The project's metering is this job's exposure: --exposure photo is another output (a
    # review found both recorded alike, so the metered output was "done" for the unmetered run).
    assert job_settings(job, replace(relight, exposure=None)) != job_settings(
        job, replace(relight, exposure="photo"))
    assert job_settings(job, replace(relight, exposure=None)) == job_settings(
        job, replace(relight, exposure="metered"))
    # The light likewise: kept (the project's "Keep the photo's light" or --keep-light), another
    # relit output or time-lapse; absent at the new sun's daylight (records from before match).
    project = state.project_path_for(photo)
    project.write_text(json.dumps({"outcast_project": 1, "image": photo.name,
                                   "original_sun": {"azimuth": 200.0, "elevation": 40.0}}))
    key = job_settings(job, relight)
    assert '"daylight"' not in key
    save(daylight=True)
    assert job_settings(job, relight) == key == job_settings(job, replace(relight,
                                                                          keep_light=False))
    assert job_settings(job, replace(relight, keep_light=True)) != key
    save(daylight=False)
    assert job_settings(job, relight) != key
    assert job_settings(job, relight) == job_settings(job, replace(relight, keep_light=True))
    assert job_settings(job, replace(relight, keep_light=False)) == key
    assert job_settings(job, timelapse) != job_settings(job, replace(timelapse, keep_light=False))
    assert job_settings(job, deshadow) == job_settings(job, replace(deshadow, keep_light=False))


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder_is_refused_before_any_photo(
    tmp_path: Path, folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["batch", str(folder), "-o", str(ro / "out"), "--to", "1,2"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "not writable" in err
    finally:
        ro.chmod(0o755)


def test_automatic_sun_source(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    auto_sun = pytest.importorskip("outcast_core.runtime.pipeline.auto_sun")
    from types import SimpleNamespace

    calls = []

    def fake_find_sun(session, *, prior=None, **kwargs):
        calls.append(prior)
        sure = len(calls) == 1
        return SimpleNamespace(azimuth=123.0, elevation=34.0, confidence=0.9 if sure else 0.1,
                               found=sure, source="shadows")

    monkeypatch.setattr(auto_sun, "find_sun", fake_find_sun)
    photo = _photo(tmp_path / "a.png", 0)
    opts = BatchOptions(kind="deshadow", sources=("project", "exif", "auto"), preset="fast",
                        mode="classic")
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "a.png")), opts)
    assert (r.status, r.sun_source, r.from_sun) == ("done", "auto", (123.0, 34.0))
    assert calls == [None] and r.details["auto_sun"]["found"] is True
    # Said with the result: a sun from the shadows alone can be far off (a user trial).
    assert any("was found from the photo's shadows (confidence 0.90)" in w for w in r.warnings)
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "b.png")), opts)  # not confident
    assert r.status == "failed" and "the automatic sun is not sure" in r.message
    given_first = replace_sources(opts, ("given", "auto"), from_sun=(10.0, 20.0))
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "c.png")), given_first)
    assert r.sun_source == "given" and len(calls) == 2  # never ran: --from came first
    calls.clear()  # (the next is the first: confident)
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "d.png")), opts)
    assert r.sun_source == "auto" and any("found from the photo's shadows" in w
                                          for w in r.warnings)
    # Guided by the compass heading: not warned of.
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: SimpleNamespace(
        azimuth=1.0, elevation=2.0, confidence=0.9, found=True, source="shadows + EXIF"))
    r = run_job(BatchJob(str(photo), str(tmp_path / "o" / "e.png")), opts)
    assert r.sun_source == "auto" and not any("shadows" in w for w in r.warnings)


def replace_sources(opts: BatchOptions, sources: tuple[str, ...], **kw: object) -> BatchOptions:
    from dataclasses import replace

    return replace(opts, sources=sources, **kw)


@pytest.mark.slow
def test_sigterm_stops_the_workers_and_leaves_no_partial_file(tmp_path: Path) -> None:
    import shutil
    import signal
    import subprocess
    import sys
    import time

    d = tmp_path / "in"
    d.mkdir()
    for i in range(3):
        shutil.copy2(SAMPLE, d / f"p{i}.jpg")  # full size: a few seconds each
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "outcast_core.runtime.cli.main", "batch", str(d), "-o", str(out),
           "--to", "90,30", "--preset", "fast", "--workers", "2"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    assert proc.stderr.readline().startswith("processing 3 photos")
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 143 and "outcast batch: terminated" in err
    partial = [p.name for p in out.iterdir() if p.name.startswith(".") and p.name != RECORD_NAME]
    assert not partial
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)  # resumed
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == [RECORD_NAME, "p0.jpg", "p1.jpg", "p2.jpg"]


def test_a_photo_that_shows_its_sun_is_relit_from_it(tmp_path: Path) -> None:
    """The ski slope's compass heading is 126° off the sun in its frame: the sun wins."""
    import shutil

    d = tmp_path / "in"
    d.mkdir()
    ski = Path(SAMPLE).with_name("exif_005_es_skislope.jpg")
    shutil.copy2(ski, d / ski.name)
    report = tmp_path / "r.json"
    assert main(["batch", str(d), "-o", str(tmp_path / "out"), "--to", "180,20", "--preset",
                 "fast", "-q", "--report", str(report)]) == 0
    r = json.loads(report.read_text())["results"][0]
    assert r["sun_source"] == "sun in the frame"
    assert abs((r["from_sun"][0] - 354.0 + 180.0) % 360.0 - 180.0) < 4.0


def test_skipped_outputs_report_their_suns(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    """A rerun reported the outputs it skipped without their suns (empty in the report and
    the line): they come from the record of the run that made them, else (a record written
    before suns were kept) from what is known without running the job: the project's."""
    from app.state import ProjectState, Sun, save_project

    d, out = tmp_path / "in", tmp_path / "out"
    d.mkdir()
    _exif_photo(d / "exif.jpg")
    aligned = _photo(d / "aligned.png", 2)
    save_project(ProjectState(image_path=str(aligned), original_sun=Sun(120.0, 35.0)),
                 d / f"aligned{PROJECT_SUFFIX}")
    args = ["batch", str(d), "-o", str(out), "--to", "90,30", "--preset", "fast", "--mode",
            "classic", "--sources", "project,exif"]

    def results(report: str) -> dict[str, dict]:
        assert main([*args, "--report", str(tmp_path / report)]) == 0
        data = json.loads((tmp_path / report).read_text())["results"]
        return {Path(r["image"]).name: r for r in data}

    first = results("first.json")
    assert first["aligned.png"]["sun_source"] == "project"
    assert first["exif.jpg"]["sun_source"] == "exif"
    capsys.readouterr()
    again = results("again.json")
    for name, made in first.items():
        assert made["status"] == "done" and again[name]["status"] == "skipped"
        for key in ("from_sun", "sun_source", "to_sun"):
            assert again[name][key] == made[key], (name, key)
    lines = capsys.readouterr().err.splitlines()
    assert "aligned.png: skipped (sun 120.0,35.0 from project -> 90,30): done with these " \
           "settings" in "\n".join(lines)
    az, el = first["exif.jpg"]["from_sun"]
    assert f"exif.jpg: skipped (sun {az:.1f},{el:.1f} from exif -> 90,30)" in "\n".join(lines)

    record = json.loads((out / RECORD_NAME).read_text())
    (out / RECORD_NAME).write_text(json.dumps({k: v["settings"] for k, v in record.items()}))
    old = results("old.json")
    assert [old[n]["status"] for n in sorted(old)] == ["skipped", "skipped"]
    assert (old["aligned.png"]["from_sun"], old["aligned.png"]["sun_source"]) == (
        [120.0, 35.0], "project")
    # The EXIF sun needs the photo read (its tilt): not guessed.
    assert (old["exif.jpg"]["from_sun"], old["exif.jpg"]["sun_source"]) == (None, "")
    assert old["exif.jpg"]["to_sun"] == old["aligned.png"]["to_sun"] == [90.0, 30.0]


def test_planned_suns_stop_where_the_photo_would_have_to_be_read(tmp_path: Path) -> None:
    from outcast_core.runtime.pipeline.batch import planned_suns

    job = BatchJob(str(_photo(tmp_path / "a.png", 0)), str(tmp_path / "o" / "a.jpg"))
    given = BatchOptions(kind="relight", from_sun=(10.0, 50.0), to_sun=(90.0, 30.0))
    assert planned_suns(job, given) == (None, "", (90.0, 30.0))  # exif comes before given
    only_given = replace_sources(given, ("project", "given"))
    assert planned_suns(job, only_given) == ((10.0, 50.0), "given", (90.0, 30.0))
    row = BatchJob(job.image, job.output, to_sun=(5.0, 6.0), from_sun=(7.0, 8.0))
    assert planned_suns(row, given) == ((7.0, 8.0), "csv", (5.0, 6.0))
    assert planned_suns(job, BatchOptions(kind="deshadow", sources=("given",),
                                          from_sun=(1.0, 2.0))) == ((1.0, 2.0), "given", None)


def test_a_rerun_with_a_report_resumes_and_replaces_its_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same command with ``--report R.json`` failed on a rerun ("already exists"), and
    ``--force`` redid every finished photo (a user trial): this batch's report is replaced by
    each run without ``--force``; another batch's report or any other file is kept."""
    d, out = tmp_path / "in", tmp_path / "out"
    d.mkdir()
    _photo(d / "a.png", 0)
    report = tmp_path / "r.json"
    args = ["batch", str(d), "-o", str(out), "--from", "200,40", "--to", "90,30", "--preset",
            "fast", "--mode", "classic", "-q", "--report", str(report)]
    assert main(args) == 0
    first = json.loads(report.read_text())
    assert first["counts"]["done"] == 1
    assert (first["input_folder"], first["output_folder"]) == (str(d.resolve()),
                                                               str(out.resolve()))
    made = (out / "a.jpg").stat().st_mtime_ns
    assert main(args) == 0, capsys.readouterr().err  # resumed: the photo is skipped
    again = json.loads(report.read_text())
    assert again["counts"] == {"done": 0, "skipped": 1, "stale": 0, "failed": 0}
    assert (out / "a.jpg").stat().st_mtime_ns == made
    # A report written before the marker, of this batch: known by its photos and outputs.
    del again["outcast_batch_report"], again["input_folder"], again["output_folder"]
    report.write_text(json.dumps(again))
    assert main(args) == 0
    assert json.loads(report.read_text())["outcast_batch_report"] == 1
    # Another batch's report, or any other JSON file, is kept; --force would replace it.
    other = [*args[:3], str(tmp_path / "out2"), *args[4:]]
    for text in (report.read_text(), '{"notes": "mine"}'):
        report.write_text(text)
        assert main(other) == 2
        err = capsys.readouterr().err.strip()
        assert "is not a report of this batch" in err and len(err.splitlines()) == 1
        assert report.read_text() == text and not (tmp_path / "out2").exists()


def test_batch_takes_the_projects_relighting_unless_told(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A project saved with step 2's "Relighting: Physics" is batch-relit with physics, as its
    suns are taken from it; ``--mode learned`` or ``classic`` says otherwise; a project from
    before the choice, or with "Learned", takes the default; the choice is part of a job's
    settings (a rerun after it changed is other settings); a relighting the app does not
    write is refused."""
    from app import state
    from outcast_core.runtime.pipeline import batch
    from outcast_core.runtime.pipeline.batch import job_settings, settings_changed
    from outcast_core.runtime.pipeline.session import RelightSession

    assert batch.PROJECT_RELIGHTINGS == state.RELIGHTINGS
    seen: list[str] = []  # the session's relighting at each relit photo
    real = RelightSession.relight_full
    monkeypatch.setattr(RelightSession, "relight_full",
                        lambda self, w, **kw: seen.append(self.relight_mode) or real(self, w, **kw))
    d, photo, project, data = _photo_with_old_project(tmp_path)
    assert batch.read_project(photo).relighting is None  # a project from before the choice
    job = BatchJob(str(photo), str(tmp_path / "o" / "x.png"))
    relight = BatchOptions(kind="relight", preset="fast")
    before = job_settings(job, relight)

    def save(relighting: str) -> None:
        state.save_project(state.ProjectState(
            image_path=str(photo), original_sun=state.Sun(200.0, 40.0),
            target_sun=state.Sun(90.0, 30.0), relighting=relighting), project)

    save("learned")
    assert job_settings(job, relight) == before  # (a record made before the choice matches)
    save("physics")
    assert batch.read_project(photo).relighting == "physics"
    assert job_settings(job, relight) != before
    assert "the project's relighting" in settings_changed(before, job_settings(job, relight))
    for i, mode in enumerate(("auto", "learned", "classic")):
        opts = BatchOptions(kind="relight", preset="fast", mode=mode)
        r = run_job(BatchJob(str(photo), str(tmp_path / "o" / f"{i}.png")), opts)
        assert r.status == "done", r.message
        assert r.details["relighting"] == seen[-1]
    assert seen == ["physics", "learned", "physics"]
    assert '"relighting"' not in job_settings(job, BatchOptions(kind="deshadow"))  # not relit
    data["relighting"] = "auto"
    project.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="'a.outcast.json' relighting: expected one of"):
        batch.read_project(photo)


def test_relights_warnings_are_in_the_batchs_lines_summary_and_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A batch dropped what ``relight`` warns of (transparency filled with white, a strip's
    shape) and an 8 x 8 photo was warned of nowhere: each is said on its photo's line (also
    with -q, and again when a rerun skips it), counted in the summary and kept in the report;
    the photos are still done (exit status 0)."""
    from outcast_core.runtime.pipeline import auto_sun
    from outcast_core.runtime.pipeline.batch import MIN_PHOTO_SIDE

    assert MIN_PHOTO_SIDE == auto_sun.LEGIBLE_LOW
    d, out, report = tmp_path / "in", tmp_path / "out", tmp_path / "r.json"
    d.mkdir()
    _photo(d / "plain.png", 0)
    _photo(d / "tiny.png", 1, size=(8, 8))
    rgba = np.full((48, 64, 4), 200, np.uint8)
    rgba[:10, :10, 3] = 0
    Image.fromarray(rgba).save(d / "clear.png")
    args = ["batch", str(d), "-o", str(out), "--from", "200,40", "--to", "90,30", "--preset",
            "fast", "--mode", "classic", "--report", str(report)]
    assert main(args) == 0
    lines = capsys.readouterr().err.splitlines()
    line = {n: next(x for x in lines if f"] {n}" in x) for n in ("clear.png", "plain.png",
                                                                  "tiny.png")}
    assert line["clear.png"].endswith("; warning: its transparency is filled with white (the "
                                      "output has none)")
    assert "; warning: the photo is only 8 x 8 pixels: too small to relight" in line["tiny.png"]
    assert "warning" not in line["plain.png"]
    assert "3 done (2 with warnings), 0 skipped (already done), 0 failed" in "\n".join(lines)
    assert lines[-1] == ("outcast batch: warning: 2 of 3 outputs were made despite a warning "
                         "(see their lines): clear.png, tiny.png")
    data = json.loads(report.read_text())
    assert data["with_warnings"] == 2
    by_name = {Path(r["image"]).name: r for r in data["results"]}
    assert by_name["plain.png"]["warnings"] == [] and len(by_name["tiny.png"]["warnings"]) == 1
    # -q: the warnings still; a rerun skips the photos and says their warnings again.
    assert main([*args, "-q"]) == 0
    err = capsys.readouterr().err
    assert "tiny.png: skipped" in err and "8 x 8 pixels" in err and "plain.png" not in err
    assert json.loads(report.read_text())["with_warnings"] == 2


def test_what_changed_is_said_in_the_options_words(tmp_path: Path) -> None:
    """A kept output's line names what differs from its record, as the options are written
    (at most three, then how many more); unreadable records say nothing more."""
    from outcast_core.runtime.pipeline.batch import job_settings, settings_changed

    photo = tmp_path / "a.jpg"
    _photo(photo, 0)
    job = BatchJob(str(photo), str(tmp_path / "out" / "a.jpg"))
    base = BatchOptions(to_sun=(90.0, 30.0), preset="fast")
    old = job_settings(job, base)
    assert settings_changed(old, old) == ""
    assert settings_changed(old, "not json") == "" and settings_changed("[1]", old) == ""
    other = dataclasses.replace(base, to_sun=(-90.0, 30.0), preset="accurate", fmt="png",
                                mode="classic", exposure="metered")
    said = settings_changed(old, job_settings(job, other))
    assert said == ("with --to 90,30 instead of 270,30; with --format jpg instead of png; "
                    "with --preset fast instead of accurate; 2 more differences")
    light = dataclasses.replace(base, keep_light=True)
    assert settings_changed(old, job_settings(job, light)) == (
        "with the new sun's light instead of the photo's")
    _photo(photo, 1)  # the photo itself replaced
    assert settings_changed(old, job_settings(job, base)) == "with another version of the photo"


def test_the_reports_paths_are_absolute_for_relative_folders(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Given relative folders, the report's photos and outputs are absolute, as its
    ``input_folder`` is (a user trial found them mixed)."""
    monkeypatch.chdir(tmp_path)
    Path("in").mkdir()
    _photo(Path("in") / "p.png", 0)
    assert main(["batch", "in", "-o", "out", "--from", "200,40", "--to", "90,30", "--mode",
                 "classic", "--preset", "fast", "--report", "r.json", "-q"]) == 0
    data = json.loads(Path("r.json").read_text())
    (r,) = data["results"]
    assert r["image"] == str(tmp_path.resolve() / "in" / "p.png")
    assert r["output"] == str(tmp_path.resolve() / "out" / "p.jpg")
    assert data["input_folder"] == str(tmp_path.resolve() / "in")


def test_a_report_in_the_output_folder_the_batch_makes_is_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``-o out --report out/r.json`` with ``out`` not made yet: the batch makes it and writes
    the report there (a user trial's was refused: "folder 'out' does not exist"); a report
    in a folder nothing makes is still refused, and so is a report without ``.json``."""
    monkeypatch.chdir(tmp_path)
    Path("in").mkdir()
    _photo(Path("in") / "p.png", 0)
    args = ["batch", "in", "-o", "out", "--from", "200,40", "--to", "90,30", "--mode",
            "classic", "--preset", "fast", "-q"]
    assert main([*args, "--report", "elsewhere/r.json"]) != 0
    assert "does not exist" in capsys.readouterr().err and not Path("out").exists()
    assert main([*args, "--report", "out/r.txt"]) != 0
    assert ".json" in capsys.readouterr().err and not Path("out").exists()
    assert main([*args, "--report", "out/r.json"]) == 0
    assert json.loads(Path("out/r.json").read_text())["counts"]["done"] == 1


def test_the_batchs_own_files_in_its_folder_are_not_called_other_files(tmp_path: Path) -> None:
    """A targets CSV or a report kept in the photos' folder is the batch's own, not a file
    it passed over."""
    from outcast_core.runtime.pipeline.batch import other_files

    _photo(tmp_path / "p.png", 0)
    for name in ("targets.csv", "report.json", "notes.txt", "p.outcast.json"):
        (tmp_path / name).write_text("x")
    assert [p.name for p in other_files(tmp_path)] == ["notes.txt", "report.json",
                                                       "targets.csv"]
    assert [p.name for p in other_files(tmp_path, exclude=[
        str(tmp_path / "targets.csv"), tmp_path / "report.json", None, ""])] == ["notes.txt"]


def test_sub_folders_are_said_not_to_be_looked_into(folder: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A folder inside the photos' folder (even one named like a photo) was passed over in
    silence (a robustness trial): a note names it; photos are taken directly in the folder."""
    for name in ("raw", "sub.jpg", ".cache"):
        (folder / name).mkdir()
    main(["batch", str(folder), "-o", str(tmp_path / "o"), "--from", "200,40", "--to", "90,30",
          "--mode", "classic", "--preset", "fast", "--workers", "1"])
    err = capsys.readouterr().err
    assert ("outcast batch: note: 2 sub-folders are not looked into (photos directly in the "
            "folder only): raw, sub.jpg\n") in err


def _night_copy(path: Path, compass: bool) -> Path:
    """The small EXIF sample with its capture time at 02:00 (the sun far below the horizon),
    with or without its compass heading."""
    with Image.open(SAMPLE) as im:
        exif = im.getexif()
        exif[306] = "2019:08:21 02:00:00"
        exif.get_ifd(0x8769)[36867] = "2019:08:21 02:00:00"
        gps = exif.get_ifd(0x8825)
        gps[7], gps[29] = (19.0, 0.0, 0.0), "2019:08:20"  # the GPS clock's UTC alike
        if not compass:
            gps.pop(17, None)  # GPSImgDirection
        im.resize((80, 60)).save(path, exif=exif)
    return path


def test_a_day_of_a_night_time_clock_takes_the_compass_or_fails(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No heading is solved from a sun below the horizon (a robustness trial): a photo whose
    EXIF time is at night renders its day at its compass heading, and without one it fails
    with the reason."""
    d = tmp_path / "in"
    d.mkdir()
    _night_copy(d / "compass.jpg", compass=True)
    _night_copy(d / "none.jpg", compass=False)
    assert read_image(d / "compass.jpg").exif.heading_deg is not None
    assert read_image(d / "none.jpg").exif.heading_deg is None
    out = tmp_path / "out"
    assert main(["batch", str(d), "-o", str(out), "--day", "--frames", "2", "--size",
                 "working", "--from", "273,67", "--sources", "given", "--mode", "classic",
                 "--preset", "fast", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    failed = [line for line in err.splitlines() if ": failed: " in line]
    assert len(failed) == 1 and "none.jpg" in failed[0]
    assert "below the horizon at the photo's EXIF time" in failed[0]
    assert (out / "compass.mp4").exists() and not (out / "none.mp4").exists()
    # A day's dark dawn and dusk are said once, with what to do; metered, not.
    assert err.count("come out dark where the photo's exposure is kept") == 1
    assert main(["batch", str(d), "-o", str(tmp_path / "m"), "--day", "--frames", "2",
                 "--size", "working", "--from", "273,67", "--sources", "given", "--mode",
                 "classic", "--preset", "fast", "--exposure", "metered"]) == 2
    assert "come out dark" not in capsys.readouterr().err


def test_a_days_heading_reads_a_bare_capture_time_at_its_longitudes_zone(monkeypatch) -> None:
    """``outcast batch --day`` read a capture time without a zone as UTC when it solved the
    heading (the app and ``outcast timelapse`` read it at its longitude's zone): at longitude
    98.3 seven hours of sun off."""
    import datetime as dt
    from types import SimpleNamespace

    from outcast_core.runtime.pipeline import batch as batch_mod
    from outcast_core.runtime.pipeline import timelapse as tl

    aware = dt.datetime(2019, 8, 21, 3, 57, 22, tzinfo=dt.UTC)
    true_az, _ = tl.true_sun_position(aware, 7.83, 98.3)
    sun = (tl.relative_azimuth(true_az, 163.7), 66.0)
    got = []
    monkeypatch.setattr(tl, "render_timelapse", lambda session, samples, *a, **k:
                        got.append(samples))
    for when in (aware, dt.datetime(2019, 8, 21, 10, 57, 22)):  # the same moment, at UTC+7
        exif = SimpleNamespace(capture_time=when, latitude=7.83, longitude=98.3,
                               heading_deg=None)
        batch_mod._render_timelapse(None, SimpleNamespace(exif=exif), sun,
                                    batch_mod.BatchJob("x.jpg", "x.mp4"),
                                    batch_mod.BatchOptions(kind="timelapse", day=True,
                                                           frames=3))
    for a, b in zip(*got, strict=True):
        assert a.azimuth == pytest.approx(b.azimuth, abs=1e-6)
        assert a.azimuth == pytest.approx((a.true_azimuth - 163.7) % 360.0, abs=1e-6)


def test_an_interrupted_batch_says_and_reports_what_ended(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl+C or SIGTERM midway said "interrupted" alone and wrote no ``--report`` (a user
    trial): what ended is counted, the report is written with ``interrupted`` and the photos
    not reached, and the command says that running it again goes on."""
    from outcast_core.runtime.cli import batch_cli
    from outcast_core.runtime.pipeline.batch import JobResult

    d = tmp_path / "in"
    d.mkdir()
    for i in range(3):
        _photo(d / f"p{i}.png", i)

    def stopped(jobs, options, workers=1, on_result=None):
        on_result(JobResult(jobs[0].image, jobs[0].output, "done"))
        raise KeyboardInterrupt

    monkeypatch.setattr(batch_cli, "run_batch", stopped)
    report = tmp_path / "r.json"
    assert main(["batch", str(d), "-o", str(tmp_path / "out"), "--to", "90,30", "--from",
                 "120,40", "--sources", "given", "--report", str(report)]) == 130
    err = capsys.readouterr().err
    assert "stopped after 1 of 3 photos (1 done, 0 skipped, 0 failed)" in err
    assert "the same command again goes on" in err and "interrupted" in err
    data = json.loads(report.read_text())
    assert data["interrupted"] is True and data["not_finished"] == 2
    assert data["counts"]["done"] == 1 and len(data["results"]) == 1


def test_an_interrupted_batch_whose_report_is_refused_still_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file of another program at the report's path by the time the batch is interrupted is
    kept: the report is said not written (no "use --force", which redoes every photo here),
    and the interruption's exit status stays (a review)."""
    from outcast_core.runtime.cli import batch_cli
    from outcast_core.runtime.pipeline.batch import JobResult

    d = tmp_path / "in"
    d.mkdir()
    _photo(d / "p0.png", 0)
    report = tmp_path / "r.json"

    def stopped(jobs, options, workers=1, on_result=None):
        on_result(JobResult(jobs[0].image, jobs[0].output, "failed"))
        report.write_text("mine\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(batch_cli, "run_batch", stopped)
    assert main(["batch", str(d), "-o", str(tmp_path / "out"), "--to", "90,30", "--from",
                 "120,40", "--sources", "given", "--report", str(report)]) == 130
    err = capsys.readouterr().err
    assert "stopped after 1 of 1 photos (0 done, 0 skipped, 1 failed)" in err
    assert f"the report '{report}' was not written" in err and "--force" not in err
    assert report.read_text() == "mine\n"
