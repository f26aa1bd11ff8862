"""A collection session names its protocol's images relative to the protocol, never by the
experimenter's own folders (issue 43, case 15: every session and file shared from it held
``/home/<user>/.../resources/protocols/images/poke.png``); older sessions that stored
absolute paths still load and resume. Real collections, real files, the real CLI."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.protocol.collect import read_resume_info
from tactile_studio.sensor.layout import get_layout
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_writer import SessionWriter

SHIPPED = Path(load_protocol("shear9").image_file(load_protocol("shear9").gestures[0])).parent
MINI = """
name = "mini"
trial_s = 0.5
blocks = 1
free_play_s = 0
[[gestures]]
name = "Poke"
key = "p"
definition = "Poke it."
image = "pics/poke.png"
[[gestures]]
name = "Twist"
key = "t"
definition = "Twist it."
"""


def _collect(capsys, out: Path, protocol: str) -> Path:
    code = main(["collect", "--protocol", protocol, "--participant", "P01",
                 "--virtual-participant", "--blocks", "1", "--speed", "0", "--out", str(out)])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    return Path(stdout.strip().splitlines()[-1])


def _exported_bytes(path: Path) -> bytes:
    if path.suffix == ".npz":
        with zipfile.ZipFile(path) as z:
            return b"".join(z.read(n) for n in z.namelist())
    return path.read_bytes()


def test_sessions_and_their_exports_name_images_relative_to_the_protocol(
        tmp_path: Path, capsys) -> None:
    lab = tmp_path / "home" / "experimenter" / "lab"
    (lab / "pics").mkdir(parents=True)
    shutil.copy(SHIPPED / "poke.png", lab / "pics" / "poke.png")
    (lab / "mini.toml").write_text(MINI)
    out = tmp_path / "sessions"
    out.mkdir()
    for protocol, images in ((str(lab / "mini.toml"), ["pics/poke.png", None]),
                             ("shear9", [f"images/{g.image.split('/')[-1]}"
                                         for g in load_protocol("shear9").gestures])):
        path = _collect(capsys, out, protocol)
        with SessionFile(path) as s:
            meta = s.metadata
        spec = meta["protocol_spec"]
        assert [g["image"] for g in spec["gestures"]] == images
        text = json.dumps(meta)
        assert str(tmp_path / "home") not in text and str(SHIPPED) not in text, text
        exported = tmp_path / f"export-{path.stem}"
        exported.mkdir()
        for fmt in ("npz", "csv-trials", "shearsense-csv", "xdf"):
            assert main(["export", str(path), "--format", fmt, "--out", str(exported)]) == 0
        capsys.readouterr()
        for f in exported.iterdir():
            data = _exported_bytes(f)
            assert str(tmp_path).encode() not in data and str(SHIPPED).encode() not in data, f
        # the console finds the pictures again: a shipped protocol's own, another through
        # the protocol file the experimenter has chosen
        at_hand = load_protocol(protocol)
        restored = read_resume_info(path, at_hand)["protocol"]
        assert [restored.image_file(g) for g in restored.gestures] == \
            [at_hand.image_file(g) for g in at_hand.gestures]


def test_an_older_session_with_absolute_image_paths_still_loads(tmp_path: Path) -> None:
    """Sessions written before names were stored keep their absolute paths: they open,
    resume and show the picture where it still is."""
    protocol = load_protocol("shear9")
    spec = protocol.to_dict()
    absolute = str(SHIPPED / "poke.png")
    spec["gestures"][0]["image"] = absolute
    layout = get_layout("shearsense-6x6")
    path = tmp_path / "old.h5"
    orders = [protocol.gesture_names]
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name,
                                      "nominal_rate_hz": 43.0},
                       {"participant": "P01", "protocol": "shear9", "source": "collect",
                        "gestures": protocol.gesture_names, "protocol_spec": spec,
                        "seed": 0, "block_order": orders, "practice_order": []}) as w:
        n = 20
        w.append_frames(np.full((n, layout.n_channels), 1000, np.uint16),
                        np.arange(n) / 43.0, 1e9 + np.arange(n) / 43.0)
    info = read_resume_info(path)
    old = info["protocol"]
    assert old.gestures[0].image == absolute and old.image_file(old.gestures[0]) == absolute
    assert old.image_file(old.gestures[1]) == str(SHIPPED / "wide-pinch.png")


def test_an_xdf_export_of_a_replayed_file_does_not_carry_its_folder(tmp_path: Path,
                                                                     capsys) -> None:
    """The replay device's settings hold the replayed file's path on this machine; the
    XDF export put them in its stream description as they were."""
    source = _collect(capsys, tmp_path, "shear9")
    copy = tmp_path / "copy.h5"
    assert main(["record", "--device", "replay", "--set", f"path={source}", "--set",
                 "speed=0", "--seconds", "100", "--out", str(copy)]) == 0
    out = tmp_path / "shared"
    out.mkdir()
    assert main(["export", str(copy), "--format", "xdf", "--out", str(out)]) == 0
    capsys.readouterr()
    data = (out / "copy.xdf").read_bytes()
    assert str(tmp_path).encode() not in data and source.name.encode() in data


@pytest.mark.damaged_files
def test_resuming_a_session_whose_protocol_is_not_a_table_is_one_line(tmp_path: Path,
                                                                       capsys) -> None:
    """A session file from elsewhere whose protocol_spec is text: a traceback before."""
    layout = get_layout("shearsense-6x6")
    path = tmp_path / "odd.h5"
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name,
                                      "nominal_rate_hz": 43.0},
                       {"participant": "P01", "source": "collect", "protocol_spec": "x",
                        "block_order": [["Poke"]], "practice_order": []}) as w:
        w.append_frames(np.full((5, layout.n_channels), 1000, np.uint16),
                        np.arange(5) / 43.0, 1e9 + np.arange(5) / 43.0)
    code = main(["collect", "--virtual-participant", "--resume", str(path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and err[-1] == ("tactile-studio: error: odd.h5: protocol_spec: not a "
                                     "protocol (expected a table of its fields)")
