"""Batch relighting: every photo of a folder, relit, de-shadowed or rendered as a time-lapse.

Plain functions first: :func:`list_photos` finds the photos, :func:`read_targets_csv` reads a
per-photo target table, :func:`plan_batch` turns them into jobs (skipping finished outputs, so a
batch is resumed by running it again), :func:`run_job` does one photo and never raises for a bad
photo, and :func:`run_batch` runs the jobs in one process or several. ``outcast batch``
(:mod:`outcast_core.runtime.cli.batch_cli`) is the command line.

Each photo's original sun comes from the first of ``sources`` that has one: ``project`` (the
app's project file next to it, ``NAME.outcast.json``: the sun the user confirmed), ``exif``
(GPS, capture time and compass heading, as the app's "Sun from EXIF"), ``given`` (one sun for
every photo: ``--from``) or ``auto`` (the automatic sun,
:func:`~outcast_core.runtime.pipeline.auto_sun.
find_sun`, with the EXIF time and place as its prior; used only when it is confident). A row of
the targets CSV may also give the photo's original sun.

Example:
    >>> opts = BatchOptions(kind="relight", to_sun=(90.0, 30.0), from_sun=(273.0, 67.0))
    >>> jobs, skipped = plan_batch("photos", "out", opts)  # doctest: +SKIP
    >>> results = run_batch(jobs, opts, workers=2)  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import signal
import time
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from outcast_core.runtime.io.photo_identity import PhotoIdentity

#: Photo extensions a batch picks up (what :func:`~outcast_core.runtime.io.imageio.read_image`
#: reads).
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp", ".heic", ".heif", ".bmp")
#: What a batch can make of each photo.
KINDS = ("relight", "deshadow", "timelapse")
#: Where an original sun may come from, in the default order.
SUN_SOURCES = ("project", "exif", "given", "auto")
#: Output formats per kind (the first is the default).
FORMATS = {"relight": ("jpg", "png", "tif", "webp"), "deshadow": ("jpg", "png", "tif", "webp"),
           "timelapse": ("mp4", "gif", "webp")}
#: The app's project files (``app.state.PROJECT_SUFFIX``; a test keeps them equal).
PROJECT_SUFFIX = ".outcast.json"
MAX_PROJECT_BYTES = 1_000_000
#: The relightings a project may choose (``app.state.RELIGHTINGS``; a test keeps them equal).
PROJECT_RELIGHTINGS = ("learned", "physics")
#: A batch's record in its output folder: the settings each finished output was made with
#: (:func:`job_settings`) and the suns it was made with (:class:`RecordEntry`). A batch run
#: again skips an output only when it was made with the same settings (and reports its suns);
#: one made otherwise (another sun, preset, format...) or not by a batch is kept and reported
#: as ``stale`` until ``force`` redoes it.
RECORD_NAME = ".outcast-batch.json"
#: Shorter side (pixels) under which a photo is too small to relight meaningfully
#: (:func:`small_photo_note`; a user trial's 8 x 8 photo was relit and reported as done with
#: no word). Its shadows are found and cast at its own size (the working size never enlarges a
#: photo), and under this many pixels there are too few for them: the automatic sun's
#: legibility is 0 there (``auto_sun.LEGIBLE_LOW``, the same number: a test keeps them equal),
#: and the learned networks, trained on 128-pixel views and halving the image four times,
#: see under two pixels across at their coarsest. A warning, not a refusal: the output is
#: written.
MIN_PHOTO_SIDE = 24

Sun = tuple[float, float]


@dataclass(frozen=True)
class BatchOptions:
    """What a batch does to every photo.

    Attributes:
        kind: ``relight``, ``deshadow`` or ``timelapse``.
        sources: where original suns come from, in order (:data:`SUN_SOURCES`).
        from_sun: the ``given`` original sun ``(azimuth, elevation)``, degrees.
        to_sun: the new sun for every photo (a CSV row or the project's target overrides it...
            see :func:`target_sun_for`).
        fmt: output format (:data:`FORMATS`); default the kind's first.
        preset: the session's quality preset.
        mode: ``auto``, ``learned`` or ``classic`` (the session's).
        depth_model: an ONNX depth model to use instead of the shipped one.
        use_phone_depth: use a phone photo's own depth map.
        sweep: time-lapse sweep ``((az1, el1), (az2, el2))``; None with ``day``.
        day: time-lapse along the real sun path of the capture day (needs EXIF GPS and time).
        frames: time-lapse frame count.
        easing: sweep easing (:data:`~outcast_core.runtime.pipeline.timelapse.EASINGS`).
        fps: time-lapse frames per second.
        size: time-lapse frame size (:data:`~outcast_core.runtime.pipeline.timelapse.FRAME_SIZES`).
        exposure: ``photo`` (the photo's exposure kept), ``metered`` (relit photos and
            time-lapse frames metered again; ``RelightSession.exposure``), or None: the
            photo's project's (:func:`project_exposure`), else ``photo``.
        keep_light: True: the photo's light kept (``RelightSession.daylight`` off), False: the
            new sun's daylight, None: the photo's project's (step 2's "Keep the photo's
            light"), else the new sun's daylight (:func:`daylight_for`).
        force: overwrite existing outputs (else finished photos are skipped).
        threads: onnxruntime threads per worker (None: onnxruntime's default).
    """

    kind: str = "relight"
    sources: tuple[str, ...] = SUN_SOURCES
    from_sun: Sun | None = None
    to_sun: Sun | None = None
    fmt: str = ""
    preset: str = "balanced"
    mode: str = "auto"
    depth_model: str | None = None
    use_phone_depth: bool = True
    sweep: tuple[Sun, Sun] | None = None
    day: bool = False
    frames: int = 48
    easing: str = "ease-in-out"
    fps: float = 12.0
    exposure: str | None = None
    keep_light: bool | None = None
    size: str = "1080p"
    force: bool = False
    threads: int | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"expected a batch kind in {KINDS}, got {self.kind!r}")
        bad = [s for s in self.sources if s not in SUN_SOURCES]
        if not self.sources or bad:
            raise ValueError(f"expected sun sources from {SUN_SOURCES}, got {self.sources!r}")
        fmt = (self.fmt or FORMATS[self.kind][0]).lower().lstrip(".")
        if fmt not in FORMATS[self.kind]:
            raise ValueError(f"expected a {self.kind} format in {FORMATS[self.kind]}, got "
                             f"{self.fmt!r}")
        object.__setattr__(self, "fmt", fmt)
        if self.kind == "timelapse" and (self.sweep is None) == (not self.day):
            raise ValueError("expected a time-lapse sun path: a sweep or the capture day")


@dataclass(frozen=True)
class BatchJob:
    """One photo to process.

    Attributes:
        image: the photo.
        output: the file to write.
        to_sun: the new sun from the targets CSV (None: :attr:`BatchOptions.to_sun` or the
            project's).
        from_sun: the original sun from the targets CSV (None: the sun sources).
    """

    image: str
    output: str
    to_sun: Sun | None = None
    from_sun: Sun | None = None
    settings: str = ""


@dataclass
class JobResult:
    """What happened to one photo.

    Attributes:
        image: the photo.
        output: the output file.
        status: ``done``, ``skipped`` (the output exists, made with the same settings),
            ``stale`` (the output exists, made with other settings or not by a batch: kept)
            or ``failed``.
        message: one line: the error, or why it was skipped.
        from_sun: the original sun used.
        sun_source: where it came from (``project``, ``exif``, ``given``, ``csv``).
        to_sun: the new sun (relighting).
        seconds: wall time of the job.
        details: the session's modes and timings.
        warnings: what ``outcast relight`` warns of for this photo (:func:`photo_warnings`:
            transparency filled with white, a strip's shape, too small, no depth model); the
            output is made all the same.
    """

    image: str
    output: str
    status: str
    message: str = ""
    from_sun: Sun | None = None
    sun_source: str = ""
    to_sun: Sun | None = None
    seconds: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


# -------------------------------------------------------------------------------- planning
def list_photos(folder: str | os.PathLike[str]) -> list[Path]:
    """The photos directly in ``folder`` (not its sub-folders), sorted by name.

    Raises:
        FileNotFoundError: ``folder`` is not a folder.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"'{folder}' is not a folder")
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and not p.name.startswith(".")
                  and p.suffix.lower() in PHOTO_SUFFIXES)


def other_files(folder: str | os.PathLike[str],
                exclude: Sequence[str | os.PathLike[str] | None] = ()) -> list[Path]:
    """The files directly in ``folder`` that a batch leaves alone, sorted by name: not photos
    (:func:`list_photos`), not hidden, not the photos' project files (``NAME.outcast.json``),
    nor one of ``exclude`` (the batch's own targets CSV and report; None and ``""`` are
    ignored).

    Example:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     for name in ("a.jpg", "a.outcast.json", "notes.txt", ".DS_Store"):
        ...         _ = (Path(d) / name).write_bytes(b"")
        ...     [p.name for p in other_files(d)]
        ['notes.txt']
    """
    photos = set(list_photos(folder))
    own = {os.path.abspath(Path(p).expanduser()) for p in exclude if p}
    return sorted(p for p in Path(folder).iterdir()
                  if p.is_file() and p not in photos and not p.name.startswith(".")
                  and not p.name.endswith(PROJECT_SUFFIX) and os.path.abspath(p) not in own)


def _parse_sun(az: str, el: str, where: str) -> Sun:
    try:
        sun = float(az), float(el)
    except ValueError:
        raise ValueError(f"{where}: expected numbers for the sun, got {az!r}, {el!r}") from None
    if not (math.isfinite(sun[0]) and math.isfinite(sun[1])) or not 0.0 <= sun[1] <= 90.0:
        raise ValueError(f"{where}: expected a sun at or above the horizon (elevation 0 to "
                         f"90), got {az},{el}")
    return sun


def read_targets_csv(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Read a targets table: one row per output.

    Columns (a header row names them): ``image`` (a file name in the input folder), ``to_az``,
    ``to_el`` (the new sun; may be empty for de-shadowing and time-lapses), and optionally
    ``from_az``, ``from_el`` (the photo's original sun, instead of the sun sources) and
    ``output`` (the output file name; needed when a photo is listed twice).

    Returns:
        Rows as ``{"image", "to_sun", "from_sun", "output"}`` (suns as ``(az, el)`` or None).

    Raises:
        ValueError: a missing column, a bad number, an empty ``image``.
    """
    path = Path(path)
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.DictReader(f)
        fields = {c.strip() for c in reader.fieldnames or []}
        if "image" not in fields:
            raise ValueError(f"{path.name}: expected a header row with an 'image' column, got "
                             f"{sorted(fields)}")
        rows = []
        for line, raw in enumerate(reader, start=2):
            row = {(k or "").strip(): (v or "").strip() for k, v in raw.items()}
            where = f"{path.name} line {line}"
            if not row.get("image"):
                raise ValueError(f"{where}: expected an image name, got an empty cell")
            to_sun = from_sun = None
            if row.get("to_az") or row.get("to_el"):
                to_sun = _parse_sun(row.get("to_az", ""), row.get("to_el", ""), where)
            if row.get("from_az") or row.get("from_el"):
                from_sun = _parse_sun(row.get("from_az", ""), row.get("from_el", ""), where)
            rows.append({"image": row["image"], "to_sun": to_sun, "from_sun": from_sun,
                         "output": row.get("output", "")})
    return rows


def plan_batch(
    in_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    options: BatchOptions,
    targets: Sequence[dict[str, Any]] | None = None,
) -> tuple[list[BatchJob], list[JobResult]]:
    """The jobs of a batch, and the photos that need none (finished, or impossible to plan).

    Output ``OUT_DIR/NAME.FMT`` for each photo ``NAME.*`` (a CSV ``output`` name instead;
    photos of a folder whose names differ only by their extension, ``IMG_1.jpg`` and
    ``IMG_1.png``, get ``IMG_1_jpg.FMT`` and ``IMG_1_png.FMT``, so none is left out). An
    existing output is ``skipped`` when the folder's record (:data:`RECORD_NAME`) says it was
    made with these settings, else ``stale`` (kept); ``options.force`` redoes both. Running a
    batch again resumes it. A skipped output's result has the suns it was made with: the
    record's, else those known without running it (:func:`planned_suns`).

    Args:
        in_dir: the folder of photos.
        out_dir: the output folder (it may not be ``in_dir``).
        options: the batch options.
        targets: rows of :func:`read_targets_csv`; None: every photo in ``in_dir``.

    Returns:
        ``(jobs, results)``: the jobs to run and the ``skipped`` / ``stale`` / ``failed``
        results of the photos not to run.

    Raises:
        ValueError: ``out_dir`` is ``in_dir``.
        FileNotFoundError: ``in_dir`` is not a folder.
    """
    in_dir, out_dir = Path(in_dir), Path(out_dir)
    photos = list_photos(in_dir)
    if out_dir.exists() and os.path.samefile(in_dir, out_dir):
        raise ValueError(f"expected an output folder other than the input folder '{in_dir}'")
    if targets is None:
        # Case folded: img_1.jpg and IMG_1.png are one name on exFAT, NTFS and macOS disks.
        stems = Counter(p.stem.casefold() for p in photos)
        rows = [{"image": p.name, "to_sun": None, "from_sun": None,
                 "output": "" if stems[p.stem.casefold()] == 1
                 else f"{p.stem}_{p.suffix.lstrip('.')}.{options.fmt}"}
                for p in photos]
    else:
        rows = list(targets)
    names = {p.name for p in photos}
    record = read_record_entries(out_dir)
    jobs: list[BatchJob] = []
    results: list[JobResult] = []
    claimed: dict[str, str] = {}
    for row in rows:
        image = in_dir / row["image"]
        name = row["output"] or f"{Path(row['image']).stem}.{options.fmt}"
        output = out_dir / name
        if row["image"] not in names:
            results.append(JobResult(str(image), str(output), "failed",
                                     f"'{row['image']}' is not a photo in '{in_dir}'"))
            continue
        if Path(name).name != name:
            results.append(JobResult(str(image), str(output), "failed",
                                     f"expected an output file name, got {name!r}"))
            continue
        if name.casefold() in claimed:  # one file on a case-insensitive disk
            results.append(JobResult(
                str(image), str(output), "failed",
                f"'{name}' is also the output of '{claimed[name.casefold()]}'; name the "
                "outputs in the targets CSV's 'output' column"))
            continue
        claimed[name.casefold()] = row["image"]
        job = BatchJob(str(image), str(output), row["to_sun"], row["from_sun"])
        job = replace(job, settings=job_settings(job, options))
        if output.exists() and not options.force:
            entry = record.get(name)
            if entry is not None and entry.settings in (
                    job.settings, settings_for_source(job, options, None)):
                from_sun, source, to_sun = (
                    (entry.from_sun, entry.sun_source, entry.to_sun) if entry.from_sun is not None
                    else planned_suns(job, options))
                results.append(JobResult(str(image), str(output), "skipped",
                                         "done with these settings (use --force to redo it)",
                                         from_sun=from_sun, sun_source=source, to_sun=to_sun,
                                         warnings=list(entry.warnings)))
            else:
                how = "is not in the output folder's batch record"
                if entry is not None:  # against the record's kind (its sun's --from unused)
                    now = (settings_for_source(job, options, None)
                           if _recorded(entry.settings).get("from_sun") == FROM_SUN_NOT_USED
                           else job.settings)
                    how = "was made " + (settings_changed(entry.settings, now)
                                         or "with other settings")
                results.append(JobResult(
                    str(image), str(output), "stale",
                    f"the output exists and {how}; use --force to redo it"))
            continue
        jobs.append(job)
    return jobs, results


#: :func:`settings_changed`: each recorded setting in the words a user gave it, in this order.
_SETTING_WORDS = {
    "kind": "the kind of batch", "to_sun": "--to", "job_to_sun": "the targets CSV's new sun",
    "job_from_sun": "the targets CSV's original sun", "from_sun": "--from",
    "sources": "--sources", "sweep": "--sweep", "day": "--day", "frames": "--frames",
    "easing": "--easing", "fps": "--fps", "size": "--size", "fmt": "--format",
    "preset": "--preset", "mode": "--mode", "exposure": "--exposure", "daylight": "the light",
    "relighting": "the project's relighting",
    "depth_model": "--depth-model", "use_phone_depth": "the phone's depth",
    "photo": "the photo", "project": "the photo's project",
}


#: :func:`job_settings` leaves these out at their defaults (records made before them match).
_SETTING_DEFAULTS = {"exposure": "photo", "daylight": True, "relighting": "the default"}


def _recorded(settings: str) -> dict[str, Any]:
    """A record's settings (:func:`job_settings`) as a dict, its left-out defaults filled in;
    ``{}`` when they cannot be read."""
    try:
        keys = json.loads(settings)
    except (TypeError, ValueError):
        return {}
    return {**_SETTING_DEFAULTS, **keys} if isinstance(keys, dict) else {}


def _said(key: str, value: Any) -> str:
    """One recorded setting's value as a user wrote it."""
    if value is None:
        return "none"
    if key == "daylight":
        return "the photo's" if value is False else "the new sun's"
    if isinstance(value, bool):
        return "on" if value else "off"
    if key in ("to_sun", "from_sun", "job_to_sun", "job_from_sun") and isinstance(value, list):
        return ",".join(f"{v:g}" for v in value)
    if key == "sweep" and isinstance(value, list):
        return ":".join(",".join(f"{v:g}" for v in sun) for sun in value)
    if key == "sources" and isinstance(value, list):
        return ",".join(str(v) for v in value)
    return str(value) if isinstance(value, str | int | float | bool) else "another"


def settings_changed(old: str, new: str) -> str:
    """What differs between two records' settings (:func:`job_settings`), in words: ``"with
    --to 90,30 instead of 180,20"``; ``"with another version of the photo"`` for a changed
    file; ``""`` when they cannot be read or do not differ.

    Example:
        >>> opts = BatchOptions(to_sun=(90.0, 30.0))
        >>> job = BatchJob("a.jpg", "out/a.jpg")
        >>> a = job_settings(job, opts)
        >>> settings_changed(a, job_settings(job, replace(opts, to_sun=(180.0, 20.0))))
        'with --to 90,30 instead of 180,20'
        >>> settings_changed(a, job_settings(job, replace(opts, exposure="metered")))
        'with --exposure photo instead of metered'
    """
    was, now = _recorded(old), _recorded(new)
    if not was or not now:
        return ""
    keys = [k for k in _SETTING_WORDS if k in was or k in now]
    keys += sorted(k for k in set(was) | set(now) if k not in _SETTING_WORDS)
    said = []
    for key in keys:
        a, b = was.get(key), now.get(key)
        if a == b:
            continue
        name = _SETTING_WORDS.get(key, key)
        if key == "daylight":
            said.append(f"with {_said(key, a)} light instead of {_said(key, b)}")
        elif key in ("photo", "project", "depth_model"):  # a file: changed, not a value
            said.append(f"with another version of {name}" if a and b else
                        f"{'without' if not a else 'with'} {name}")
        else:
            said.append(f"with {name} {_said(key, a)} instead of {_said(key, b)}")
    if len(said) > 3:
        said = [*said[:3], f"{len(said) - 3} more differences"]
    return "; ".join(said)


#: :func:`job_settings`: the options each kind of batch reads (the rest cannot change its output).
_KIND_OPTIONS = {
    "relight": ("to_sun",),
    "deshadow": (),
    "timelapse": ("sweep", "day", "frames", "easing", "fps", "size"),
}


def _sun_key(sun: Any) -> Any:
    """A sun as the record compares it: azimuth in [0, 360), both rounded (-90 and 270, -0.0
    and 0.0 are one sun)."""
    if sun is None:
        return None
    az, el = (float(v) for v in sun)
    return [round(az % 360.0, 3) + 0.0, round(el, 3) + 0.0]


def exposure_for(options: BatchOptions, read: ProjectSettings | None) -> str:
    """A job's exposure: ``--exposure``, else its project's "Meter the new light" (as its
    suns are taken from it), else the photo's own."""
    return options.exposure or (read.exposure if read is not None else None) or "photo"


def daylight_for(options: BatchOptions, read: ProjectSettings | None) -> bool:
    """Whether a job takes the new sun's daylight (``RelightSession.daylight``): not with
    ``--keep-light``, else as its project says (step 2's "Keep the photo's light", as its
    suns are taken from it), else it does."""
    if options.keep_light is not None:
        return not options.keep_light
    daylight = read.daylight if read is not None else None
    return True if daylight is None else daylight


def relight_mode_for(options: BatchOptions, read: ProjectSettings | None) -> str | None:
    """A job's relighting (``RelightSession``'s ``relight_mode``) where ``--mode`` leaves
    it to the photo's project: ``"physics"`` when the project chose it in step 2 and
    ``--mode`` is ``auto``; None (as ``--mode`` says) otherwise."""
    if options.mode == "auto" and read is not None and read.relighting == "physics":
        return "physics"
    return None


def _project_key(read: ProjectSettings | None, photo: Path) -> Any:
    """The photo's project as the record compares it: what a batch reads of it (its suns,
    depth map and shadow corrections; its exposure, light and relighting count in the job's),
    so a project saved again with the same ones (the dial moved in step 1, say) is not other
    settings (a user trial's was redone); None without one."""
    if read is None:
        return None
    key = [_sun_key(read.original_sun), _sun_key(read.target_sun),
           _file_key(Path(read.depth_path)) if read.depth_path else None]
    if read.shadow_edits:  # (absent without any: records made before them match)
        from outcast_core.runtime.pipeline.photo_shadows import shadow_edits_to_json

        key.append(shadow_edits_to_json(read.shadow_edits))
    return key


def _file_key(path: Path | None) -> Any:
    """A file as the record compares it: its absolute path, size and modification time."""
    if path is None or not path.is_file():
        return None
    st = path.stat()
    return [str(path.resolve()), st.st_size, st.st_mtime_ns]


def job_settings(job: BatchJob, options: BatchOptions) -> str:
    """Everything that decides a job's output, as one string (compared, not parsed): the
    options its kind reads (suns normalised), the photo and its project file (path, size and
    time: another photo of the same name, or an edited project, is not the same job) and the
    job's own suns from a targets CSV."""
    keys: dict[str, Any] = {
        "kind": options.kind, "fmt": options.fmt, "preset": options.preset,
        "mode": options.mode, "sources": list(options.sources),
        "from_sun": _sun_key(options.from_sun),
        "depth_model": _file_key(Path(options.depth_model).expanduser())
        if options.depth_model else None,
        "use_phone_depth": options.use_phone_depth,
    }
    for name in _KIND_OPTIONS[options.kind]:
        value = getattr(options, name)
        if name == "to_sun":
            value = _sun_key(value)
        elif name == "sweep" and value is not None:
            value = [_sun_key(v) for v in value]
        keys[name] = value
    image = Path(job.image)
    try:
        read = read_project(image)
        project: Any = _project_key(read, image)
    except ValueError:  # the job says why; the file itself stands for it here
        read, project = None, _file_key(image.with_name(image.stem + PROJECT_SUFFIX))
    exposure = exposure_for(options, read)
    if options.kind != "deshadow" and exposure != "photo":
        keys["exposure"] = exposure  # (absent at the photo's: records made before it match)
    if options.kind != "deshadow" and not daylight_for(options, read):
        keys["daylight"] = False  # (absent when on: records made before it match)
    relighting = relight_mode_for(options, read)
    if options.kind != "deshadow" and relighting:
        keys["relighting"] = relighting  # (likewise)
    keys.update(photo=_file_key(image), project=project,
                job_to_sun=_sun_key(job.to_sun), job_from_sun=_sun_key(job.from_sun))
    return json.dumps(keys, sort_keys=True)


#: :func:`settings_for_source`: the ``from_sun`` of an output whose sun came from elsewhere.
FROM_SUN_NOT_USED = "not used"


def settings_for_source(job: BatchJob, options: BatchOptions, source: str | None) -> str:
    """``job``'s settings as its record keeps them once its sun came from ``source``: when
    ``--from`` (the ``given`` source) could not have decided it (a CSV sun, or a source before
    ``given`` in ``options.sources``; the sun in the frame stands where the first of ``exif``
    and ``auto`` stands), ``from_sun`` reads :data:`FROM_SUN_NOT_USED`, so a rerun that adds
    or changes ``--from`` keeps that output as done. ``source`` None: the settings such a
    record holds (what :func:`plan_batch` compares too).

    Example:
        >>> opts = BatchOptions(kind="deshadow", from_sun=(120.0, 39.0))
        >>> job = BatchJob("a.jpg", "out/a.jpg")
        >>> job = replace(job, settings=job_settings(job, opts))
        >>> settings_for_source(job, opts, "given") == job.settings
        True
        >>> '"from_sun": "not used"' in settings_for_source(job, opts, "exif")
        True
    """
    keys = json.loads(job.settings or job_settings(job, options))
    if source is not None:
        order = list(options.sources)
        if source == "sun in the frame":
            source = next((s for s in order if s in ("exif", "auto")), source)
        before_given = source in order and source != "given" and (
            "given" not in order or order.index(source) < order.index("given"))
        if not (source == "csv" or before_given):  # an unknown source counts as used
            return json.dumps(keys, sort_keys=True)
    keys["from_sun"] = FROM_SUN_NOT_USED
    return json.dumps(keys, sort_keys=True)


@dataclass(frozen=True)
class RecordEntry:
    """One output in the batch record (:data:`RECORD_NAME`).

    Attributes:
        settings: what it was made with (:func:`job_settings`, :func:`settings_for_source`).
        from_sun: the original sun it was made with; None until its job was heard to finish
            (recorded before the work) and in records written before suns were kept.
        sun_source: where ``from_sun`` came from (:attr:`JobResult.sun_source`).
        to_sun: the new sun (relighting), or None.
        warnings: the job's :attr:`JobResult.warnings`, so a skipped output still says them.
    """

    settings: str
    from_sun: Sun | None = None
    sun_source: str = ""
    to_sun: Sun | None = None
    warnings: tuple[str, ...] = ()

    def as_json(self) -> dict[str, Any]:
        data = {"settings": self.settings, "from_sun": _plain_sun(self.from_sun),
                "sun_source": self.sun_source, "to_sun": _plain_sun(self.to_sun)}
        if self.warnings:  # (absent without: records from before warnings read the same)
            data["warnings"] = list(self.warnings)
        return data

    @classmethod
    def from_json(cls, value: Any) -> RecordEntry | None:
        """An entry as :meth:`as_json` writes it, or a bare settings string (records written
        before suns were kept); None for anything else."""
        if isinstance(value, str):
            return cls(value)
        if not (isinstance(value, dict) and isinstance(value.get("settings"), str)):
            return None
        source = value.get("sun_source")
        warnings = value.get("warnings")
        warnings = (tuple(w for w in warnings if isinstance(w, str))
                    if isinstance(warnings, list) else ())
        return cls(value["settings"], _recorded_sun(value.get("from_sun")),
                   source if isinstance(source, str) else "", _recorded_sun(value.get("to_sun")),
                   warnings)


def _plain_sun(sun: Sun | None) -> list[float] | None:
    return None if sun is None else [float(sun[0]), float(sun[1])]


def _recorded_sun(value: Any) -> Sun | None:
    """A sun as the record keeps it (``[az, el]``), or None when it is not one."""
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int | float) and not isinstance(v, bool)
                    and math.isfinite(v) for v in value)):
        return None
    return float(value[0]), float(value[1])


def read_record_entries(out_dir: str | os.PathLike[str]) -> dict[str, RecordEntry]:
    """The output folder's :data:`RECORD_NAME` (output name -> :class:`RecordEntry`); empty
    when it is missing or unreadable (every existing output is then ``stale``, never
    overwritten)."""
    path = Path(out_dir) / RECORD_NAME
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    entries = {str(k): RecordEntry.from_json(v) for k, v in data.items()}
    return {k: v for k, v in entries.items() if v is not None}


def read_record(out_dir: str | os.PathLike[str]) -> dict[str, str]:
    """The settings of :func:`read_record_entries` (output name -> settings)."""
    return {k: v.settings for k, v in read_record_entries(out_dir).items()}


def record_done(out_dir: str | os.PathLike[str], jobs: Sequence[BatchJob],
                results: Sequence[JobResult] = ()) -> None:
    """Add jobs to the output folder's record (one write, replaced atomically). The batch
    command records the jobs whose outputs are new before it runs them (an output is written
    atomically, so an existing one is then finished and made with these settings, even when
    the batch was stopped before it heard so), and every output again when it is done, with
    its ``done`` result (of ``results``, by output): its suns are recorded with it."""
    from outcast_core.runtime.io.imageio import atomic_output

    if not jobs:
        return
    record = read_record_entries(out_dir)
    done = {r.output: r for r in results if r.status == "done"}
    for job in jobs:
        r = done.get(job.output)
        record[Path(job.output).name] = RecordEntry(job.settings) if r is None else RecordEntry(
            job.settings, r.from_sun, r.sun_source, r.to_sun, tuple(r.warnings))
    data = {k: v.as_json() for k, v in record.items()}
    with atomic_output(Path(out_dir) / RECORD_NAME, force=True) as tmp:
        tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8")


def planned_suns(job: BatchJob, options: BatchOptions) -> tuple[Sun | None, str, Sun | None]:
    """``(from_sun, sun_source, to_sun)`` of ``job`` as far as they are known without running
    it (for an output done by an earlier batch whose record does not say them): the original
    sun of a CSV row, or of ``options.sources`` up to the first that needs the photo read
    (``exif``, ``auto``; then ``(None, "")``), and the new sun of a relighting
    (:func:`target_sun_for`, or None when there is none).
    """
    try:
        read = read_project(job.image)
    except ValueError:  # the job would fail; it did not, or it would not be done
        read = None
    project_sun, project_target = (None, None) if read is None else (read.original_sun,
                                                                     read.target_sun)
    to_sun = None
    if options.kind == "relight":
        to_sun = next((s for s in (job.to_sun, options.to_sun, project_target) if s is not None),
                      None)
    if job.from_sun is not None:
        return job.from_sun, "csv", to_sun
    for source in options.sources:
        if source == "project" and project_sun is not None:
            return project_sun, "project", to_sun
        if source == "given" and options.from_sun is not None:
            return options.from_sun, "given", to_sun
        if source in ("exif", "auto"):  # (and the sun in the frame) need the photo
            break
    return None, "", to_sun


# -------------------------------------------------------------------------------- suns
@dataclass(frozen=True)
class ProjectSettings:
    """What a batch takes from a photo's project file (:func:`read_project`)."""

    original_sun: Sun | None
    target_sun: Sun | None
    depth_path: str
    exposure: str | None
    #: The user's corrections of the found shadows (the app's "Not a shadow" / "Mark
    #: shadow"; :class:`~outcast_core.runtime.pipeline.photo_shadows.ShadowEdit`).
    shadow_edits: tuple[Any, ...] = ()
    #: Whether relit photos take the new sun's daylight (False: step 2's "Keep the photo's
    #: light"); None in projects from before the setting.
    daylight: bool | None = None
    #: Step 2's relighting (``learned`` or ``physics``; ``RelightSession.relight_mode``); None
    #: in projects from before the choice.
    relighting: str | None = None
    #: The photo the project was saved with (pixel size and fingerprint); None in projects
    #: from before the app recorded it.
    photo: PhotoIdentity | None = None
    #: The project file's name (for messages).
    name: str = ""


def _project_data(photo: Path) -> tuple[Path, dict[str, Any]] | None:
    """The app's project file next to ``photo`` and its JSON, checked (version, photo); None
    without one. Raises ``ValueError`` as :func:`project_suns` says."""
    project = photo.with_name(photo.stem + PROJECT_SUFFIX)
    if not project.is_file():
        return None
    if project.stat().st_size > MAX_PROJECT_BYTES:
        raise ValueError(f"project '{project.name}' is larger than {MAX_PROJECT_BYTES} bytes")
    try:
        data = json.loads(project.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ValueError(f"project '{project.name}' is not valid JSON: {exc}") from exc
    if not isinstance(data, dict) or data.get("outcast_project") != 1:
        raise ValueError(f"project '{project.name}' is not an OutCast project (version 1)")
    image = data.get("image") or ""
    if image and Path(str(image)).name != photo.name:
        raise ValueError(f"project '{project.name}' is for '{image}', not '{photo.name}'")
    return project, data


def read_project(photo: str | os.PathLike[str]) -> ProjectSettings | None:
    """What a batch takes from the app's project file next to ``photo`` (read once), or None
    without one.

    Reads ``NAME.outcast.json`` (the format of :mod:`app.state`) without the app: its
    ``original_sun`` (the sun the user confirmed last: a project saved while re-aligning
    still gives that one, the dial's being no answer yet), ``target_sun``, ``depth_path`` (a
    depth map the user loaded, relative to the project file), ``exposure`` ("Meter the new
    light"; None in projects from before it), ``shadow_edits`` (the user's corrections of
    the found shadows; none in projects from before them), ``daylight`` (false: "Keep the
    photo's light"; None in projects from before it), ``relighting`` (step 2's "Relighting";
    None in projects from before it) and ``photo``, the identity of the photo
    it was saved with (:class:`~outcast_core.runtime.io.photo_identity.PhotoIdentity`; None in
    projects from before it), which a batch checks against the photo it reads.

    Raises:
        ValueError: the project file is not a valid OutCast project, is for another photo, or
            holds a sun, an exposure, a light, a relighting or a photo identity the app does
            not write.
    """
    from outcast_core.runtime.pipeline.relight import EXPOSURES

    found = _project_data(Path(photo))
    if found is None:
        return None
    project, data = found

    def sun(key: str) -> Sun | None:
        value = data.get(key)
        if value is None:
            return None
        try:
            return _parse_sun(str(value["azimuth"]), str(value["elevation"]),
                              f"project '{project.name}' {key}")
        except (KeyError, TypeError):
            raise ValueError(f"project '{project.name}' {key}: expected azimuth and "
                             f"elevation, got {value!r}") from None

    depth = data.get("depth_path") or ""
    if depth and not os.path.isabs(depth):
        depth = str((project.parent / depth).resolve())
    exposure = data.get("exposure")
    if exposure is not None and exposure not in EXPOSURES:
        raise ValueError(f"project '{project.name}' exposure: expected one of {EXPOSURES}, got "
                         f"{exposure!r}")
    daylight = data.get("daylight")
    if "daylight" in data and not isinstance(daylight, bool):  # null too, as the app says
        raise ValueError(f"project '{project.name}' daylight: expected true or false, got "
                         f"{daylight!r}")
    relighting = data.get("relighting")
    if "relighting" in data and relighting not in PROJECT_RELIGHTINGS:  # null too, as the app
        raise ValueError(f"project '{project.name}' relighting: expected one of "
                         f"{PROJECT_RELIGHTINGS}, got {relighting!r}")
    from outcast_core.runtime.pipeline.photo_shadows import shadow_edits_from_json

    try:
        edits = shadow_edits_from_json(data.get("shadow_edits"))
    except ValueError as exc:
        raise ValueError(f"project '{project.name}' shadow_edits: {exc}") from None
    try:
        photo_id = PhotoIdentity.from_any(data.get("photo"))
    except ValueError as exc:
        raise ValueError(f"project '{project.name}' photo: {exc}") from None
    return ProjectSettings(sun("original_sun"), sun("target_sun"), str(depth), exposure, edits,
                           daylight, relighting, photo_id, project.name)


def project_suns(photo: str | os.PathLike[str]) -> tuple[Sun | None, Sun | None, str]:
    """``(original_sun, target_sun, depth_path)`` of :func:`read_project`; ``(None, None, "")``
    without a project."""
    read = read_project(photo)
    return (None, None, "") if read is None else (read.original_sun, read.target_sun,
                                                  read.depth_path)


def project_exposure(photo: str | os.PathLike[str]) -> str | None:
    """The ``exposure`` of :func:`read_project` (None without a project or the setting)."""
    read = read_project(photo)
    return None if read is None else read.exposure


def original_sun_for(
    job: BatchJob,
    options: BatchOptions,
    exif: Any,
    project_sun: Sun | None,
    auto: Callable[[], Sun | None] | None = None,
    tilt: tuple[float, float] = (0.0, 0.0),
    seen: Sun | None = None,
) -> tuple[Sun, str]:
    """The photo's original sun and where it came from (``csv``, ``sun in the frame`` or one of
    ``options.sources``).

    Args:
        job: the photo (a CSV ``from_sun`` wins).
        options: ``sources`` in order, and the ``given`` sun.
        exif: the photo's metadata.
        project_sun: the project file's confirmed sun.
        auto: runs the automatic sun (slow: called only when its turn comes); returns None
            when it is not confident. None: the ``auto`` source is unavailable.
        tilt: the camera's ``(pitch, roll)``: the EXIF sun is turned into the camera's frame.
        seen: the sun the photo shows (:func:`~outcast_core.runtime.pipeline.auto_sun.
            sun_in_photo`): exact, so it takes the place of the first of ``exif`` and ``auto``
            in ``options.sources`` (a compass heading can be off by 130°, as on the ski-slope
            sample's).

    Raises:
        ValueError: none of the sources has a sun (one line: what each source lacked, a
            night photo's sun below the horizon included, and what to do).
    """
    if job.from_sun is not None:
        return job.from_sun, "csv"
    for source in options.sources:
        if source == "project" and project_sun is not None:
            return project_sun, "project"
        if seen is not None and source in ("exif", "auto"):  # the first found-by-itself one
            return seen, "sun in the frame"
        if source == "exif":
            from outcast_core.runtime.pipeline.timelapse import exif_sun

            sun = exif_sun(exif, tilt=tilt)
            if sun is not None:
                return sun, "exif"
        if source == "given" and options.from_sun is not None:
            return options.from_sun, "given"
        if source == "auto" and auto is not None:
            sun = auto()
            if sun is not None:
                return sun, "auto"
    from outcast_core.runtime.pipeline.timelapse import exif_sun_problem

    tried = {"project": f"no {Path(job.image).stem}{PROJECT_SUFFIX} with a confirmed sun",
             # what is missing, or the sun below the horizon at the EXIF time and place
             "exif": exif_sun_problem(exif) or "no EXIF sun",
             "auto": "the automatic sun is not sure" if auto is not None
             else "no automatic sun in this version"}
    said = "; ".join(tried[s] for s in options.sources if s != "given")
    todo = "give --from AZ,EL"
    if "given" not in options.sources:
        todo = "add 'given' to --sources" + ("" if options.from_sun else f" and {todo}")
    raise ValueError(f"no original sun: {said}: {todo}" if said else f"no original sun: {todo}")


def target_sun_for(job: BatchJob, options: BatchOptions, project_target: Sun | None) -> Sun:
    """The new sun: the CSV row's, else ``options.to_sun``, else the project's target sun.

    Raises:
        ValueError: there is none.
    """
    for sun in (job.to_sun, options.to_sun, project_target):
        if sun is not None:
            return sun
    raise ValueError("no new sun: give --to, a targets CSV row or a project with a new sun")


# -------------------------------------------------------------------------------- one job
_REGISTRY: Any = None  # one per process: models load once per worker


def _registry(threads: int | None) -> Any:
    global _REGISTRY
    if _REGISTRY is None or _REGISTRY.threads != threads:
        from outcast_core.runtime.io.models import ModelRegistry

        _REGISTRY = ModelRegistry(threads=threads)
    return _REGISTRY


def one_line(exc: BaseException) -> str:
    """An exception as one line (user errors as their message, others with their type; a
    photo that cannot be read in plain words, without the decoder's: :func:`run_job` keeps
    those in the result's ``details["decoder"]``)."""
    from outcast_core.runtime.io.models import ModelError

    text = " ".join(str(exc).split())
    if isinstance(exc, ValueError | ModelError | FileExistsError) and text:
        return text
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.filename or ''}: {exc.strerror}".lstrip(": ")
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def run_job(job: BatchJob, options: BatchOptions) -> JobResult:
    """Process one photo; a failure is returned as a ``failed`` result, never raised.

    Args:
        job: the photo and its output.
        options: the batch options.

    Returns:
        The result (``done`` or ``failed``).
    """
    t0 = time.perf_counter()
    result = JobResult(job.image, job.output, "failed")
    try:
        _run_job(job, options, result)
        result.status = "done"
    except (Exception, MemoryError) as exc:  # noqa: BLE001 - one photo's failure is reported
        result.message = one_line(exc)
        if getattr(exc, "detail", ""):  # an ImageReadError's decoder words: for the report
            result.details["decoder"] = str(exc.detail)
    result.seconds = time.perf_counter() - t0
    return result


def _run_job(job: BatchJob, options: BatchOptions, result: JobResult) -> None:
    import numpy as np

    from outcast_core.runtime.geometry.camera import sun_angles, sun_vector
    from outcast_core.runtime.io.depth_models import pick_depth_source
    from outcast_core.runtime.io.imageio import (
        in_file_channels,
        output_bit_depth,
        read_depth,
        read_image,
        write_image,
    )
    from outcast_core.runtime.pipeline.session import RelightSession

    read = read_project(job.image)
    project_sun, project_target, depth_path = (
        (None, None, "") if read is None else (read.original_sun, read.target_sun, read.depth_path))
    loaded = read_image(job.image, keep_uint8=True)  # as the app reads it
    if read is not None and read.photo is not None:  # before the slow part
        now = PhotoIdentity.of(loaded.image_srgb)
        why = read.photo.mismatch(now)
        if why:  # the app asks, with "Cancel" the default; a batch cannot ask
            sized = (now.width, now.height) != (read.photo.width, read.photo.height)
            raise ValueError(
                f"the photo does not look like the one project '{read.name}' was saved with"
                f"{f' ({why})' if sized else ''}: its suns and shadow corrections may not fit; "
                "if it is the same picture (edited), open it in the app and save its project "
                "again, else move the project away")
    to_sun = None
    if options.kind == "relight":  # before the slow part
        to_sun = target_sun_for(job, options, project_target)
        result.to_sun = to_sun
    session = RelightSession(registry=_registry(options.threads), preset=options.preset,
                             mode=options.mode, relight_mode=relight_mode_for(options, read))
    session.exposure = exposure_for(options, read)  # (a user trial's metered project was
    # batch-relit unmetered)
    if options.kind != "deshadow":  # (a de-shadowed photo is not relit: no new sun's light)
        session.daylight = daylight_for(options, read)
    depth = read_depth(depth_path) if depth_path else None
    if depth is None:
        width, height = loaded.original_size
        session.depth_provider, _note = pick_depth_source(
            loaded.path, (height, width), model_path=options.depth_model,
            use_phone=options.use_phone_depth, strict=False, photo_srgb=loaded.image_srgb)
    session.set_image(loaded.image_srgb, focal_35mm=loaded.exif.focal_35mm, depth=depth,
                      photo_path=job.image)
    result.warnings = photo_warnings(loaded, session)
    tilt = session.photo_tilt()  # the EXIF sun's frame and the new sun's daylight's horizon
    seen = session.sun_seen  # the sun the photo shows, if it does
    sun, source = original_sun_for(job, options, loaded.exif, project_sun,
                                   _auto_sun(session, loaded.exif, result, tilt), tilt[:2],
                                   seen=None if seen is None else sun_angles(seen.w))
    result.from_sun, result.sun_source = sun, source
    if read is not None:
        session.set_shadow_edits(read.shadow_edits)
    session.set_original_sun(sun_vector(*sun))
    Path(job.output).parent.mkdir(parents=True, exist_ok=True)
    if options.kind == "timelapse":
        _render_timelapse(session, loaded, sun, job, options, tilt[:2])
    else:
        bits = output_bit_depth(job.output, loaded.bit_depth)
        dtype = np.uint8 if bits == 8 else np.float32  # (no full-size float buffer for 8 bits)
        out = (session.relight_full(sun_vector(*to_sun), dtype=dtype) if to_sun
               else session.deshadow_full(dtype=dtype))
        write_image(job.output, in_file_channels(out, loaded), bit_depth=bits,
                    force=options.force, exif=loaded.exif_bytes)
    result.details.update(shadows=session.shadow_mode, relighting=session.relight_mode,
                          depth=session.depth_source,
                          camera={"pitch": round(tilt[0], 2), "roll": round(tilt[1], 2),
                                  "source": tilt[2]},
                          timings={k: round(v, 3) for k, v in session.timings.items()})


def small_photo_note(width: int, height: int) -> str:
    """A warning for a photo too small to relight meaningfully (shorter side under
    :data:`MIN_PHOTO_SIDE`), else "".

    Example:
        >>> small_photo_note(8, 8)[:48]
        'the photo is only 8 x 8 pixels: too small to rel'
        >>> small_photo_note(64, 48)
        ''
    """
    if min(width, height) >= MIN_PHOTO_SIDE:
        return ""
    return (f"the photo is only {width} x {height} pixels: too small to relight meaningfully "
            f"(its shadows are found and cast at that size, and under {MIN_PHOTO_SIDE} pixels "
            "on the shorter side there are too few for them)")


def photo_warnings(loaded: Any, session: Any, *, transparency: bool = True,
                   small: bool = True) -> list[str]:
    """What ``outcast relight`` warns of for a photo (and a batch reports with its result):
    transparency filled with white, a strip's shape
    (:func:`~outcast_core.runtime.pipeline.session.elongation_note`), a photo too small
    (:func:`small_photo_note`) and depth from no model (a flat ground plane). The output is
    made all the same; these say why it may be poor. One list for the command line and
    batch (the app words the file's notes as sentences: ``app.main_window.photo_file_notes``).

    Args:
        loaded: the photo (:class:`~outcast_core.runtime.io.imageio.LoadedImage`).
        session: its session, after ``set_image``.
        transparency: include the transparency's note (the command line says it as it reads
            the photo).
        small: include the note of a photo too small to relight (``outcast sun`` says it in
            the sun's terms: a user trial read of relighting from the sun command).
    """
    from outcast_core.runtime.pipeline.session import elongation_note

    width, height = loaded.original_size
    notes = []
    if transparency and loaded.has_alpha:
        notes.append("its transparency is filled with white (the output has none)")
    notes += [note for note in (elongation_note(width, height),
                                small_photo_note(width, height) if small else "") if note]
    if str(session.depth_source).startswith("ground-plane prior"):
        folder = session.registry.directory_for("depth")
        notes.append(f"no depth model in '{folder}': the depth is a flat ground plane, so the "
                     "predicted shadows will be poor (see 'outcast models')")
    return notes


def _auto_sun(session: Any, exif: Any, result: JobResult,
              tilt: tuple[float, float, str]) -> Callable[[], Sun | None] | None:
    """The ``auto`` source for one photo, or None when this version has no automatic sun."""
    try:
        from outcast_core.runtime.pipeline.auto_sun import (
            SOURCE_SHADOWS,
            SOURCE_SHADOWS_EXIF_ELEVATION,
            exif_sun_prior,
            find_sun,
        )
    except ImportError:
        return None

    def run() -> Sun | None:
        prior = exif_sun_prior(exif)
        fit = find_sun(session, prior=prior, pitch_roll=tilt)
        result.details["auto_sun"] = {"azimuth": round(float(fit.azimuth), 2),
                                      "elevation": round(float(fit.elevation), 2),
                                      "confidence": round(float(fit.confidence), 3),
                                      "found": bool(fit.found)}
        if not fit.found:
            return None
        if fit.source in (SOURCE_SHADOWS, SOURCE_SHADOWS_EXIF_ELEVATION):
            # Its direction from the shadows alone (no compass): said with its result (a user
            # trial's photo without EXIF was relit from a sun 38 degrees off, without a word).
            result.warnings.append(
                f"the original sun ({fit.azimuth:.0f}, {fit.elevation:.0f}) was found from the "
                f"photo's shadows (confidence {fit.confidence:.2f}"
                f"{'; its elevation from the EXIF time and place' if prior else ''}); its "
                "direction can be tens of degrees off: check the output, or align the sun in "
                "the app and save a project")
        return float(fit.azimuth), float(fit.elevation)

    return run


def _render_timelapse(session: Any, loaded: Any, sun: Sun, job: BatchJob,
                      options: BatchOptions, tilt: tuple[float, float] = (0.0, 0.0)) -> None:
    from outcast_core.runtime.pipeline import timelapse as tl

    if options.sweep is not None:
        samples = tl.sweep_path(options.sweep[0], options.sweep[1], options.frames,
                                options.easing)
    else:
        exif = loaded.exif
        # A capture time without a zone is read at its longitude's, as the app's EXIF sun
        # reads it (it was read as UTC here: the heading hours of sun off).
        when, _ = tl.exif_capture_time(exif)
        lat, lon = exif.latitude, exif.longitude
        if when is None or lat is None or lon is None:
            raise ValueError("the capture day's sun path needs the photo's EXIF GPS and time")
        try:
            heading = tl.solve_heading(when, lat, lon, sun[0], original_elevation=sun[1],
                                       tilt=tilt)
        except tl.SunBelowHorizonError:  # a night-time EXIF clock: the compass, else the
            # job says why
            heading = getattr(exif, "heading_deg", None)
            if heading is None:
                raise
        samples = tl.real_sun_path(when.date(), lat, lon, heading, options.frames, tilt=tilt)
    tl.render_timelapse(session, samples, job.output, fps=options.fps, size=options.size,
                        force=options.force)


# -------------------------------------------------------------------------------- many jobs
class _Stop(BaseException):
    """Raised in a worker by SIGTERM: unwinds the job (its writers remove partial outputs)."""


def _worker_init() -> None:
    """Workers leave Ctrl+C to the parent, and turn SIGTERM into :class:`_Stop`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def stop(signum: int, frame: object) -> None:
        raise _Stop()

    signal.signal(signal.SIGTERM, stop)


def _run_in_worker(job: BatchJob, options: BatchOptions) -> JobResult:
    """:func:`run_job` in a worker process: stopped by SIGTERM, it cleans up and exits at once
    (instead of taking the next queued photo)."""
    try:
        return run_job(job, options)
    except _Stop:
        os._exit(143)


def threads_per_worker(workers: int) -> int:
    """onnxruntime threads for each of ``workers`` processes: the cores shared out, at least 1."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, (cores or 1) // max(1, workers))


def run_batch(
    jobs: Sequence[BatchJob],
    options: BatchOptions,
    workers: int = 1,
    on_result: Callable[[JobResult], None] | None = None,
) -> list[JobResult]:
    """Run ``jobs``, in this process (``workers == 1``) or in ``workers`` processes.

    One photo's failure does not stop the others. Ctrl+C (or SIGTERM turned into an exception
    by the caller) stops the workers; what they were writing is removed, finished outputs stay,
    so running the batch again resumes it.

    Args:
        jobs: from :func:`plan_batch`.
        options: the batch options (``threads`` None: the cores shared out among workers).
        workers: number of processes.
        on_result: called in this process with each result as it comes (progress).

    Returns:
        The results in the order of ``jobs``.
    """
    if workers < 1:
        raise ValueError(f"expected at least one worker, got {workers}")
    if options.threads is None:
        options = replace(options, threads=threads_per_worker(workers))
    results: dict[int, JobResult] = {}

    def done(i: int, r: JobResult) -> None:
        results[i] = r
        if on_result is not None:
            on_result(r)

    if workers == 1 or len(jobs) <= 1:
        for i, job in enumerate(jobs):
            done(i, run_job(job, options))
        return [results[i] for i in range(len(jobs))]
    context = get_context("forkserver" if os.name == "posix" else "spawn")
    pool = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=context,
                               initializer=_worker_init)
    pending: dict[Future[JobResult], int] = {}
    try:
        pending = {pool.submit(_run_in_worker, job, options): i for i, job in enumerate(jobs)}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                i = pending.pop(fut)
                try:
                    r = fut.result()
                except Exception as exc:  # noqa: BLE001 - a worker died (killed, out of memory)
                    r = JobResult(jobs[i].image, jobs[i].output, "failed",
                                  f"the worker stopped: {one_line(exc)}")
                done(i, r)
    except BaseException:
        _stop_workers(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return [results[i] for i in range(len(jobs))]


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """SIGTERM every worker of ``pool`` (they clean up their partial outputs and exit)."""
    processes: Iterable[Any] = (getattr(pool, "_processes", None) or {}).values()
    for process in list(processes):
        with contextlib.suppress(Exception):
            process.terminate()


def summarize(results: Sequence[JobResult]) -> dict[str, int]:
    """Counts of ``done``, ``skipped``, ``stale`` and ``failed`` results."""
    counts = {"done": 0, "skipped": 0, "stale": 0, "failed": 0}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    return counts
