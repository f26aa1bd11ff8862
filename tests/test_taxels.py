"""Taxels by name or index, through one parser (tactile_studio/sensor/taxels.py).

Every screen names taxels A1..F6; options that ask for a taxel (``--set fault_taxel=``,
``--taxels``, ``--spots``, ``--hover``) accept the name as well as the index.
"""

from __future__ import annotations

import pytest

from tactile_studio.cli import main
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import SettingsError, UserError
from tactile_studio.live import parse_taxel_name
from tactile_studio.sensor.characterise import parse_taxels as characterise_taxels
from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAY
from tactile_studio.sensor.taxels import parse_taxel, parse_taxels, taxel_label
from tactile_studio.sensor.wellness import parse_taxel as wellness_taxel
from tactile_studio.storage.format.session_file import SessionFile


def test_names_and_indices_name_the_same_taxel():
    for t in range(LAY.n_taxels):
        name = taxel_label(LAY, t)
        assert parse_taxel(LAY, name) == parse_taxel(LAY, name.lower()) == t
        assert parse_taxel(LAY, str(t)) == parse_taxel(LAY, t) == t
    assert taxel_label(LAY, 14) == "C3" and parse_taxel(LAY, " c3 ") == 14
    assert parse_taxels(LAY, "B2, 7,c3") == [7, 7, 14]
    assert parse_taxels(LAY, "all")[:7] == [0, 6, 12, 18, 24, 30, 1]  # A1..A6, B1: row by row
    # the older entry points are the same parser
    assert wellness_taxel(LAY, "14") == characterise_taxels(LAY, "C3")[0] == 14
    assert parse_taxel_name(LAY, "14") == parse_taxel_name(LAY, "c3") == (2, 2)


@pytest.mark.parametrize("bad", ["G1", "A7", "36", "-1", "C", "3C", "", "x9"])
def test_a_bad_taxel_names_the_valid_range(bad):
    with pytest.raises(UserError, match=r"is not a taxel of shearsense-6x6 \(A1\.\.F6\) "
                                        r"or an index \(0\.\.35\)"):
        parse_taxel(LAY, bad)


def test_fault_taxel_takes_a_name_as_every_screen_shows_it():
    by_name = create_device("simulated", {"fault_taxel": "C3", "fault": "dead_taxel"})
    by_index = create_device("simulated", {"fault_taxel": "14", "fault": "dead_taxel"})
    assert by_name._sim.config.fault_taxel == by_index._sim.config.fault_taxel == 14
    assert by_name.settings["fault_taxel"] == "C3"
    with pytest.raises(SettingsError, match="setting fault_taxel: 'G9' is not a taxel"):
        create_device("simulated", {"fault_taxel": "G9"})
    with pytest.raises(SettingsError, match="fault_taxel: 'middle' is not a valid taxel"):
        create_device("simulated", {"fault_taxel": "middle"})


def test_the_cli_records_with_a_named_fault_taxel(tmp_path, capsys):
    out = tmp_path / "c3.h5"
    code = main(["record", "--device", "simulated", "--set", "fault_taxel=C3", "--set",
                 "fault=dead_taxel", "--set", "speed=0", "--seconds", "0.5", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    capsys.readouterr()
    with SessionFile(out) as s:
        assert s.n_frames > 0
    code = main(["record", "--device", "simulated", "--set", "fault_taxel=Z9",
                 "--seconds", "0.5", "--out", str(tmp_path / "z9.h5")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "'Z9' is not a taxel" in err[0]
