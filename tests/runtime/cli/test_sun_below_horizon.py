"""A sun below the horizon (issue 19, defect 10).

Decision: OutCast renders sunlight and the shadows it casts, not twilight. A still's sun
(``shadow --sun``, ``relight --from/--to``, ``timelapse --from``, ``batch --from/--to``) below
the horizon is refused with one line and exit status 2; a time-lapse path that dips below the
horizon (a real day's sunrise and sunset, a sweep: ``timelapse --sweep`` and ``batch --sweep``
alike) renders those frames with the sun at the horizon.
"""

from __future__ import annotations

import numpy as np
import pytest

from outcast_core.runtime.cli.main import build_parser, main, parse_azel
from outcast_core.runtime.pipeline.timelapse import MIN_RENDER_ELEVATION, sun_vectors, sweep_path


def test_parse_azel_refuses_a_sun_below_the_horizon():
    np.testing.assert_allclose(parse_azel("90,0"), [1, 0, 0], atol=1e-12)  # the horizon is fine
    with pytest.raises(ValueError, match="at or above the horizon.*not twilight"):
        parse_azel("90,-10")


def _exit_code(args: list[str]) -> int:
    try:
        return main(args)
    except SystemExit as exc:  # argparse refuses an option's value
        return int(exc.code)


@pytest.mark.parametrize(
    "argv",
    [
        ["relight", "{photo}", "--from", "273,67", "--to", "90,-10", "-o", "{out}.jpg"],
        ["relight", "{photo}", "--from", "273,-5", "--to", "90,30", "-o", "{out}.jpg"],
        ["shadow", "{photo}", "--sun", "90,-0.5", "-o", "{out}.png"],
        ["timelapse", "{photo}", "--from", "90,-10", "--sweep", "0,20:90,20", "--frames", "2",
         "-o", "{out}.gif"],
    ],
)  # fmt: skip
def test_cli_refuses_a_sun_below_the_horizon(photo, tmp_path, capsys, argv):
    out = tmp_path / "out"
    assert _exit_code([a.format(photo=photo, out=out) for a in argv]) == 2
    err = capsys.readouterr().err
    assert "above the horizon" in err and "Traceback" not in err
    assert "above the horizon" in err.strip().splitlines()[-1]  # the last line says why
    assert not list(tmp_path.glob("out*"))


def test_timelapse_paths_below_the_horizon_render_at_the_horizon():
    samples = sweep_path((90.0, 10.0), (270.0, -10.0), 5)
    assert min(s.elevation for s in samples) < 0  # the path may dip below
    lowest = min(sun_vectors(samples), key=lambda w: -w[1])
    el = np.degrees(np.arcsin(-lowest[1]))
    assert el == pytest.approx(MIN_RENDER_ELEVATION)


#: The start of each command line whose --sweep / --from / --to are checked (parsing only).
_SWEEP_COMMANDS = {
    "timelapse": ["timelapse", "photo.jpg", "--from", "90,30", "-o", "out.mp4"],
    "batch": ["batch", "photos", "-o", "out"],
}


@pytest.mark.parametrize("command", sorted(_SWEEP_COMMANDS))
def test_a_sweep_end_may_be_below_the_horizon(command):
    """One rule for both commands (one parser): a sweep is a sun path, so an end may dip below
    the horizon (down to -90); a malformed end or one past -90 is refused by both."""
    parser = build_parser()
    argv = _SWEEP_COMMANDS[command]
    args = parser.parse_args([*argv, "--sweep", "90,10:270,-10"])
    assert args.sweep == ((90.0, 10.0), (270.0, -10.0))
    args = parser.parse_args([*argv, "--sweep", "0,-90:45,0"])
    assert args.sweep == ((0.0, -90.0), (45.0, 0.0))
    for bad in ("90,10:270,-91", "90,10", "90,10:east,5", "90,nan:0,5"):
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([*argv, "--sweep", bad])
        assert exc.value.code == 2


@pytest.mark.parametrize("option", ["--from", "--to"])
def test_batch_refuses_a_still_sun_below_the_horizon(option, capsys):
    parser = build_parser()
    assert parser.parse_args(["batch", "photos", "-o", "out", option, "90,0"]) is not None
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(["batch", "photos", "-o", "out", option, "90,-10"])
    assert exc.value.code == 2
    assert "above the horizon" in capsys.readouterr().err
