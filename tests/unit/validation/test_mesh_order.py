"""The elastic block's solid-mesh study: the observed order and limit through three runs."""

from __future__ import annotations

import pytest

from elastoflow.validation._elastic_block import MeshRun, observed_order


@pytest.mark.parametrize("order", [1.0, 1.4, 2.0])
def test_observed_order_recovers_a_power_law(order: float) -> None:
    """Runs on a0 - C s^p (s = 1 / cells across, unequal refinement ratios 2 and 1.5) give
    back p and a0."""
    runs = [MeshRun((n, 2 * n, 4 * n), 0, 2.0e-3 - 3.0e-3 * (1.0 / n) ** order, 0.0)
            for n in (4, 8, 12)]
    p, limit = observed_order(runs)
    assert p == pytest.approx(order, abs=1e-9)
    assert limit == pytest.approx(2.0e-3, rel=1e-9)
