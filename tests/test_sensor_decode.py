"""Decoding raw counts: signs, calibration, virtual taxels, touch detection."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.errors import UserError
from tactile_studio.sensor import SHEARSENSE_6X6, Calibration, decode, get_layout, grid_layout
from tactile_studio.sensor.decode import FrameDecoder, compute_baseline, contact_map, touched
from tactile_studio.sensor.layout import CENTRE, X_NEG, X_POS, Y_NEG, Y_POS

LAY = SHEARSENSE_6X6
BASE = np.linspace(25000, 35000, LAY.n_channels)


def frame_with(rel_by_channel: dict[int, float]) -> np.ndarray:
    """Raw counts with the given relative changes (positive = more load)."""
    rel = np.zeros(LAY.n_channels)
    for ch, v in rel_by_channel.items():
        rel[ch] = v
    return BASE * (1.0 - rel)


def test_layout_geometry_and_names():
    assert LAY.n_channels == 180 and LAY.n_taxels == 36
    assert LAY.taxel_rc(0) == (0, 0) and LAY.taxel_rc(1) == (1, 0) and LAY.taxel_rc(6) == (0, 1)
    assert LAY.taxel_name(0, 0) == "A1" and LAY.taxel_name(5, 5) == "F6"
    assert LAY.channel(7, CENTRE) == 37
    grid = LAY.grid_index()
    assert all(LAY.taxel_rc(grid[r, c]) == (r, c) for r in range(6) for c in range(6))
    assert LAY.pitch_mm == 16.0 and LAY.virtual_shape == (11, 11)


def test_named_layouts_and_grids():
    assert get_layout("cost-8x8").n_channels == 64
    assert get_layout("haart-10x10").rows == 10
    assert get_layout("grid-3x5").n_channels == 15
    with pytest.raises(UserError, match="unknown layout"):
        get_layout("nope")
    with pytest.raises(UserError, match="grid-RxC"):
        get_layout("grid-axb")
    with pytest.raises(UserError):
        grid_layout(0, 3)


def test_idle_decodes_to_zero():
    s = decode(LAY, BASE, BASE)
    assert np.allclose(s.normal, 0) and np.allclose(s.shear_x, 0) and np.allclose(s.shear_y, 0)


def test_press_reads_positive_kpa_through_the_calibration():
    t = LAY.taxel_at(2, 3)
    raw = frame_with({LAY.channel(t, CENTRE): 0.05})
    s = decode(LAY, raw, BASE)
    assert s.normal.shape == (1, 6, 6)
    assert s.normal[0, 2, 3] == pytest.approx(5.0, rel=1e-6)  # 0.05 / (0.01 /kPa)
    assert np.count_nonzero(s.normal) == 1


def test_two_range_normal_calibration_is_continuous_and_inverts():
    cal = Calibration()
    kpa = np.array([0.0, 5.0, 9.3, 20.0, 43.0])
    assert np.allclose(cal.normal_kpa(cal.normal_rel(kpa)), kpa)
    assert cal.normal_kpa(np.array([0.093]))[0] == pytest.approx(9.3)
    # above the split the slope is 6.2e-3 /kPa
    assert cal.normal_kpa(np.array([0.093 + 0.0062]))[0] == pytest.approx(10.3)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_shear_points_the_way_the_skin_is_dragged(axis):
    t = LAY.taxel_at(3, 3)
    neg, pos = (X_NEG, X_POS) if axis == "x" else (Y_NEG, Y_POS)
    # dragging towards +axis loads the +axis channel more than the -axis channel
    raw = frame_with({LAY.channel(t, CENTRE): 0.02, LAY.channel(t, pos): 0.02 + 0.055,
                      LAY.channel(t, neg): 0.02 - 0.055})
    s = decode(LAY, raw, BASE)
    along, across = (s.shear_x, s.shear_y) if axis == "x" else (s.shear_y, s.shear_x)
    assert along[0, 3, 3] == pytest.approx(1.0, rel=0.05)  # 0.11 relative = 1 kPa
    assert abs(across[0, 3, 3]) < 1e-9


def test_virtual_grid_uses_facing_channels():
    rel = {}
    for t in range(LAY.n_taxels):
        for role in range(5):
            rel[LAY.channel(t, role)] = 0.03
    uniform = decode(LAY, frame_with(rel), BASE, virtual=True)
    assert uniform.normal.shape == (1, 11, 11)
    assert np.allclose(uniform.normal, uniform.normal[0, 0, 0])
    # a load between taxel (2,2) and (2,3) lands on their facing channels
    a, b = LAY.taxel_at(2, 2), LAY.taxel_at(2, 3)
    between = decode(LAY, frame_with({LAY.channel(a, X_POS): 0.04, LAY.channel(b, X_NEG): 0.04}),
                     BASE, virtual=True)
    assert np.unravel_index(np.argmax(between.normal[0]), (11, 11)) == (4, 5)


def test_batches_and_channel_count_checks():
    raw = np.stack([BASE, frame_with({LAY.channel(0, CENTRE): 0.01})])
    assert decode(LAY, raw, BASE).normal.shape == (2, 6, 6)
    with pytest.raises(UserError, match="180 channels"):
        decode(LAY, np.zeros((1, 64)), BASE)


def test_touch_detection_uses_97_percent_of_baseline():
    raw = frame_with({LAY.channel(4, X_POS): 0.031, LAY.channel(5, CENTRE): 0.02})
    t = touched(LAY, raw, BASE)
    assert t.sum() == 1 and t[0, LAY.channel(4, X_POS)]
    cm = contact_map(LAY, raw, BASE)
    assert cm.sum() == 1 and cm[0][LAY.taxel_rc(4)]


def test_baseline_is_the_mean_of_the_first_frames():
    frames = np.vstack([np.full((100, 180), 10.0), np.full((50, 180), 99.0)])
    assert np.allclose(compute_baseline(frames), 10.0)
    assert np.allclose(compute_baseline(frames, n=150), (100 * 10 + 50 * 99) / 150)
    with pytest.raises(UserError):
        compute_baseline(np.zeros((0, 180)))


def test_pressure_grid_rises_under_load():
    lay = get_layout("cost-8x8")
    base = np.full(64, 100.0)
    raw = base.copy()
    raw[lay.taxel_at(1, 2)] = 400
    s = decode(lay, raw, base)
    assert s.shear_x is None and s.normal[0, 1, 2] == 300
    assert decode(lay, raw, base, virtual=True).normal.shape == (1, 15, 15)
    assert contact_map(lay, raw, base)[0, 1, 2]


@pytest.mark.parametrize("virtual", [False, True])
def test_single_frame_decoder_matches_decode_exactly(virtual):
    rng = np.random.default_rng(3)
    frames = BASE * (1.0 - rng.uniform(-0.05, 0.08, size=(20, LAY.n_channels)))
    frames[3] = BASE  # idle
    frames[5, LAY.channel(7, CENTRE)] = 0.0  # a dead channel (guarded division)
    fd = FrameDecoder(LAY, BASE, virtual=virtual)
    for raw in frames:
        want = decode(LAY, raw[None], BASE, virtual=virtual)
        got = fd.decode(raw)
        for a, b in ((want.normal, got.normal), (want.shear_x, got.shear_x),
                     (want.shear_y, got.shear_y)):
            assert a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b)
        assert np.array_equal(contact_map(LAY, raw[None], BASE)[0], fd.contact(raw))
    want, got = decode(LAY, frames, BASE, virtual=virtual), fd.decode(frames)  # a batch
    for a, b in ((want.normal, got.normal), (want.shear_x, got.shear_x),
                 (want.shear_y, got.shear_y)):
        assert a.shape == b.shape == (20, *want.normal.shape[1:]) and np.array_equal(a, b)
    grid = get_layout("cost-8x8")
    base = np.full(64, 100.0)
    raw = base + rng.uniform(0, 4000, 64)
    gd = FrameDecoder(grid, base, virtual=virtual)
    assert np.array_equal(gd.decode(raw).normal, decode(grid, raw[None], base, virtual).normal)
    assert gd.decode(raw).shear_x is None
    assert np.array_equal(gd.contact(raw), contact_map(grid, raw[None], base)[0])
    with pytest.raises(UserError, match="180 channels"):
        fd.decode(np.zeros(64))
