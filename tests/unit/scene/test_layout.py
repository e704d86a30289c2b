"""The layout of the unknowns (cosserat_fem/scene/layout.py): exact bookkeeping, no tolerance."""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.scene.build import PLANAR
from cosserat_fem.scene.layout import FULL, NAMES, Layout

pytestmark = pytest.mark.unit


@pytest.mark.parametrize("components", [FULL, PLANAR["x-z"], PLANAR["y-z"], FULL[:6]])
def test_a_layout_embeds_and_extracts_its_components(components):
    """full_array puts each entry at its component (zeros elsewhere) and from_full takes it
    back: a round trip of 4 nodes is the identity, bit for bit."""
    layout = Layout(components)
    nodes = 4
    state = np.arange(nodes * layout.size, dtype=float) + 0.5
    full = layout.full_array(state)
    assert full.shape == (nodes, 12)
    for j, c in enumerate(components):
        assert np.array_equal(full[:, c], state.reshape(nodes, -1)[:, j])
    others = [c for c in FULL if c not in components]
    assert not full[:, others].any()
    assert np.array_equal(layout.from_full(full.ravel(), nodes), state)
    assert layout.reduced == (components != FULL)
    assert layout.p_count == sum(c < 6 for c in components)
    assert layout.names == tuple(NAMES[c] for c in components)


def test_planar_layouts_are_those_of_their_plane():
    assert Layout(PLANAR["x-z"]).p_names == ("x", "z", "psi")
    assert Layout(PLANAR["y-z"]).p_names == ("y", "z", "theta")
    assert Layout(PLANAR["x-z"]).index(4) == 2 and Layout(PLANAR["x-z"]).index(3) is None


def test_si_scale():
    """ℓ for positions, 1 for angles, ℓ ω0 and ω0 for their τ-rates (τ = ω0 t, (47))."""
    scale = Layout(PLANAR["x-z"]).si_scale(2.0, 10.0)  # x, z, psi and their rates
    assert scale.tolist() == [2.0, 2.0, 1.0, 20.0, 20.0, 10.0]


@pytest.mark.parametrize("components", [(0, 0), (12,), (6, 0), (0, 6, 1)])
def test_malformed_layouts_are_refused(components):
    with pytest.raises(ValueError):
        Layout(components)


def test_a_state_of_another_size_is_refused():
    with pytest.raises(ValueError, match="12 per node"):
        Layout(PLANAR["x-z"]).from_full(np.zeros(6 * 3), 3)
