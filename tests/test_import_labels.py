"""Imports name gestures by the corpora's published numbering and always say which key
map they applied and where it came from ("guessed" when none was given)."""

from __future__ import annotations

import numpy as np
from csv_fixtures import labelled_csv

from tactile_studio.cli import main
from tactile_studio.storage.format.session_file import SessionFile

# CoST's README, alphabetical: 10 slap, 11 squeeze, 12 stroke, 13 tap
COST_KNOWN = {1: "grab", 8: "rub", 10: "slap", 11: "squeeze", 12: "stroke", 13: "tap",
              14: "tickle"}
# HAART's seven gestures in the challenge's alphabetical list
HAART_KNOWN = {1: "constant", 2: "no touch", 3: "pat", 4: "rub", 5: "scratch", 6: "stroke",
               7: "tickle"}


def _dataset_csv(path, header, rows_of):
    rng = np.random.default_rng(0)
    lines = [header + ", " + ", ".join(f"ch{i}" for i in range(1, 65))]
    for ids in rows_of:
        lines.append(", ".join(map(str, ids)) + ", "
                     + ", ".join(map(str, rng.integers(0, 1024, 64))))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cost_labels_follow_the_corpus_numbering(tmp_path, capsys):
    rows = [(1, "normal", label, f) for label in COST_KNOWN for f in range(1, 6)]
    src = _dataset_csv(tmp_path / "CoST.csv", "subject, variant, gesture, frame", rows)
    assert main(["import", "cost", str(src), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "gesture labels: CoST's published numbering: 1=grab, " in out
    assert "10=slap, 11=squeeze, 12=stroke, 13=tap, 14=tickle" in out
    with SessionFile(tmp_path / "cost_P01.h5") as s:
        assert [t.gesture for t in s.trials] == list(COST_KNOWN.values())


def test_haart_numbers_follow_its_published_names(tmp_path, capsys):
    rows = [(1, "none", label, label) for label in HAART_KNOWN for _ in range(3)]
    src = _dataset_csv(tmp_path / "training.csv", "Subject, Cover, Gesture, Sequence", rows)
    assert main(["import", "haart", str(src), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "gesture labels: HAART's published numbering: 1=constant, 2=notouch" in out
    with SessionFile(tmp_path / "haart_training_P01.h5") as s:
        assert [t.gesture for t in s.trials] == list(HAART_KNOWN.values())


def test_shearsense_keys_without_a_map_are_said_to_be_guessed(tmp_path, capsys):
    src = labelled_csv(tmp_path, "P03_FLAT.csv", 3, keys="swr")  # all keys in shear9's map
    assert main(["import", "shearsense", str(src), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert ("gesture keys guessed (no map given, shear9's keys assumed): p=Poke, w=Wide Pinch"
            in out)
    with SessionFile(tmp_path / "out" / "P03_FLAT.h5") as s:
        assert [t.gesture for t in s.trials] == ["Circular Stroke", "Wide Pinch",
                                                    "Back & Forth Rub"]


def test_shearsense_map_given_names_its_source(tmp_path, capsys):
    src = labelled_csv(tmp_path, "P03_FLAT.csv", 3, keys="qk")
    for given, source in (("cost14", "protocol cost14"), ("q=Squeeze,k=Stroke", "the map given")):
        assert main(["import", "shearsense", str(src), "--out", str(tmp_path / "out"),
                     "--force", "--gestures", given]) == 0
        out = capsys.readouterr().out
        assert f"gesture keys (from {source}): " in out and "guessed" not in out
    (tmp_path / "g.toml").write_text('q = "Squeeze"\nk = "Stroke"\n')
    assert main(["import", "shearsense", str(src), "--out", str(tmp_path / "out"), "--force",
                 "--gestures", str(tmp_path / "g.toml")]) == 0
    assert "gesture keys (from file g.toml): q=Squeeze, k=Stroke" in capsys.readouterr().out
