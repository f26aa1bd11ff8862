"""Protocol files: the shipped ones load, every bad field is named, orders reproduce."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from tactile_studio.errors import UserError
from tactile_studio.protocol.randomise import block_orders, practice_order
from tactile_studio.storage.format.protocol_file import (
    ProtocolError,
    list_protocols,
    load_protocol,
    protocol_from_dict,
    restored_protocol,
)

SHEAR9 = ["Poke", "Wide Pinch", "Heavy Pat", "Twist", "Back & Forth Rub", "Isometric Rub",
          "Circular Stroke", "Constant Touch", "Tickle"]
COST14 = ["grab", "hit", "massage", "pat", "pinch", "poke", "press", "rub", "scratch", "slap",
          "stroke", "squeeze", "tap", "tickle"]
HAART7 = ["constant", "no touch", "pat", "rub", "scratch", "stroke", "tickle"]

GOOD = """
name = "mini"
trial_s = 2.0
blocks = 3
[breaks]
every_blocks = 1
min_s = 5
[[gestures]]
name = "Poke"
key = "p"
definition = "Poke it."
[[gestures]]
name = "Rub"
key = "r"
definition = "Rub it."
"""


def test_shipped_protocols_load_with_the_papers_numbers() -> None:
    assert list_protocols() == ["cost14", "haart7", "shear9"]
    p = load_protocol("shear9")
    assert p.gesture_names == SHEAR9
    assert (p.blocks, p.trial_s, p.free_play_s, p.break_every) == (52, 2.0, 10.0, 12)
    assert p.break_min_s >= 120
    assert p.beep_hz > 0 and p.beep_s > 0
    assert len({g.key for g in p.gestures}) == 9
    assert all(len(g.definition) > 20 for g in p.gestures)
    assert sorted(load_protocol("cost14").gesture_names) == sorted(COST14)
    assert load_protocol("haart7").gesture_names == HAART7
    for name in ("cost14", "haart7"):
        assert all(g.definition for g in load_protocol(name).gestures)


def test_protocol_by_path_and_roundtrip(tmp_path: Path) -> None:
    f = tmp_path / "mini.toml"
    f.write_text(GOOD)
    p = load_protocol(f)
    assert (p.name, p.blocks, p.break_every, p.break_min_s) == ("mini", 3, 1, 5.0)
    assert p.gesture_by_key("R").name == "Rub"
    again = protocol_from_dict(p.to_dict(), "again")
    assert again.to_dict() == p.to_dict()
    small = p.with_overrides(blocks=1, break_min_s=0.5)
    assert (small.blocks, small.break_min_s, small.gestures) == (1, 0.5, p.gestures)
    assert p.order == "prompted"  # the default: the screen prompts the block's order
    f.write_text(GOOD.replace('name = "mini"', 'name = "mini"\norder = "free"'))
    free = load_protocol(f)
    assert free.order == "free" and protocol_from_dict(free.to_dict(), "x").order == "free"
    old = {k: v for k, v in p.to_dict().items() if k != "order"}  # a session from before
    assert protocol_from_dict(old, "old").order == "prompted"
    assert {load_protocol(n).order for n in list_protocols()} == {"prompted"}


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace('key = "r"', 'key = "p"'),
     "mini.toml: gestures[1].key: duplicate key 'p'"),
    (lambda t: t.replace('name = "Rub"', 'name = "poke"'),
     "mini.toml: gestures[1].name: duplicate"),
    (lambda t: t.replace('key = "r"', 'key = "rr"'),
     "mini.toml: gestures[1].key: must be one printable"),
    (lambda t: t.replace('definition = "Rub it."', ''),
     "mini.toml: gestures[1].definition: missing"),
    (lambda t: t.replace('definition = "Rub it."', 'definition = " "'),
     "gestures[1].definition: must not be empty"),
    (lambda t: t.replace('definition = "Rub it."', 'definition = "x"\nimage = "nope.png"'),
     "gestures[1].image: no such file 'nope.png'"),
    (lambda t: t.replace('definition = "Rub it."', 'definition = "x"\nimage = "notes.txt"'),
     "gestures[1].image: 'notes.txt' is not an image"),
    (lambda t: t.replace('definition = "Rub it."', 'definition = "x"\nimage = ""'),
     "gestures[1].image: must not be empty"),
    # a stranger's protocol cannot point the participant screen (and the session's
    # metadata) at a file elsewhere on the machine
    (lambda t: t.replace('definition = "Rub it."', 'definition = "x"\nimage = "/etc/x.png"'),
     "gestures[1].image: '/etc/x.png' is outside the protocol's folder"),
    (lambda t: t.replace('definition = "Rub it."',
                         'definition = "x"\nimage = "pics/../../x.png"'),
     "gestures[1].image: 'pics/../../x.png' is outside the protocol's folder"),
    (lambda t: t.replace('definition = "Rub it."', 'definition = "x"\nimage = "C:\\\\x.png"'),
     "is outside the protocol's folder"),
    (lambda t: t.replace('definition = "Rub it."', 'definition = "x"\ncolour = "red"'),
     "gestures[1].colour: unknown field"),
    (lambda t: t.replace("blocks = 3", "blocks = 0"), "mini.toml: blocks: 0 is out of range"),
    (lambda t: t.replace("blocks = 3", 'blocks = "many"'),
     "mini.toml: blocks: expected a whole number"),
    (lambda t: t.replace("blocks = 3", ""), "mini.toml: blocks: missing"),
    (lambda t: t.replace("trial_s = 2.0", "trial_s = -1"),
     "mini.toml: trial_s: -1 is out of range"),
    (lambda t: t.replace("trial_s = 2.0", "trial_s = true"),
     "mini.toml: trial_s: expected a number"),
    (lambda t: t.replace("min_s = 5", "min_s = -5"), "mini.toml: breaks.min_s: -5 is out of range"),
    (lambda t: t.replace("every_blocks = 1", "every = 1"),
     "mini.toml: breaks.every: unknown field"),
    (lambda t: t + '\n[beep]\nfrequency_hz = 5\n',
     "mini.toml: beep.frequency_hz: 5 is out of range"),
    (lambda t: t + '\n[randomisation]\nmode = "latin"\n',
     "mini.toml: randomisation.mode: unknown mode 'latin'"),
    (lambda t: t.replace('name = "mini"', 'name = "mini"\ntrials = 4'),
     "mini.toml: trials: unknown field"),
    (lambda t: t.replace('name = "mini"', 'name = "mini"\norder = "random"'),
     "mini.toml: order: unknown order 'random' (use prompted or free)"),
    (lambda t: t.replace('name = "mini"', 'name = "mini"\norder = 1'),
     "mini.toml: order: expected text"),
    (lambda t: t.split("[[gestures]]")[0], "mini.toml: gestures: missing"),
    (lambda t: t.replace("[breaks]\nevery_blocks = 1\nmin_s = 5", "breaks = 3"),
     "mini.toml: breaks: must be a table"),
    (lambda t: t + "\nblocks = [", "mini.toml: not valid TOML"),
    # a protocol from a stranger: its name names every session file, and it cannot make a
    # collection store millions of trials (issue 43, the hunt)
    (lambda t: t.replace('name = "mini"', 'name = "../../x"'),
     "mini.toml: name: '../../x' cannot name session files: it holds a path separator"),
    (lambda t: t.replace('name = "mini"', 'name = "mini\\u001b[2J"'),
     "mini.toml: name: 'mini\\x1b[2J' cannot name session files: it holds a control"),
    (lambda t: t + "".join(f'[[gestures]]\nname = "g{i}"\nkey = "{chr(0x4e00 + i)}"\n'
                           f'definition = "x"\n' for i in range(100)),
     "mini.toml: gestures: 102 gestures; a protocol has at most 100"),
    (lambda t: t.replace("blocks = 3", "blocks = 10000") + "".join(
        f'[[gestures]]\nname = "g{i}"\nkey = "{chr(0x4e00 + i)}"\ndefinition = "x"\n'
        for i in range(9)),
     "mini.toml: blocks: 10000 blocks of 11 gestures make 110,000 trials; a protocol holds "
     "at most 100,000"),
])
def test_validation_names_the_field(tmp_path: Path, edit, message: str) -> None:
    f = tmp_path / "mini.toml"
    f.write_text(edit(GOOD))
    with pytest.raises(ProtocolError) as err:
        load_protocol(f)
    assert message in str(err.value)
    assert "\n" not in str(err.value)
    assert isinstance(err.value, UserError)


PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
ROOT = Path(__file__).resolve().parents[1]


def test_shear9_ships_a_pictogram_per_gesture_as_package_data() -> None:
    shear9 = load_protocol("shear9")
    images = [Path(shear9.image_file(g)) for g in shear9.gestures]
    assert len(images) == 9 and len(set(images)) == 9
    for image in images:
        assert image.is_absolute() and image.read_bytes()[:8] == PNG_MAGIC
        assert 1_000 < image.stat().st_size < 100_000  # small, not empty
    assert len({i.read_bytes() for i in images}) == 9  # nine different pictures
    # installed too: every image matches a package-data glob of tactile_studio.resources
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    resources = ROOT / "resources"
    shipped = {p.resolve() for pattern in config["package-data"]["tactile_studio.resources"]
               for p in resources.glob(pattern)}
    missing = sorted(str(i.relative_to(resources)) for i in images if i.resolve() not in shipped)
    assert not missing, f"add to package-data: {missing}"


def test_image_paths_are_relative_to_the_protocol_file(tmp_path: Path, monkeypatch) -> None:
    folder = tmp_path / "lab"
    (folder / "pics").mkdir(parents=True)
    (folder / "pics" / "rub.png").write_bytes(PNG_MAGIC)
    (folder / "mini.toml").write_text(GOOD.replace('definition = "Rub it."',
                                                   'definition = "Rub it."\n'
                                                   'image = "pics/rub.png"'))
    monkeypatch.chdir(tmp_path)
    p = load_protocol("lab/mini.toml")
    rub = p.gesture_by_name("Rub")
    assert rub.image == "pics/rub.png"  # the name sessions store, no folder of this machine
    assert p.image_file(rub) == str(folder / "pics" / "rub.png")
    assert p.gesture_by_name("Poke").image is None
    assert p.image_file(p.gesture_by_name("Poke")) is None
    assert "lab" not in json.dumps(p.to_dict())
    monkeypatch.chdir(folder / "pics")  # found from any working folder
    assert protocol_from_dict(p.to_dict(), "again").gestures == p.gestures
    assert p.with_overrides(blocks=1).image_file(rub) == p.image_file(rub)
    # a session's copy finds the images through the protocol file at hand, if it is the same
    restored = restored_protocol(p.to_dict(), "session", at_hand=p)
    assert restored.image_file(restored.gesture_by_name("Rub")) == p.image_file(rub)
    other = restored_protocol(p.to_dict(), "session", at_hand=load_protocol("shear9"))
    assert other.image_file(other.gesture_by_name("Rub")) is None  # shows the text alone
    (folder / "pics" / "rub.png").unlink()  # resuming elsewhere: not checked, not refused
    restored = restored_protocol(p.to_dict(), "session")
    assert restored.gesture_by_name("Rub").image == rub.image
    with pytest.raises(ProtocolError, match=r"mini.toml: gestures\[1\].image: no such file"):
        load_protocol(folder / "mini.toml")


def test_missing_protocols_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="unknown protocol 'shear10'.*shear9"):
        load_protocol("shear10")
    with pytest.raises(UserError, match="no such protocol file"):
        load_protocol(tmp_path / "absent.toml")


def test_randomisation_is_per_block_reproducible_and_per_participant() -> None:
    p = load_protocol("shear9")
    a = block_orders(p, "P01", seed=0)
    assert len(a) == 52
    assert all(sorted(block) == sorted(SHEAR9) for block in a)
    assert len({tuple(b) for b in a}) > 40  # a fresh shuffle per block
    assert block_orders(p, "P01", seed=0) == a
    assert block_orders(p, "P02", seed=0) != a
    assert block_orders(p, "P01", seed=1) != a
    assert block_orders(p.with_overrides(blocks=2), "P01", seed=0) == a[:2]
    fixed = p.with_overrides(randomisation="fixed")
    assert block_orders(fixed, "P01") == [SHEAR9] * 52
    eleven = p.with_overrides(practice_trials=11)
    practice = practice_order(eleven, "P01")
    assert len(practice) == 11 and set(practice) <= set(SHEAR9)
    assert practice_order(eleven, "P02") != practice  # each participant gets their own


def test_a_protocol_file_too_large_to_be_one_is_refused_before_it_is_read(
        tmp_path: Path) -> None:
    f = tmp_path / "fat.toml"
    f.write_text(GOOD.replace('definition = "Rub it."', 'definition = "' + "x" * (1 << 20)
                              + '"'))
    with pytest.raises(ProtocolError, match=r"fat.toml: 1.0 MB is not a protocol file "
                                            r"\(at most 1 MB\)"):
        load_protocol(f)
