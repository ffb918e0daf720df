"""Colour maps as 256-entry uint8 lookup tables, built once from a few anchor colours."""

from __future__ import annotations

from functools import cache

import numpy as np

# Anchor colours (RGB in [0, 1]) evenly spaced over [0, 1]; piecewise-linear in between.
_ANCHORS: dict[str, tuple[tuple[float, float, float], ...]] = {
    # Rainbow from dark blue to dark red, the look of the paper's Fig. 6.
    "jet": ((0.0, 0.0, 0.5), (0.0, 0.0, 1.0), (0.0, 0.5, 1.0), (0.0, 1.0, 1.0), (0.5, 1.0, 0.5),
            (1.0, 1.0, 0.0), (1.0, 0.5, 0.0), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0)),
    # Diverging blue-white-red (signed quantities: vorticity, pressure).
    "diverging": ((0.02, 0.19, 0.38), (0.26, 0.58, 0.77), (0.97, 0.97, 0.97), (0.84, 0.38, 0.30),
                  (0.40, 0.0, 0.12)),
    # Dark blue water to white dye.
    "dye": ((0.02, 0.03, 0.12), (0.10, 0.25, 0.55), (0.45, 0.70, 0.90), (1.0, 1.0, 1.0)),
}

COLORMAP_BY_VIEW = {"speed": "jet", "vorticity": "diverging", "pressure": "diverging",
                    "dye": "dye"}


@cache
def colormap_lut(name: str) -> np.ndarray:
    """Lookup table of colour map ``name``, shape (256, 3) uint8."""
    if name not in _ANCHORS:
        raise ValueError(f"colormap = {name!r}: must be one of {sorted(_ANCHORS)}")
    anchors = np.asarray(_ANCHORS[name])
    positions = np.linspace(0.0, 1.0, len(anchors))
    samples = np.linspace(0.0, 1.0, 256)
    table = np.column_stack([np.interp(samples, positions, anchors[:, c]) for c in range(3)])
    lut = np.round(255.0 * table).astype(np.uint8)
    lut.flags.writeable = False
    return lut


def apply_colormap(values: np.ndarray, low: float, high: float, name: str) -> np.ndarray:
    """Colour ``values`` linearly between ``low`` and ``high`` (clipped): shape ``values.shape
    + (3,)`` uint8."""
    span = high - low if high > low else 1.0
    index = np.clip((values - low) * (255.0 / span), 0.0, 255.0)
    return colormap_lut(name)[np.nan_to_num(index).astype(np.intp)]
