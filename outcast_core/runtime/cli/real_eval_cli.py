"""``outcast eval real DIR``: the real-photo evaluation
(:mod:`outcast_core.runtime.pipeline.real_eval`).

Runtime only (no torch): the measurement uses the app's own session and shipped models. The
parser's name is ``eval-real``; :func:`outcast_core.runtime.cli.main.main` also accepts the spelling
``outcast eval real DIR``, so it sits beside ``outcast eval`` (synthetic Table 1) for the user.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from outcast_core.runtime.cli.main import (
    DEFAULT_CLI_PRESET,
    CliError,
    add_exposure_option,
    names_in,
)
from outcast_core.runtime.pipeline.session import PRESETS


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``eval-real`` (``outcast eval real``) to a sub-parser collection."""
    p = subparsers.add_parser(
        "eval-real", help="measure shadows on real photos with human shadow masks "
        "(also spelled: outcast eval real DIR)",
        description="Runs the app's session on every NAME_image.* + NAME_mask.png in DIR, sweeps "
        "24 suns (azimuth every 30 deg, elevation 20 and 45) and reports the best-sun balanced "
        "error rate of the shadow overlay, of the refined original shadow, Otsu's, a shuffled "
        "control, the opposite azimuth's, the sky mask's claim on shadow pixels, de-shadowing "
        "error on pairs with a NAME_free.* twin, and the time per photo.",
    )
    p.add_argument("folder", metavar="DIR", help="folder of NAME_image.* and NAME_mask.png")
    p.add_argument("--preset", type=names_in(tuple(PRESETS), "presets"),
                   default=(DEFAULT_CLI_PRESET,),
                   help="preset, or several separated by commas (fast,balanced,accurate) to "
                   "measure the speed/accuracy trade")
    p.add_argument("--mode", choices=["auto", "learned", "classic"], default="auto",
                   help="learned networks (default when installed) or Direct + physics")
    p.add_argument("--relight", choices=["auto", "learned", "physics"], default="auto",
                   help="relighting method for the relighting checks (default: the app's)")
    p.add_argument("--refine", choices=["photo", "learned"], default="photo",
                   help="how the photo's own shadows are found (default: the app's)")
    add_exposure_option(p, "the relit photos' exposure for the relighting checks (default: "
                           "the app's, the photo's own)")
    p.add_argument("--depth-model", default="",
                   help="an ONNX monocular depth model to use instead of the shipped Z "
                   "(README: depth from other estimators)")
    p.add_argument("--limit", type=int, default=0, help="first N photos only (0: all)")
    p.add_argument("--json", dest="json_out", default="", help="write the results as JSON here")
    p.add_argument("--sheet", default="",
                   help="write a contact sheet (PNG/JPEG) here: photo, human mask (green), "
                   "overlay (red), refined shadow (blue), de-shadowed; keep it out of git")
    p.add_argument("--report", default="",
                   help="write the tables into this Markdown file's real-photo section (e.g. "
                   "models/EVAL.md; the rest of the file is kept)")
    p.add_argument("--force", action="store_true", help="overwrite existing JSON / sheet files")
    p.add_argument("-q", "--quiet", action="store_true", help="print only the summary")
    p.set_defaults(func=run_command)
    return p


def _session(args: argparse.Namespace, preset: str) -> Any:
    """The app's session for one preset, with the options of ``outcast eval real``."""
    from outcast_core.runtime.pipeline.session import RelightSession

    session = RelightSession(
        preset=preset, mode=args.mode, refine=args.refine,
        relight_mode=None if args.relight == "auto" else args.relight)
    session.exposure = args.exposure
    if args.depth_model:
        from outcast_core.runtime.io.depth_models import ModelDepthSource, load_depth_model

        session.depth_provider = ModelDepthSource(load_depth_model(args.depth_model))
    return session


def _check_outputs(args: argparse.Namespace) -> None:
    """Before the measurement (minutes): ``--json`` and ``--sheet`` (each sheet of several
    presets) can be written and do not exist without ``--force``, and ``--report``'s folder
    exists (the file itself is updated in place, or made). No missing folder is made: a typo
    in its name would go unseen, as for every output of ``outcast``."""
    from outcast_core.runtime.cli.main import check_folder_writable, check_output_path

    sheets = [_sheet_path(args, preset) for preset in args.preset] if args.sheet else []
    for path in [args.json_out, *map(str, sheets)]:
        if path:
            check_output_path(path, extensions=None, force=args.force,
                              outputs=[args.json_out] if path != args.json_out else [])
    if args.report:
        report = Path(args.report).expanduser()
        if report.is_dir():
            raise CliError(f"cannot write '{args.report}': it is a folder")
        check_folder_writable(report.parent, f"cannot write '{args.report}'")


def _sheet_path(args: argparse.Namespace, preset: str) -> Path:
    """``--sheet``'s file for ``preset`` (one per preset when several are measured)."""
    sheet = Path(args.sheet).expanduser()
    if len(args.preset) > 1:
        sheet = sheet.with_name(f"{sheet.stem}_{preset}{sheet.suffix}")
    return sheet


def run_command(args: argparse.Namespace) -> int:
    """Handler of ``outcast eval real``."""
    from outcast_core.runtime.pipeline.real_eval import (
        evaluate_real,
        find_items,
        render_table,
        update_report,
        write_json,
    )

    if args.limit < 0:
        raise ValueError(f"expected --limit >= 0, got {args.limit}")
    find_items(args.folder)  # a clear error before any model loads
    _check_outputs(args)
    reports: dict[str, Any] = {}
    said: set[str] = set()  # the photos skipped, said
    for preset in args.preset:
        def progress(name: str, frac: float, preset: str = preset) -> None:
            if not args.quiet:
                print(f"[{preset}] {frac * 100:5.1f}% {name}", file=sys.stderr, flush=True)

        sheet = _sheet_path(args, preset) if args.sheet else None
        t0 = time.perf_counter()
        report = evaluate_real(
            args.folder, limit=args.limit, progress=progress, sheet=sheet,
            session_factory=lambda preset=preset: _session(args, preset),
        )
        report["preset"] = preset
        report["wall_s"] = time.perf_counter() - t0
        for k in report.get("skipped", ()):  # (even with -q: the means leave it out)
            if k["name"] not in said:  # (once, not once a preset)
                said.add(k["name"])
                print(f"outcast eval real: warning: {k['name']} skipped: {k['error']}",
                      file=sys.stderr)
        reports[preset] = report
        print(f"\n## Preset {preset} ({report['wall_s']:.0f} s)\n")
        print(render_table(report) if not args.quiet else _summary_line(preset, report))
    if len(reports) > 1:
        print("\n## Speed / accuracy\n")
        print(render_trade(reports))
    if args.report:
        update_report(args.report, render_report(reports, args))
    if args.json_out:
        write_json(args.json_out, reports if len(reports) > 1 else next(iter(reports.values())))
    return 0


def render_report(reports: dict[str, Any], args: argparse.Namespace) -> str:
    """The real-photo section of ``models/EVAL.md``: command, date, trade table, per-photo
    table of the first preset. Only numbers: no picture of the photos."""
    import datetime as dt
    import shlex

    argv = ["outcast", "eval", "real", args.folder, "--preset", ",".join(reports),
            "--mode", args.mode, "--relight", args.relight, "--refine", args.refine]
    argv += ["--exposure", args.exposure] if args.exposure != "photo" else []
    argv += ["--depth-model", args.depth_model] if args.depth_model else []
    argv += ["--limit", str(args.limit)] if args.limit else []
    first = next(iter(reports.values()))
    from outcast_core.runtime.pipeline.real_eval import render_table

    return "\n".join([
        "## Real photographs", "",
        f"Produced by `{' '.join(shlex.quote(a) for a in argv)} --report ...` on "
        f"{dt.datetime.now(dt.UTC).isoformat(timespec='minutes')} (this 2-core CPU, shared, so "
        "times are noisy). Protocol: DESIGN.md, \"Real photographs: how we measure\"; BER = "
        "balanced error rate against the human masks (0 perfect, 0.5 chance), at each photo's "
        "best of 24 suns; shuffled = other photos' best overlays laid on this photo's mask; "
        "swept = other photos' overlay masks at all 24 suns, the best taken for this photo's "
        "mask (the choice the overlay itself gets), and (own) this photo's own best scored "
        "the same way, both on a 128-px grid; de-shadow in = Lab RMSE inside the mask "
        "against the shadow-free twin "
        "over the unchanged input's; out = excess over the input's own RMSE outside the mask; "
        "relit chroma = mean a*b* change where lit under both suns (sun 120 deg away), sky = mean "
        "Lab change on the sky when neither sun's centre is in frame (both relightings keep "
        "the photo's sky; a sun whose disc reaches into the frame is drawn there, fading in); "
        "new shade = median log-luminance change where the new sun newly shadows, over the "
        "photo's own shade/lit log ratio (1: as dark as the photo's own shadows), (colour) = "
        "the distance between the chromaticity shift (log R/G, log B/G) it gives there and "
        "the photo's own shade's against its lit ring (0: the photo's shade colour); "
        "old shade = the relit photo's log-luminance ratio between the lit ring outside each "
        "marked shadow and the shadow, where the new sun lights both, over the photo's own "
        "(0: the old shadow is gone, 1: unchanged); detail = the standard deviation of log "
        "luminance's finest band (minus a Gaussian of 1/128 of the longer side) where both suns "
        "light the surface, relit over the photo's (1: the photo's texture kept; below: "
        "blurred); false lift = the mean natural-log luminance gain where the photo's found "
        "shadows lie away from every marked one (3 % of the longer side) and the new sun "
        "lights them: dark materials and foliage taken for shade (0: unchanged; large: "
        "bleached). "
        "The photos are research data kept "
        "outside the repository; only these numbers are here.", "",
        "### Speed / accuracy", "", render_trade(reports), "",
        f"### Per photo ({first['preset']})", "", render_table(first),
    ])


def _summary_line(preset: str, report: dict[str, Any]) -> str:
    m = report["mean"]
    nan = float("nan")
    return (f"{preset}: overlay BER {m.get('overlay_ber', nan):.3f}, S_o BER "
            f"{m.get('refined_ber', nan):.3f}, {m.get('seconds', nan):.1f} s/photo")


def render_trade(reports: dict[str, Any]) -> str:
    """One row per preset: the mean figures beside the time per photo."""
    lines = ["| Preset | Overlay BER | Opposite | S_o BER | Otsu | Shuffled / swept (own) | "
             "Sky claim | "
             "De-shadow in / out | Relit chroma / sky / new shade (colour) / old shade / "
             "detail / false lift | "
             "s / photo |",
             "|---|---|---|---|---|---|---|---|---|---|"]

    def f(m: dict[str, float], k: str, d: int = 3) -> str:
        return f"{m[k]:.{d}f}" if k in m else "-"

    for preset, rep in reports.items():
        m = rep["mean"]
        ds = ("-" if "deshadow_in" not in m
              else f"{f(m, 'deshadow_in', 2)} / {f(m, 'deshadow_out', 2)}")
        lines.append(f"| {preset} | {f(m, 'overlay_ber')} | {f(m, 'opposite_ber')} | "
                     f"{f(m, 'refined_ber')} | {f(m, 'otsu_ber')} | {f(m, 'shuffled_ber')} / "
                     f"{f(m, 'swept_shuffled_ber')} ({f(m, 'swept_own_ber')}) | "
                     f"{f(m, 'sky_claim')} | {ds} | {f(m, 'relit_chroma', 2)} / "
                     f"{f(m, 'relit_sky', 2)} / {f(m, 'new_shade', 2)} "
                     f"({f(m, 'shade_colour', 2)}) / "
                     f"{f(m, 'old_shade', 2)} / {f(m, 'relit_detail', 2)} / "
                     f"{f(m, 'false_lift', 2)} | {f(m, 'seconds', 2)} |")
    return "\n".join(lines)
