"""Model cards: ``models/README.md`` rendered from the manifests (no hand-typed numbers)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

PURPOSE = {
    "shadow": "S: learned ray-marching cast shadows (the paper's key network)",
    "shadow_2d": "the paper's '2D' ablation of S (a U-Net, no ray marching)",
    "refine": "R: refines the original-sun shadow S(C, w_o) using the photo",
    "relight": "L: relights the photo from (C_o, S_o, S_n, N, w_o, w_n, Psi)",
    "relight_pix2pix": "the paper's 'Pix2Pix-like' ablation of L (no shadow inputs)",
    "depth": "Z: monocular depth (scale-free) + sky mask",
    "sun": "D: the sun's direction from the photo's look, a distribution over directions",
}


def _card(man: dict[str, Any]) -> list[str]:
    tr = man.get("training", {})
    cfg = tr.get("config", {})
    ins = ", ".join(f"`{i['name']}` {i['shape']}" for i in man["inputs"])
    outs = ", ".join(f"`{o['name']}` {o['shape']}" for o in man["outputs"])
    lines = [
        f"## `{man['file']}` — {PURPOSE.get(man['name'], man['name'])}",
        "",
        f"- Inputs: {ins}",
        f"- Outputs: {outs}",
        f"- Colour space: {man['colour_space']}; pad multiple: {man['pad_multiple']}; "
        f"parameters: {man['parameters']:,}; ONNX opset {man.get('opset')}; onnxruntime vs "
        f"torch max abs diff at export: {man.get('onnx_parity_max_abs_diff')}",
    ]
    if man.get("base") == "physics":
        lines.append(
            "- Residual on the physics relighting: the output is the shading-ratio relighting "
            "`C_o (1 + r S_n) / (1 + r S_o)` (linear RGB; `light_ratio` is r, estimated from the "
            "photo by `runtime.pipeline.relight.estimate_light`) plus what the network corrects"
        )
    if man.get("input_side"):
        lines.append(
            (f"- Run at its training scale: the app resizes a photo to a longer side of "
             f"{man['input_side']} px, both sides multiples of {man['pad_multiple']}, before "
             "this network (`runtime.pipeline.sun_look.read_sun`)") if man["name"] == "sun" else
            f"- Run at its training scale: the app shrinks a photo whose longer side exceeds "
            f"{man['input_side']} px to that side before this network and brings its outputs "
            "back up (`runtime.pipeline.depth_post.run_depth_model`)"
        )
    if "bins" in man:
        lines.append(
            f"- Output: one logit per direction of a {man['bins']}-point Fibonacci lattice over "
            f"the sphere of camera-space directions; the runtime's density is a von "
            f"Mises-Fisher kernel mixture of the bins (kappa {man.get('kappa', 0):.1f}: "
            f"`runtime.pipeline.sun_look`), a term of the sun search's ranking "
            f"(`auto_sun.LOOK_WEIGHT`)"
        )
    if "march_steps" in man:
        lines.append(
            f"- March: z = {man['march_steps']} steps of {man['march_step']} (fraction of the "
            f"longer side); volume built at scale {man['volume_scale']}"
        )
    if tr:
        lines += [
            f"- Trained: `{tr.get('command') or 'outcast train'}` "
            f"(run `{cfg.get('run')}`), {tr.get('steps')} steps of batch {cfg.get('batch')} at "
            f"{cfg.get('size')} px, lr {cfg.get('lr')}"
            f"{' cosine to ' + str(cfg['lr_final']) if cfg.get('lr_final') else ''}, "
            f"seed {cfg.get('seed')}, "
            f"{tr.get('wall_time_s')} s wall time on this 2-core CPU "
            f"({cfg.get('threads')} torch thread(s); {_minutes(tr.get('wall_time_s'))})",
            *_branch_lines(tr.get("branched_from")),
            f"- Data: `{tr.get('data_set')}` (data seed {tr.get('data_seed')}, "
            f"{tr.get('views')} views in all)",
            *_extra_data_lines(tr.get("extra_data")),
            f"- Final training losses (moving average): {json.dumps(tr.get('loss', {}))}",
        ]
    mets = man.get("metrics") or {}
    if mets:
        lines.append(f"- Held-out metrics (see EVAL.md): {json.dumps(mets)}")
    else:
        lines.append("- Held-out metrics: not measured")
    lines += [f"- sha256: `{man['sha256']}`", ""]
    return lines


def _extra_data_lines(extra: list[dict[str, Any]] | None) -> list[str]:
    """One card line per extra data folder of a run: where, its seed, its views and kind."""
    lines = []
    for e in extra or []:
        rec = e.get("data_record") or {}
        kind = f", scene kind {rec['kind']}" if rec.get("kind") else ""
        loaded = e.get("views_loaded")
        used = f", {loaded} of them loaded" if loaded is not None else ""
        lines.append(
            f"- Extra data: `{e.get('data_set')}` (data seed {rec.get('seed')}, "
            f"{rec.get('views')} views of {rec.get('suns')} sun(s){kind}{used})"
        )
    return lines


def _branch_lines(br: dict[str, Any] | None) -> list[str]:
    """The card line of a run that continues another (``resume_from``), or none."""
    if not br:
        return []
    if br.get("init_onnx"):
        return [f"- Starts from the weights of `{Path(br['init_onnx']).name}` (sha256 "
                f"{str(br['sha256'])[:12]}..., trained {br.get('step')} steps in "
                f"{_minutes(br.get('wall_time_s'))} by `{br.get('command')}`); steps and wall "
                "time above count this run only"]
    threads = f", trained with {br['threads']} thread(s)" if br.get("threads") else ""
    return [f"- Continues run `{br['run']}` (`{br['command']}`) from its step {br['step']} "
            f"({_minutes(br['wall_time_s'])} of the wall time above{threads}); steps and wall "
            "time count both runs"]


def _minutes(seconds: Any) -> str:
    return f"{float(seconds) / 60:.0f} min" if isinstance(seconds, (int, float)) else "?"


def render_cards(models: str | Path, preamble: str = "") -> str:
    """The README text for every manifest in ``models``."""
    models = Path(models)
    mans = [json.loads(p.read_text()) for p in sorted(models.glob("*.json"))]
    mans = [m for m in mans if "sha256" in m and "inputs" in m]
    out = ["# Shipped models", ""]
    if preamble:
        out += [preamble.strip(), ""]
    for m in mans:
        out += _card(m)
    return "\n".join(out)


def update_readme(models: str | Path) -> Path:
    """Re-render ``models/README.md`` from the manifests, keeping its hand-written preamble
    (everything between the title and the first card)."""
    path = Path(models) / "README.md"
    preamble = ""
    if path.is_file():
        text = path.read_text()
        body = text.split("\n", 1)[1] if text.startswith("# ") else text
        preamble = body.split("\n## `", 1)[0]
    path.write_text(render_cards(models, preamble).rstrip() + "\n")
    return path
