"""Collection-runner events reach the LSL marker stream exactly, in order, stamped at the
frames they refer to; the collection console's "Stream to LSL" toggle drives the core."""

from __future__ import annotations

import json
import time
from pathlib import Path

from collect_fixtures import do_trial, make_rig, mini_protocol, start
from lsl_fixtures import WAIT_S, Collector, unique

from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.streams.lsl_outlet import LslStreamer

CONNECT_S = 120.0  # the headless collection's recipient: found and connected, at most

SHOWN = {"trial_start", "beep", "trial_end", "refused", "redo", "discard", "note"}


def test_runner_markers_match_the_session_file(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol(3, blocks=1))
    streamer = LslStreamer(rig.engine, name=unique("collect")).start()
    detach = streamer.attach_runner(rig.runner)
    got = Collector(f"name='{streamer.marker_name}'")
    got.wait_connected()
    r = rig.runner
    try:
        start(rig)
        first = r.snapshot().prompted  # the block's random order decides
        do_trial(rig, first)
        assert not r.key("!")                      # refused: not a gesture key
        assert r.redo_last("started late")
        do_trial(rig, first)
        assert r.discard(r.trials[-1]["index"], "wrong gesture")
        assert r.add_note("participant laughed")
        detach()
        assert r.add_note("not streamed")  # after detach, the runner is no longer forwarded
        deadline = time.monotonic() + WAIT_S
        while not any("participant laughed" in m[0] for m in list(got.samples)):
            assert time.monotonic() < deadline, "the note marker never arrived"
            time.sleep(0.02)
    finally:
        streamer.stop()
        got.stop()
        rig.close()
    markers = [(json.loads(m[0]), t) for m, t in zip(got.samples, got.stamps)]
    collect = [(m, t) for m, t in markers if m["source"] == "collect"]
    assert [m["kind"] for m, _ in collect if m["kind"] in SHOWN] == [
        "trial_start", "beep", "trial_end", "refused", "redo",
        "trial_start", "beep", "trial_end", "discard", "note"]
    assert "not streamed" not in json.dumps([m for m, _ in markers])
    with SessionFile(rig.session.path) as s:
        trials = s.journal.trials
        host = s.column("host_time", 0, s.n_frames)
        offset = next(e for e in s.events if e["kind"] == "lsl_clock")["offset_s"]
    assert offset == streamer.offset.offset_s
    starts = [(m, t) for m, t in collect if m["kind"] == "trial_start"]
    ends = [m for m, _ in collect if m["kind"] == "trial_end"]
    for (m, t), trial in zip(starts, trials, strict=True):
        # the file's rows are the engine's frames here (the file was opened first)
        assert (m["gesture"], m["key"], m["frame"]) == (trial["gesture"], trial["key"],
                                                        trial["start_sample"])
        assert t == host[trial["start_sample"]] + offset
    for m, trial in zip(ends, trials, strict=True):
        assert (m["index"], m["gesture"], m["start_sample"], m["end_sample"]) == (
            trial["index"], trial["gesture"], trial["start_sample"], trial["end_sample"])
        assert m["frame"] == trial["end_sample"] - 1 and m["status"] == "ok"
    redo = next(m for m, _ in collect if m["kind"] == "redo")
    assert (redo["index"], redo["status"], redo["reason"]) == (0, "redone", "started late")
    discard = next(m for m, _ in collect if m["kind"] == "discard")
    assert (discard["index"], discard["reason"]) == (1, "wrong gesture")
    refused = next(m for m, _ in collect if m["kind"] == "refused")
    assert "'!' is not a gesture key" in refused["text"]


def test_headless_collect_with_lsl_publishes_every_trial(tmp_path: Path, capsys) -> None:
    from tactile_studio.cli import main

    # both waits are bounds on a condition (the stream is found, a recipient connects),
    # ended as soon as it holds: 10 s each was not always enough on a loaded machine
    got = Collector("name='TactileStudio-simulated-markers'", wait_s=CONNECT_S)
    code = main(["collect", "--protocol", "shear9", "--participant", "P02", "--virtual-participant",
                 "--blocks", "1", "--seed", "8", "--speed", "40", "--out", str(tmp_path), "--lsl",
                 "--lsl-wait", f"{CONNECT_S:g}"])
    out, err = capsys.readouterr()
    got.stop()
    assert code == 0, err
    assert "LSL: publishing 'TactileStudio-simulated'" in err
    assert "LSL: a recipient is connected" in err  # so no marker was published unseen
    with SessionFile(Path(out.strip().splitlines()[-1])) as s:
        trials = s.journal.trials
        assert any(e["kind"] == "lsl_clock" for e in s.events)
    ends = [json.loads(m[0]) for m in got.samples]
    ends = [m for m in ends if m["kind"] == "trial_end"]
    assert [(m["gesture"], m["start_sample"]) for m in ends] == [
        (t["gesture"], t["start_sample"]) for t in trials]
    assert len(ends) == 9
