"""A sun below the horizon (issue 19, defect 10).

Decision: OutCast renders sunlight and the shadows it casts, not twilight. A still's sun
(``shadow --sun``, ``relight --from/--to``, ``timelapse --from``) below the horizon is refused
with one line and exit status 2; a time-lapse path that dips below the horizon (a real day's
sunrise and sunset, a sweep) renders those frames with the sun at the horizon.
"""

from __future__ import annotations

import numpy as np
import pytest

from outcast_core.runtime.cli.main import main, parse_azel
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
