"""The README's headless collection (the simulator at ``--speed 0``, faster than real
time) survives ``export --format xdf`` and ``import xdf``: the imported file passes
``check`` and keeps every trial on its rows (found walking issues 34 and 38: its host
clock ran in bursts, pyxdf's dejittering moved the frames under the markers, and the
imported trials overlapped: 23 check violations).

Budget: ~6 s (one collection block at speed 0, the round trip).
"""

from __future__ import annotations

import numpy as np
import pyxdf

from tactile_studio.cli import main
from tactile_studio.storage import SessionFile
from tactile_studio.storage.format.session_check import check_file


def _rows(s: SessionFile) -> list[tuple]:
    return [(t.gesture, t.start_sample, t.end_sample, t.status) for t in s.trials]


def _events(s: SessionFile) -> list[tuple]:
    return [(e["kind"], e.get("frame")) for e in s.events
            if e["kind"] in ("session_start", "block_start", "session_end")]


def test_a_speed_0_collection_round_trips_through_xdf_with_its_trials(tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["collect", "--protocol", "shear9", "--participant", "P07", "--device",
                 "simulated", "--virtual-participant", "--speed", "0", "--blocks", "1",
                 "--seed", "1", "--out", str(data)]) == 0
    (src,) = sorted(data.glob("*.h5"))
    assert main(["export", str(src), "--format", "xdf", "--out", str(tmp_path / "x")]) == 0
    (xdf,) = sorted((tmp_path / "x").glob("*.xdf"))
    streams, _ = pyxdf.load_xdf(str(xdf), dejitter_timestamps=False)
    frames = next(s for s in streams if s["info"]["type"][0] == "Tactile")
    with SessionFile(src) as a:
        dev = a.column("device_time")
        # on the device's clock: the stamps advance by the frame period, not in bursts
        np.testing.assert_allclose(np.diff(frames["time_stamps"]), np.diff(dev), atol=1e-6)
    assert main(["import", "xdf", str(xdf), "--out", str(tmp_path / "in")]) == 0
    (back,) = sorted((tmp_path / "in").glob("*.h5"))
    result = check_file(back)
    assert result.ok, result.violations
    with SessionFile(src) as a, SessionFile(back) as b:
        assert b.n_frames == a.n_frames and len(a.trials) >= 9
        assert _rows(b) == _rows(a)
        assert _events(b) == _events(a)
        rate = (b.n_frames - 1) / float(np.ptp(b.column("host_time")))
        assert abs(rate - 43.0) < 0.5
