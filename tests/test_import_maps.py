"""``import shearsense`` names: participants normalised and mapped, gesture key maps,
and a summary that lists files without trials and keys without a gesture name."""

from __future__ import annotations

import json

import pytest
from csv_fixtures import labelled_csv

from tactile_studio.cli import main
from tactile_studio.storage.exchange.importers.maps import (
    MapError,
    gesture_key_map,
    normalise_participant,
    participant_map,
)
from tactile_studio.storage.format.session_file import SessionFile


@pytest.fixture
def files(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    names = ["Pilot_FLAT.csv", "PILOT_PILLOW.csv", "P8_FLAT.csv", "P08_PILLOW.csv"]
    out = [labelled_csv(src, n, i) for i, n in enumerate(names)]
    out.append(labelled_csv(src, "P09_FLAT.csv", 9, keys=""))  # nothing labelled
    return out


def _import(capsys, tmp_path, files, *extra):
    out = tmp_path / "out"
    code = main(["import", "shearsense", *map(str, files), "--out", str(out), "--force", *extra])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    people = {}
    for f in files:
        with SessionFile(out / f"{f.stem}.h5") as s:
            people[f.name] = (s.metadata["participant"], [t.gesture for t in s.trials],
                              s.metadata["unmapped_keys"])
    return stdout, people


def test_normalise_participant():
    assert [normalise_participant(n) for n in ("Pilot", "PILOT", "P8", "p08", "P008", "P123",
                                               "PA1", "")] == \
        ["PILOT", "PILOT", "P08", "P08", "P08", "P123", "PA1", ""]


def test_default_import_normalises_participants_and_reports_gaps(tmp_path, capsys, files):
    stdout, people = _import(capsys, tmp_path, files)
    assert {k: v[0] for k, v in people.items()} == {
        "Pilot_FLAT.csv": "PILOT", "PILOT_PILLOW.csv": "PILOT", "P8_FLAT.csv": "P08",
        "P08_PILLOW.csv": "P08", "P09_FLAT.csv": "P09"}
    assert "participants: P08, P09, P8 -> P08, PILOT, Pilot -> PILOT" in stdout
    assert "1 file(s) with no labelled runs (0 trials): P09_FLAT.csv" in stdout
    assert "key 'z' (code 122) has no gesture name, trials keep the key: 4 file(s)" in stdout
    assert people["P8_FLAT.csv"][1] == ["Back & Forth Rub", "Poke", "z"]  # shear9's keys
    assert people["P8_FLAT.csv"][2] == ["z"]
    assert "gesture keys guessed (no map given, shear9's keys assumed): p=Poke, " in stdout
    # more keys than shear9 names: the names it gave may be wrong too, and the fix is named
    assert ("the files use 3 gesture keys, shear9's map names 2 (p, r), perhaps wrongly: if "
            "they were recorded with another protocol, give its keys with --gestures "
            "(cost14, haart7, shear9, a .toml file or key=Name,...)") in stdout


def test_a_protocol_names_the_keys_by_name_or_file(tmp_path, capsys, files):
    from importlib import resources
    stdout, people = _import(capsys, tmp_path, files, "--gestures", "cost14")
    assert people["P8_FLAT.csv"][1] == ["rub", "pat", "z"]
    assert "gesture keys (from protocol cost14): g=grab, h=hit," in stdout
    assert "perhaps wrongly" not in stdout and "guessed" not in stdout
    shipped = resources.files("tactile_studio.resources") / "protocols" / "cost14.toml"
    (tmp_path / "study.toml").write_text(shipped.read_text())
    stdout, people = _import(capsys, tmp_path, files, "--gestures", str(tmp_path / "study.toml"))
    assert people["P8_FLAT.csv"][1] == ["rub", "pat", "z"]
    with SessionFile(tmp_path / "out" / "P8_FLAT.h5") as s:
        assert s.metadata["gestures"][:3] == ["grab", "hit", "massage"]


def test_maps_inline_and_from_toml(tmp_path, capsys, files):
    stdout, people = _import(capsys, tmp_path, files, "--participant-map", "pilot=P00,P8=P07",
                             "--gestures", "r=Rub,112=Press")
    assert {v[0] for k, v in people.items() if "ilot" in k.lower()} == {"P00"}
    assert people["P8_FLAT.csv"][0] == people["P08_PILLOW.csv"][0] == "P07"
    assert people["P8_FLAT.csv"][1] == ["Rub", "Press", "z"]
    assert "Pilot -> P00" in stdout and "P8 -> P07" in stdout
    assert "gesture keys (from the map given): r=Rub, p=Press" in stdout
    with SessionFile(tmp_path / "out" / "P8_FLAT.h5") as s:
        assert s.metadata["gestures"] == ["Rub", "Press", "z"]
        assert s.metadata["protocol"] == ""  # not shear9's names any more
    assert main(["info", str(tmp_path / "out" / "P8_FLAT.h5")]) == 0
    assert "unmapped keys: z" in capsys.readouterr().out
    assert main(["info", "--json", str(tmp_path / "out" / "P8_FLAT.h5")]) == 0
    assert json.loads(capsys.readouterr().out)["unmapped_keys"] == ["z"]

    # a file name without a P-number keeps its stem, which the map can rename too
    other = labelled_csv(tmp_path / "src", "recording 3.csv", 11)
    stdout, people = _import(capsys, tmp_path, [other], "--participant-map", "Recording 3=P11")
    assert people["recording 3.csv"][0] == "P11" and "recording 3 -> P11" in stdout

    (tmp_path / "g.toml").write_text('[gestures]\nr = "Rub"\n122 = "Zigzag"\n')
    (tmp_path / "p.toml").write_text('PILOT = "P00"\n"p08" = "P01"\n')
    stdout, people = _import(capsys, tmp_path, files, "--gestures", str(tmp_path / "g.toml"),
                             "--participant-map", str(tmp_path / "p.toml"))
    assert people["P08_PILLOW.csv"][0] == "P01" and people["Pilot_FLAT.csv"][0] == "P00"
    assert people["P8_FLAT.csv"][1] == ["Rub", "p", "Zigzag"]
    assert "key 'p' (code 112) has no gesture name" in stdout


def test_bad_maps_are_one_line_errors(tmp_path, capsys, files):
    for opt, value, words in [("--gestures", "r", "'r' is not key=Name,..., a .toml file or a "
                                               "shipped protocol (cost14, haart7, shear9)"),
                              ("--gestures", "r=", "not old=new"),
                              ("--gestures", "rr=Rub", "one character"),
                              ("--gestures", str(tmp_path / "missing.toml"), "no such file"),
                              ("--participant-map", "P8=bad id!", "bad participant id")]:
        code = main(["import", "shearsense", str(files[0]), "--out", str(tmp_path / "o"),
                     opt, value])
        err = capsys.readouterr().err.strip()
        assert code == 1 and words in err and len(err.splitlines()) == 1, err
    (tmp_path / "bad.toml").write_text("r = [1, 2]\n")
    with pytest.raises(MapError, match="must map to a name"):
        gesture_key_map(str(tmp_path / "bad.toml"))
    with pytest.raises(MapError, match="not a readable TOML"):
        (tmp_path / "worse.toml").write_text("r = \n")
        participant_map(str(tmp_path / "worse.toml"))
