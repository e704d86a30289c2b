"""Unit checks of cosserat_fem/rom/basis.py's algebra without a rod: the SVD both POD's share
(serial, and its tall-skinny QR path under a stand-in communicator of several 'ranks'), the
number of modes of an energy tolerance, and the pairing of p's rows with its rate's."""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.rom.basis import state_rows
from cosserat_fem.scene.layout import Layout
from cosserat_fem.studies.karhunen_loeve import modes_for_tolerance, snapshot_svd

pytestmark = pytest.mark.unit


class _Ranks:
    """A communicator of ``size`` ranks seen from one of them: allgather returns the blocks
    every rank would give (the test sets them), as MPI would."""

    def __init__(self, blocks):
        self.size, self.blocks = len(blocks), blocks

    def allgather(self, _local):
        return [np.linalg.qr(b, mode="r") for b in self.blocks]


def test_tall_skinny_svd_equals_the_serial_one():
    """A = [A_0; A_1] split over two 'ranks': the QR path's singular values equal numpy's SVD
    of the whole to round-off of the largest (both backward stable: |δσ| ≤ c ε σ_1, here
    1e-13 σ_1), and each rank's rows of Φ are the whole Φ's rows (up to each column's sign)
    to c ε σ_1/σ_k ≤ 1e-9 (A's condition is 1e6)."""
    rng = np.random.default_rng(1)
    scales = np.logspace(0, -6, 7)
    A = rng.standard_normal((40, 7)) * scales @ np.linalg.qr(rng.standard_normal((7, 7)))[0]
    Phi, sigma, _ = snapshot_svd(A)
    blocks = [A[:25], A[25:]]
    for rank, rows in enumerate((slice(0, 25), slice(25, 40))):
        Phi_r, sigma_r, _ = snapshot_svd(blocks[rank], _Ranks(blocks))
        assert np.abs(sigma_r - sigma).max() <= 1e-13 * sigma[0]
        signs = np.sign(np.sum(Phi_r * Phi[rows], axis=0))
        assert np.allclose(Phi_r * signs, Phi[rows], atol=1e-9)


def test_modes_for_tolerance():
    """Energies 8, 4, 2, 1, 1 (total 16): left out after k = 1..5 modes 1/2, 1/4, 1/8, 1/16, 0;
    the fewest modes with at most the tolerance left out."""
    energies = np.array([8.0, 4.0, 2.0, 1.0, 1.0])
    assert modes_for_tolerance(energies, 0.5) == 1
    assert modes_for_tolerance(energies, 0.25) == 2
    assert modes_for_tolerance(energies, 0.2) == 3
    assert modes_for_tolerance(energies, 1 / 16) == 4
    assert modes_for_tolerance(energies, 0.0) == 5


def test_state_rows_pair_p_with_its_rate():
    """The x-z plane's layout (x, z, ψ, ẋ, ż, ψ̇): rows 0-2 of each block are p, 3-5 its rates;
    a layout whose rates do not follow p's order is refused (SceneError)."""
    p, q = state_rows(Layout((0, 2, 4, 6, 8, 10)), 12)
    assert p.tolist() == [0, 1, 2, 6, 7, 8] and q.tolist() == [3, 4, 5, 9, 10, 11]
    with pytest.raises(SceneError, match="layout"):
        state_rows(Layout((0, 2, 8, 6)), 8)


def _quaternions(rng, nodes):
    Q = rng.standard_normal((nodes, 4))
    Q /= np.linalg.norm(Q, axis=1)[:, None]
    Q[Q[:, 0] < 0] *= -1.0
    return Q


def test_a_basis_per_chart_is_the_pod_of_the_states_in_that_chart():
    """basis.in_chart: T = 12 states of 5 nodes (angles up to 0.5 rad, random rates), given in
    the chart Q_new, each recorded in another random chart Q_s (charts.change_chart: the same
    directors and angular velocity, angles up to π/2) and its snapshot u_s = U_s − U_ref kept
    with Q_s. Mapped back to Q_new and POD'd to the same k = 4 they span what the POD of the
    states in Q_new spans: the W-projectors V Vᵀ W agree to 1e-9 (a round trip through two
    charts is exact to ~1e-15 rad; the projector's sensitivity is that over the gap between
    the 4th and 5th singular values, ~1e2 here). The energy left out is the same POD's. A
    basis without its snapshots (a file's) is refused in one line."""
    from types import SimpleNamespace

    from cosserat_fem.common.errors import SolverError
    from cosserat_fem.rod.charts import change_chart
    from cosserat_fem.rom.basis import Basis, in_chart, pod_modes

    class _Comm:
        size = 1

        def allgather(self, x):
            return [x]

    rng = np.random.default_rng(3)
    nodes, T, k, layout = 5, 12, 4, Layout()
    Q_new = _quaternions(rng, nodes)
    states = 0.5 * rng.uniform(-1, 1, (T, nodes, 12))
    weights = rng.uniform(0.5, 2.0, nodes * 12)
    reference = np.zeros(nodes * 12)
    columns, charts = [], []
    for s in range(T):
        Q_s = _quaternions(rng, nodes)
        columns.append(change_chart(states[s], Q_new, Q_s).ravel())
        charts.append(Q_s.ravel())
    V0, energies0, _ = pod_modes(layout, weights, states.reshape(T, -1).T, _Comm(), modes=k)
    basis = Basis(
        np.eye(nodes * 12)[:, : 2 * k],  # any V: in_chart makes its own
        reference,
        weights,
        energies0,
        {},
        {},
        snapshots=np.column_stack(columns),
        snapshot_charts=charts,
    )
    model = SimpleNamespace(
        layout=layout,
        msh=SimpleNamespace(comm=_Comm()),
        chart=SimpleNamespace(x=SimpleNamespace(array=Q_new.ravel())),
    )
    mapped, left = in_chart(basis, model)
    projector = mapped.V @ mapped.V.T * weights
    assert np.abs(projector - V0 @ V0.T * weights).max() <= 1e-9
    assert left == pytest.approx(energies0[k:].sum() / energies0.sum(), rel=1e-9)
    bare = Basis(basis.V, reference, weights, energies0, {}, {})
    with pytest.raises(SolverError) as refused:
        in_chart(bare, model)
    assert "\n" not in str(refused.value) and "snapshots" in str(refused.value)
