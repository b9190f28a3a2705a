"""Stage 0 of the compact network: sensor pixels pooled into blocks before stage 1.

With ``ModelParams.input_pool = p`` the model sees the sensor through blocks
of ``p x p`` pixels: an event at sensor pixel ``(x, y)`` is an event at
model pixel ``(x // p, y // p)``, and a block of an event frame is ON (OFF)
where any of its pixels is (a block can be both, as a pixel of a recording
with ON and OFF events in one window drives both of its spike sources). A
partial block at the right or bottom edge counts as a whole one. The maps
come back at the sensor's size (:func:`unpool_maps`): every event pixel
takes its block's figure-ground vector, turned towards the pixel's own edge
normal (the network decides the side, the sensor's pixels say where the
edge runs), and the grouping map is resized bilinearly.

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


#: scale (sensor pixels) over which the event frame is smoothed before its
#: gradients are taken for the edge normals of :func:`edge_normals`
NORMAL_SIGMA = 1.0


def edge_normals(edges: np.ndarray, pool: int, at=None):
    """The edge normal at pixels of a sensor's event frame ``edges`` (H x W)
    and how line-like the events around them are: ``(nx, ny, coherence)``
    at the pixels ``at`` (a tuple of index arrays, as ``np.nonzero`` gives;
    every pixel, as H x W arrays, if None), ``(nx, ny)`` a unit vector (x right, y up) of
    arbitrary sign, ``coherence`` in [0, 1] (1: a straight line of events;
    0: no direction, such as a lone event or a corner).

    From the structure tensor: the gradients of the frame smoothed over
    :data:`NORMAL_SIGMA`, their products averaged over a block (a Gaussian
    of ``pool`` pixels); the normal is its leading eigenvector, the
    coherence ``(l1 - l2) / (l1 + l2)`` of its eigenvalues."""
    from scipy.ndimage import gaussian_filter

    e = gaussian_filter(np.asarray(edges, dtype=np.float64), NORMAL_SIGMA)
    d_row, d_col = np.gradient(e)
    gx, gy = d_col, -d_row
    at = (slice(None), slice(None)) if at is None else at
    jxx, jyy, jxy = (gaussian_filter(a, float(pool))[at] for a in (gx * gx, gy * gy, gx * gy))
    phi = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    trace = jxx + jyy
    spread = np.hypot(jxx - jyy, 2.0 * jxy)
    coherence = np.divide(spread, trace, out=np.zeros_like(trace), where=trace > 1e-12)
    return np.cos(phi), np.sin(phi), np.clip(coherence, 0.0, 1.0)


def unpool_maps(fg_x, fg_y, grouping, edges: np.ndarray, pool: int):
    """Maps on the block grid back at the sensor's size (``edges``: H x W,
    the sensor's event pixels); the grouping map is resized bilinearly.

    Each event pixel takes its block's vector ``v``, turned towards the
    pixel's own edge normal ``n`` (:func:`edge_normals`), on the side ``v``
    points to: the vector becomes ``|v|`` times the unit vector along
    ``c s n + (1 - c) v / |v|``, with ``s = sign(v . n)`` and ``c`` the
    coherence. A block's vector has the block's angle, which on a curved
    or slanted edge is off the edge's own normal by up to the block's
    width; the side is the network's decision and is kept. Where the
    events around a pixel make no line (``c`` near 0) the block's vector
    stays as it is."""
    if pool == 1:
        return fg_x, fg_y, grouping
    h, w = edges.shape
    on = np.asarray(edges) != 0
    at = np.nonzero(on)
    bx, by = (np.asarray(a, np.float64)[at[0] // pool, at[1] // pool] for a in (fg_x, fg_y))
    mag = np.hypot(bx, by)
    nx, ny, c = edge_normals(on, pool, at)
    s = np.where(bx * nx + by * ny >= 0, 1.0, -1.0)
    unit_x = np.divide(bx, mag, out=np.zeros_like(mag), where=mag > 0)
    unit_y = np.divide(by, mag, out=np.zeros_like(mag), where=mag > 0)
    tx, ty = c * s * nx + (1 - c) * unit_x, c * s * ny + (1 - c) * unit_y
    t = np.hypot(tx, ty)
    ok = (mag > 0) & (t > 0)
    ux, uy = np.zeros((h, w), np.asarray(fg_x).dtype), np.zeros((h, w), np.asarray(fg_y).dtype)
    ux[at] = np.divide(mag * tx, t, out=np.zeros_like(mag), where=ok)
    uy[at] = np.divide(mag * ty, t, out=np.zeros_like(mag), where=ok)
    g = np.asarray(grouping)
    whole = resize(g.astype(np.float64), (g.shape[0] * pool, g.shape[1] * pool), "linear")
    return ux, uy, whole[:h, :w].astype(g.dtype)
