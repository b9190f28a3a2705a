"""Stage 0 of the compact network: sensor pixels pooled into blocks before stage 1.

With ``ModelParams.input_pool = p`` the model sees the sensor through blocks
of ``p x p`` pixels: an event at sensor pixel ``(x, y)`` is an event at
model pixel ``(x // p, y // p)``, and a block of an event frame is ON (OFF)
where any of its pixels is (a block can be both, as a pixel of a recording
with ON and OFF events in one window drives both of its spike sources). A
partial block at the right or bottom edge counts as a whole one. The maps
come back at the sensor's size: every event pixel takes its block's
figure-ground vector, and the grouping map is resized bilinearly.

On a board this is the input adapter's job (an FPGA or host binning the
camera's events), so the network's spike sources are the blocks.
"""
from __future__ import annotations

import numpy as np

from .levels import resize


def pooled_shape(shape: tuple[int, int], pool: int) -> tuple[int, int]:
    """``(rows, cols)`` of the model's frame for a sensor frame of ``shape``."""
    h, w = shape
    return (-(-h // pool), -(-w // pool))


def _blocks(a: np.ndarray, pool: int) -> np.ndarray:
    """``a`` (H x W) zero-padded to whole blocks, as (rows, pool, cols, pool)."""
    h, w = pooled_shape(a.shape, pool)
    padded = np.zeros((h * pool, w * pool), dtype=a.dtype)
    padded[:a.shape[0], :a.shape[1]] = a
    return padded.reshape(h, pool, w, pool)


def pool_frame(pos: np.ndarray, neg: np.ndarray, pool: int) -> tuple[np.ndarray, np.ndarray]:
    """The event frame the model sees: a block is ON (OFF) where any of its pixels is."""
    if pool == 1:
        return pos, neg
    on = _blocks(np.asarray(pos) != 0, pool).any(axis=(1, 3))
    off = _blocks(np.asarray(neg) != 0, pool).any(axis=(1, 3))
    return on.astype(np.uint8), off.astype(np.uint8)


def pool_events(events: np.ndarray, pool: int) -> np.ndarray:
    """A copy of ``events`` (:data:`~snn_fg.events.EVENT_DTYPE`) on the block grid."""
    if pool == 1:
        return events
    out = events.copy()
    out["x"] //= pool
    out["y"] //= pool
    return out


def unpool_maps(fg_x, fg_y, grouping, edges: np.ndarray, pool: int):
    """Maps on the block grid back at the sensor's size (``edges``: H x W,
    the sensor's event pixels): each event pixel takes its block's vector;
    the grouping map is resized bilinearly."""
    if pool == 1:
        return fg_x, fg_y, grouping
    h, w = edges.shape
    on = np.asarray(edges) != 0

    def up(a):
        return np.where(on, np.repeat(np.repeat(a, pool, axis=0), pool, axis=1)[:h, :w], 0).astype(a.dtype)

    g = np.asarray(grouping)
    whole = resize(g.astype(np.float64), (g.shape[0] * pool, g.shape[1] * pool), "linear")
    return up(fg_x), up(fg_y), whole[:h, :w].astype(g.dtype)
