"""What a collection writes does not depend on the simulator's speed: the same trials at
the same rows and the runner's events at the same frames, around their trials, whether
the stream runs as fast as possible (speed 0), in real time (1) or 20x (the real command).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tactile_studio.cli import main
from tactile_studio.storage.format.session_check import check_file
from tactile_studio.storage.format.session_file import SessionFile

# three gestures, short trials, free play and a break after every block: every runner
# event that a timed phase or a trial boundary places
PROTOCOL = """
name = "speedtest"
trial_s = 0.5
blocks = 2
free_play_s = 1.0
order = "prompted"
[breaks]
every_blocks = 1
min_s = 1.0
[beep]
length_s = 0.1
[[gestures]]
name = "Poke"
key = "p"
definition = "x"
[[gestures]]
name = "Twist"
key = "t"
definition = "x"
[[gestures]]
name = "Heavy Pat"
key = "h"
definition = "x"
"""
RUNNER_EVENTS = ("session_start", "free_play", "block_start", "break_start", "break_end",
                 "session_end")


def _collect(tmp_path: Path, capsys, speed: str, *extra: str) -> Path:
    out = tmp_path / f"speed-{speed}"
    code = main(["collect", "--protocol", str(tmp_path / "speedtest.toml"), "--participant",
                 "P07", "--virtual-participant", "--speed", speed, "--seed", "1",
                 "--out", str(out), *extra])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return Path(captured.out.strip().splitlines()[-1])


def _written(path: Path) -> tuple[list, list]:
    with SessionFile(path) as s:
        events = [(e["kind"], e.get("block"), e["frame"]) for e in s.events
                  if e["kind"] in RUNNER_EVENTS]
        trials = [(t.index, t.block, t.gesture, t.start_sample, t.end_sample,
                   t.status) for t in s.trials]
    return events, trials


@pytest.mark.slow
def test_event_frames_and_trial_rows_are_the_same_at_speed_0_1_and_20(
        tmp_path: Path, capsys) -> None:
    (tmp_path / "speedtest.toml").write_text(PROTOCOL)
    runs = {speed: _collect(tmp_path, capsys, speed) for speed in ("0", "1", "20")}
    for path in runs.values():
        result = check_file(path)
        assert result.ok, result.violations
    written = {speed: _written(path) for speed, path in runs.items()}
    events, trials = written["20"]
    assert len(trials) == 6 and {t[-1] for t in trials} == {"ok"}
    assert [e[0] for e in events] == ["session_start", "free_play", "block_start",
                                      "break_start", "break_end", "block_start",
                                      "session_end"]
    # block 2 begins after block 1's last trial and before its own first; the session
    # ends where its last trial does (not where the stream or the recorder had got to)
    assert events[-1][2] == trials[-1][4] and events[3][2] == trials[2][4]
    assert trials[2][4] <= events[5][2] <= trials[3][3]
    # free play and the break last their seconds in stream frames (43 Hz), whatever
    # chunks the stream came in (a clock read from a chunk once ended free play early)
    for speed, (evs, _) in written.items():
        frame = {kind: f for kind, _, f in evs[:5]}
        assert frame["block_start"] - frame["free_play"] == round(1.0 * 43), speed
        assert frame["break_end"] - frame["break_start"] == round(1.0 * 43), speed
    assert written["0"] == written["20"] and written["1"] == written["20"]
    # and so does the file's length: it ends with the session, not a ring of idle frames
    # later (speed 0 wrote 7,461 frames against 2,881 at speed 20)
    lengths = {}
    for speed, path in runs.items():
        with SessionFile(path) as s:
            lengths[speed] = s.n_frames
    assert lengths["0"] == lengths["1"] == lengths["20"] == events[-1][2] + 1, lengths
