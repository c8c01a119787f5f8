"""``outcast batch IN_DIR -o OUT_DIR``: relight, de-shadow or time-lapse every photo of a folder.

Registered by :data:`outcast_core.runtime.cli.main.OPTIONAL_COMMANDS`; the work is
:mod:`outcast_core.runtime.pipeline.batch`. One line per photo as it finishes, with the
warnings ``outcast relight`` would give for it (``-q``: only failures and warnings), a summary
at the end; exit status 0 when every photo is done or was already done with the same
settings, 2 when one failed (the rest are still done) or an output made with other settings was
kept (``--force`` redoes it). Running the same command again resumes a batch.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from outcast_core.runtime.cli.main import (
    DEFAULT_CLI_PRESET,
    add_exposure_option,
    add_light_option,
    int_in,
    names_in,
    sun_pair,
)
from outcast_core.runtime.cli.timelapse_cli import (
    SWEEP_HELP,
    fps_value,
    frame_count,
    sweep_ends,
    sweep_turn_note,
)
from outcast_core.runtime.pipeline.batch import (
    FORMATS,
    RECORD_NAME,
    SUN_SOURCES,
    BatchJob,
    BatchOptions,
    JobResult,
    other_files,
    plan_batch,
    read_targets_csv,
    record_done,
    run_batch,
    settings_for_source,
    summarize,
)
from outcast_core.runtime.pipeline.timelapse import MAX_FPS, MIN_FPS


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``outcast batch`` to an argparse sub-parser set.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers()``.

    Returns:
        The ``batch`` parser.
    """
    from outcast_core.runtime.pipeline.timelapse import EASINGS, FRAME_SIZES

    p = subparsers.add_parser(
        "batch", help="relight, de-shadow or time-lapse every photo of a folder",
        description="Processes every photo in IN_DIR (not its sub-folders) into OUT_DIR/NAME.FMT. "
        "Each photo's original sun comes from the first of --sources that has one: its project "
        "file NAME.outcast.json (the sun confirmed in the app), its EXIF (GPS, time and "
        "heading), --from, or the automatic sun (when it is confident). The new sun is --to, "
        "a row of --targets, or the project's. "
        "Finished outputs are skipped (run again to resume; --force redoes them); one photo's "
        "failure is reported and the others are done (exit status 2).",
    )
    p.add_argument("folder", metavar="IN_DIR", help="folder of photos")
    p.add_argument("-o", "--output", required=True, metavar="OUT_DIR",
                   help="output folder (made when missing, in a folder that exists)")
    what = p.add_mutually_exclusive_group()
    what.add_argument("--deshadow", action="store_true",
                      help="write each photo with its own shadows removed")
    what.add_argument("--sweep", type=sweep_ends, metavar="AZ1,EL1:AZ2,EL2",
                      help=f"write a time-lapse of each photo, the sun swept A -> B; {SWEEP_HELP}")
    what.add_argument("--day", action="store_true",
                      help="write a time-lapse of each photo along the real sun path of its "
                           "capture day (needs EXIF GPS and time)")
    p.add_argument("--to", dest="to_sun", type=sun_pair, metavar="AZ,EL",
                   help="the new sun for every photo (relighting)")
    p.add_argument("--targets", metavar="CSV",
                   help="a table with columns image,to_az,to_el[,from_az,from_el][,output]: "
                        "the photos to do and their suns")
    p.add_argument("--from", dest="from_sun", type=sun_pair, metavar="AZ,EL",
                   help="the original sun of photos with no project file or EXIF sun")
    p.add_argument("--sources", type=names_in(SUN_SOURCES, "sources"), default=SUN_SOURCES,
                   metavar="LIST",
                   help="where original suns come from, in order (default "
                        f"{','.join(SUN_SOURCES)}; 'given' is --from, 'auto' the automatic sun)")
    p.add_argument("--format", dest="fmt", default="", metavar="FMT",
                   help="output format: jpg, png, tif (16-bit) or webp for stills (default "
                        "jpg); mp4, gif or webp for time-lapses (default mp4)")
    p.add_argument("--frames", type=frame_count, default=48, help="time-lapse frames (default 48)")
    p.add_argument("--easing", choices=EASINGS, default=None,
                   help="the time-lapse sweep's pace (--sweep only; default ease-in-out)")
    p.add_argument("--fps", type=fps_value, default=12.0,
                   help=f"time-lapse frames per second, {MIN_FPS:g}..{MAX_FPS:g} (default 12)")
    p.add_argument("--size", choices=FRAME_SIZES, default="1080p",
                   help="time-lapse frame size (default 1080p)")
    add_exposure_option(p, "keep the photo's exposure, or meter the new light again as a "
                           "camera would (default: what the photo's project says, else the "
                           "photo's)", default=None)
    add_light_option(p, "keep the photo's light, its strength and colour, whatever the new "
                        "sun's height (--no-keep-light: the new sun's daylight); either "
                        "overrides the photos' projects (default: what the photo's project "
                        "says, else the new sun's daylight)", overrides=True)
    p.add_argument("--preset", choices=["fast", "balanced", "accurate"], default=DEFAULT_CLI_PRESET,
                   help="speed/accuracy preset")
    p.add_argument("--mode", choices=["auto", "learned", "classic"], default="auto",
                   help="learned networks (default when installed) or Direct + physics; "
                   "with auto, a photo whose project chose physics relighting gets it")
    p.add_argument("--depth-model", metavar="MODEL.onnx", default=None,
                   help="an ONNX depth model to use instead of the shipped one")
    p.add_argument("--no-phone-depth", action="store_true",
                   help="ignore depth maps stored inside the photos")
    p.add_argument("--workers", type=int_in(1, 256, "worker count"), default=1,
                   help="worker processes (default 1); the cores are shared among them")
    p.add_argument("--report", metavar="REPORT.json", default="",
                   help="also write every photo's result (sun, source, time, error) as JSON; "
                        "a report of this batch (the same IN_DIR and OUT_DIR) is replaced by "
                        "each run, so a rerun resumes and rewrites it; any other file is kept "
                        "(--force replaces it)")
    p.add_argument("--force", action="store_true",
                   help="redo photos whose output exists (and replace a --report file that is "
                        "not this batch's)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="print only failures and warnings (and then the summary line)")
    p.set_defaults(func=run_batch_command, check_output=check_batch_output)
    return p


def _options(args: argparse.Namespace) -> BatchOptions:
    kind = "deshadow" if args.deshadow else "timelapse" if (args.sweep or args.day) else "relight"
    if args.fmt and args.fmt.lower().lstrip(".") not in FORMATS[kind]:
        raise ValueError(f"expected --format in {', '.join(FORMATS[kind])} for {kind}, got "
                         f"{args.fmt!r}")
    if args.sources == ("given",) and args.from_sun is None:
        raise ValueError("expected --from AZ,EL with --sources given")
    if kind != "relight" and args.to_sun is not None:
        # (a user trial's --to beside --deshadow and --sweep was ignored without a word)
        what = {"deshadow": "--deshadow", "timelapse": "--sweep" if args.sweep else "--day"}
        raise ValueError(f"--to is the new sun of a relighting; {what[kind]} takes none "
                         f"(leave out --to, or leave out {what[kind]} to relight)")
    if args.easing is not None and not args.sweep:  # (as outcast timelapse refuses it)
        raise ValueError("--easing is the pace of a --sweep; "
                         + ("--day follows the real sun's clock" if args.day
                            else "leave it out, or add --sweep"))
    return BatchOptions(
        kind=kind, sources=args.sources, from_sun=args.from_sun, to_sun=args.to_sun,
        fmt=args.fmt, preset=args.preset, mode=args.mode, depth_model=args.depth_model,
        use_phone_depth=not args.no_phone_depth, sweep=args.sweep, day=args.day,
        frames=args.frames, easing=args.easing or "ease-in-out", fps=args.fps, size=args.size,
        exposure=args.exposure, keep_light=args.keep_light, force=args.force)


def check_batch_output(args: argparse.Namespace) -> None:
    """Before any work: IN_DIR is a folder, OUT_DIR is not it and can be written, or made in
    an existing folder (the batch makes OUT_DIR, not the folders above it: a typo in their
    names is refused, as for every output), and ``--report`` can be written."""
    from outcast_core.runtime.cli.main import CliError, check_folder_writable, check_output_path

    folder, out = Path(args.folder).expanduser(), Path(args.output).expanduser()
    if not folder.is_dir():
        raise CliError(f"'{args.folder}' is not a folder")
    if out.exists() and not out.is_dir():
        raise CliError(f"cannot write into '{args.output}': it is a file, not a folder")
    if out.exists() and out.resolve() == folder.resolve():
        raise CliError("expected an output folder other than the input folder (the outputs "
                       "have the photos' names)")
    # before any photo: OUT_DIR itself, or the folder it is made in
    check_folder_writable(out if out.exists() else out.parent,
                          f"cannot write into '{args.output}'")
    if args.report:
        report = Path(args.report).expanduser()
        ours = _our_report(args.report, folder, out)
        if report.is_file() and not (ours or args.force):
            raise FileExistsError(
                f"'{args.report}' already exists and is not a report of this batch "
                f"('{args.folder}' into '{args.output}'); choose another name, or use --force "
                "to replace it (--force also redoes every photo)")
        if not out.exists() and report.parent.resolve() == out.resolve():
            # in OUT_DIR, which the batch makes (checked above): a new file, its name checked
            # (a user trial's "-o out --report out/r.json" was refused: "folder does not exist")
            if report.suffix.lower() != ".json":
                raise CliError(f"cannot write '{args.report}': expected an extension in .json, "
                               f"got '{report.suffix}'")
        else:
            check_output_path(args.report, extensions=(".json",), force=args.force or ours,
                              inputs=[args.targets])


#: The report's marker (:func:`_our_report`): a file without it is not a batch's report.
REPORT_MARKER = "outcast_batch_report"


def _our_report(report: str, folder: Path, out: Path) -> bool:
    """Whether ``report`` is a report ``outcast batch`` wrote for this batch (the same input
    and output folders): then a run replaces it without ``--force``. A rerun is how a batch is
    resumed, and its report was refused as an existing file, while ``--force`` would redo
    every photo (a user trial). A report of another batch, or any other file, is kept.

    Reports written before the marker are known by their shape: options, counts and results,
    every result's photo in ``folder`` and its output in ``out``."""
    path = Path(report).expanduser()
    if not path.is_file() or path.stat().st_size > 100_000_000:
        return False
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    if not isinstance(data, dict):
        return False

    def same(value: Any, where: Path) -> bool:
        return isinstance(value, str) and bool(value) and _same_folder(Path(value), where)

    if REPORT_MARKER in data:
        return (data[REPORT_MARKER] == 1 and same(data.get("input_folder"), folder)
                and same(data.get("output_folder"), out))
    results = data.get("results")
    if not ({"options", "counts", "results"} <= set(data) and isinstance(results, list)
            and results and all(isinstance(r, dict) for r in results)):
        return False
    return all(same(str(Path(str(r.get("image", ""))).parent), folder)
               and same(str(Path(str(r.get("output", ""))).parent), out) for r in results)


def _same_folder(a: Path, b: Path) -> bool:
    try:
        return a.expanduser().resolve() == b.expanduser().resolve()
    except (OSError, RuntimeError):
        return False


def _suns(r: JobResult) -> str:
    """A result's suns in words ("sun 273.5,66.8 from exif -> 90,30"), or ``""``."""
    sun = f"sun {r.from_sun[0]:.1f},{r.from_sun[1]:.1f} from {r.sun_source}" if r.from_sun else ""
    to = f"-> {r.to_sun[0]:g},{r.to_sun[1]:g}" if r.to_sun else ""
    return " ".join(part for part in (sun, to) if part)


def _line(r: JobResult, index: int, total: int) -> str:
    name = Path(r.image).name
    head = f"[{index:>{len(str(total))}}/{total}] {name}"
    if r.status == "failed":
        return f"{head}: failed: {r.message}"
    if r.status == "skipped":
        suns = _suns(r)
        return f"{head}: skipped{f' ({suns})' if suns else ''}: {r.message}{_warned(r)}"
    if r.status == "stale":
        return f"{head}: kept: {r.message}"
    return f"{head} -> {Path(r.output).name} ({_suns(r)}; {r.seconds:.1f} s){_warned(r)}"


def _few(paths: list[Path]) -> str:
    """The first three names of ``paths``, and how many more."""
    return ", ".join(p.name for p in paths[:3]) + (
        f" and {len(paths) - 3} more" if len(paths) > 3 else "")


def _warned(r: JobResult) -> str:
    """A done or skipped result's warnings, to end its line (``outcast relight`` says them for
    one photo; a batch said nothing: a user trial), or ``""``."""
    if not r.warnings:
        return ""
    return f"; warning{'s' if len(r.warnings) > 1 else ''}: " + "; ".join(r.warnings)


def run_batch_command(args: argparse.Namespace) -> int:
    """Handler of ``outcast batch``; returns 0, or 2 when a photo failed."""
    options = _options(args)
    targets = read_targets_csv(args.targets) if args.targets else None
    out_dir = Path(args.output).expanduser()
    jobs, early = plan_batch(args.folder, out_dir, options, targets)
    total = len(jobs) + len(early)
    if total == 0:
        raise ValueError(f"no photos in '{args.folder}' (expected JPEG, PNG, TIFF, WebP, HEIC "
                         "or BMP files)")
    others = other_files(args.folder, exclude=[args.targets, args.report])
    if others and not args.quiet:  # (a user trial: notes.txt went unmentioned)
        said = ("1 file is not a photo and was" if len(others) == 1
                else f"{len(others)} files are not photos and were")
        print(f"outcast batch: note: {said} left alone: {_few(others)}", file=sys.stderr)
    folders = sorted(p for p in Path(args.folder).expanduser().iterdir()
                     if p.is_dir() and not p.name.startswith("."))
    if folders and not args.quiet:  # (a robustness trial: a sub-folder went unmentioned)
        said = ("1 sub-folder is" if len(folders) == 1 else f"{len(folders)} sub-folders are")
        print(f"outcast batch: note: {said} not looked into (photos directly in the folder "
              f"only): {_few(folders)}", file=sys.stderr)
    if options.day and options.exposure != "metered" and jobs and not args.quiet:
        # (as `outcast timelapse` measures and says for one photo: a user trial's day had
        # near-black first and last frames; here once, not measured per photo)
        print("outcast batch: note: a day's first and last frames, the sun at the horizon, come "
              "out dark where the photo's exposure is kept (a project's \"Meter the new "
              "light\" meters them); --exposure metered meters every frame", file=sys.stderr)
    turn = sweep_turn_note(options.sweep) if options.sweep else ""
    if turn and jobs and not args.quiet:  # (as `outcast timelapse` says it)
        print(f"outcast batch: note: {turn}", file=sys.stderr)
    unused = sum(row["to_sun"] is not None for row in targets or ()) if (
        options.kind != "relight") else 0
    if unused and not args.quiet:  # (a user trial: they were ignored without a word)
        what = "--deshadow" if options.kind == "deshadow" else (
            "--sweep" if options.sweep else "--day")
        print(f"outcast batch: note: {what} uses no new sun: the targets CSV's to_az, to_el "
              f"of {unused} photo{'s' if unused != 1 else ''} are left unused (its photos, "
              "original suns and output names are used)", file=sys.stderr)
    if options.kind == "relight" and options.to_sun is None and targets is None and jobs:
        print("outcast batch: note: no --to or --targets: each photo's project gives the new "
              "sun", file=sys.stderr)
    out_dir.mkdir(exist_ok=True)  # in a folder that exists (check_batch_output)
    count = 0
    t0 = time.perf_counter()

    # The record of each output's settings: a rerun skips an output only when it was made with
    # the same ones. New outputs are recorded before the work (written atomically, one that
    # exists is finished), and every output again as it finishes, with the source its sun came
    # from (--from did not decide a sun from the project, EXIF or the frame).
    redone = {job.output: job for job in jobs if Path(job.output).exists()}
    by_output = {job.output: job for job in jobs}

    def record(done: list[BatchJob], results: tuple[JobResult, ...] = ()) -> None:
        try:
            record_done(out_dir, done, results)
        except OSError as exc:  # the outputs matter more than the record
            print(f"outcast batch: warning: cannot update {RECORD_NAME}: "
                  f"{exc.strerror or exc}", file=sys.stderr)

    record([job for job in jobs if job.output not in redone])

    seen: list[JobResult] = []  # what has ended, for an interrupted batch's report

    def show(r: JobResult) -> None:
        nonlocal count
        count += 1
        seen.append(r)
        if r.status == "done" and r.output in by_output:
            job = by_output[r.output]
            record([replace(job, settings=settings_for_source(job, options, r.sun_source))], (r,))
        if r.status == "failed" or r.warnings or not args.quiet:  # (-q: failures, warnings)
            print(_line(r, count, total), file=sys.stderr, flush=True)

    if jobs and not args.quiet:  # (first: a rerun's skipped lines came before it)
        # (the lines count all the photos: a rerun's "processing 4 photos" above [1/8] to
        # [8/8] read as a contradiction in a user trial)
        of = f" of {total}" if early else ""
        words = {"skipped": "already done", "stale": "kept (made otherwise)",
                 "failed": "refused"}
        rest = ", ".join(f"{n} {words.get(status, status)}" for status, n in sorted(
            summarize(early).items()) if n and status in words)
        print(f"processing {len(jobs)}{of} photo{'s' if total != 1 else ''} ({options.kind}) "
              f"with {min(args.workers, len(jobs))} worker(s){f'; {rest}' if rest else ''}",
              file=sys.stderr, flush=True)
    def write_report(results: list[JobResult], seconds: float, interrupted: bool) -> None:
        from outcast_core.runtime.io.imageio import atomic_output

        warned = [r for r in results if r.warnings and r.status in ("done", "skipped")]
        data = {REPORT_MARKER: 1, "input_folder": str(Path(args.folder).expanduser().resolve()),
                "output_folder": str(out_dir.resolve()), "options": dict(vars(options)),
                "counts": summarize(results), "with_warnings": len(warned),
                "seconds": round(seconds, 2),
                # The photos not reached are in neither list: not_reached counts them.
                **({"interrupted": True, "not_finished": total - len(results)}
                   if interrupted else {}),
                # Paths as the folders are given: absolute (the image's was relative when the
                # folder was, beside an absolute input_folder: a user trial).
                # (no expanduser: the folders were expanded, and a photo named "~trip.jpg"
                # in "." is no home folder)
                "results": [{**vars(r), "image": os.path.abspath(r.image),
                             "output": os.path.abspath(r.output)} for r in results]}
        # (checked again: a file that appeared meanwhile is not replaced)
        force = args.force or _our_report(args.report, Path(args.folder), out_dir)
        with atomic_output(Path(args.report).expanduser(), force=force) as tmp:
            tmp.write_text(json.dumps(data, indent=2, default=list) + "\n", encoding="utf-8")

    try:
        for r in early:
            show(r)
        results = early + run_batch(jobs, options, workers=args.workers, on_result=show)
    except KeyboardInterrupt:
        # Ctrl+C or SIGTERM: what ended is said and reported, and how to go on (an interrupted
        # batch said "interrupted" alone and wrote no report: a user trial).
        ended = list(seen)
        c = summarize(ended)
        kept = f"{c['stale']} kept (made otherwise), " if c["stale"] else ""
        print(f"outcast batch: stopped after {len(ended)} of {total} photos ({c['done']} done, "
              f"{c['skipped']} skipped, {kept}{c['failed']} failed); nothing half-written is "
              "left: the same command again goes on where this one stopped (finished outputs "
              "are skipped)", file=sys.stderr)
        if args.report:
            try:
                write_report(ended, time.perf_counter() - t0, interrupted=True)
            except Exception as exc:  # noqa: BLE001 (the interruption is what is raised)
                # (not atomic_output's "use --force": here --force redoes every photo too)
                why = ("a file that is not this batch's report is there, and is kept"
                       if isinstance(exc, FileExistsError)
                       else getattr(exc, "strerror", None) or exc)
                print(f"outcast batch: warning: the report '{args.report}' was not written: "
                      f"{why}", file=sys.stderr)
            except KeyboardInterrupt:  # a second Ctrl+C while it is written
                print(f"outcast batch: warning: the report '{args.report}' was not written",
                      file=sys.stderr)
        raise
    counts = summarize(results)
    seconds = time.perf_counter() - t0
    warned = [r for r in results if r.warnings and r.status in ("done", "skipped")]
    if args.report:
        write_report(results, seconds, interrupted=False)
    if not args.quiet or counts["failed"] or counts["stale"] or warned:
        stale = f"{counts['stale']} kept (made otherwise), " if counts["stale"] else ""
        new = sum(r.status == "done" for r in warned)
        print(f"{counts['done']} done{f' ({new} with warnings)' if new else ''}, "
              f"{counts['skipped']} skipped (already done), {stale}"
              f"{counts['failed']} failed in {seconds:.1f} s", file=sys.stderr)
    if warned:  # made, but maybe poor: said (the exit status stays 0)
        print(f"outcast batch: warning: {len(warned)} of {total} outputs were made despite a "
              f"warning (see their lines): {_names(warned)}", file=sys.stderr)
    if counts["stale"]:
        kept = _names([r for r in results if r.status == "stale"])
        # (with other settings, or not by a batch at all: a user trial's own file was said
        # to be "from other settings"; each photo's line says which)
        print(f"outcast batch: error: {counts['stale']} of {total} outputs exist, made "
              f"otherwise than this batch would make them, and were kept, not redone: {kept} "
              "(use --force to redo them)", file=sys.stderr)
    if counts["failed"]:
        print(f"outcast batch: error: {counts['failed']} of {total} photos failed: "
              f"{_names([r for r in results if r.status == 'failed'])}", file=sys.stderr)
    return 2 if counts["failed"] or counts["stale"] else 0


def _names(results: list[JobResult]) -> str:
    names = [Path(r.image).name for r in results]
    return ", ".join(names[:10]) + (" ..." if len(names) > 10 else "")
