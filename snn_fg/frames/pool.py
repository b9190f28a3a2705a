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

A run can keep its maps on the blocks instead (``--maps-grid blocks``,
:data:`MAPS_GRIDS`): one value per block, no unpooling, and the event frame
stored beside them pooled as the network saw it
(:func:`~snn_fg.results.maps.maps_scale` says how many sensor pixels one map
pixel is wide).

On a board this is the input adapter's job (an FPGA or host binning the
camera's events), so the network's spike sources are the blocks.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .pyramid import resize

#: where a run's maps are read out: on the sensor's pixels (the blocks unpooled, :func:`unpool_maps`),
#: or on the network's own blocks (a network that pools its input: one value per block, 1/pool**2 of
#: the pixels to decode, store and draw; what a live run with a short hop can afford)
MAPS_GRIDS = ("sensor", "blocks")


def pooled_shape(shape: tuple[int, int], pool: int) -> tuple[int, int]:
    """``(rows, cols)`` of the model's frame for a sensor frame of ``shape``."""
    h, w = shape
    return (-(-h // pool), -(-w // pool))


def pool_frame(pos: np.ndarray, neg: np.ndarray, pool: int) -> tuple[np.ndarray, np.ndarray]:
    """The event frame the model sees: a block is ON (OFF) where any of its pixels is."""
    if pool == 1:
        return pos, neg
    out = []
    for frame in (pos, neg):
        frame = np.asarray(frame)
        blocks = np.zeros(pooled_shape(frame.shape, pool), np.uint8)
        _any_in_block(frame, pool, blocks)
        out.append(blocks)
    return out[0], out[1]


#: a block of a :func:`signed_frame` with ON and OFF pixels both (a sensor pixel keeps one polarity)
BOTH = 2


def signed_frame(pos: np.ndarray, neg: np.ndarray, pool: int = 1) -> np.ndarray:
    """The event frame as one int8 array, on the blocks of ``pool``: +1 ON, -1 OFF,
    0 no event, :data:`BOTH` a block with ON and OFF pixels (``> 0`` reads it as ON,
    ``!= 0`` as a block with events; :func:`frame_polarities` gives both back)."""
    if pool == 1:
        return np.asarray(pos).astype(np.int8) - np.asarray(neg).astype(np.int8)
    on, off = (np.asarray(f) != 0 for f in pool_frame(pos, neg, pool))
    return np.where(on & off, BOTH, on.astype(np.int8) - off.astype(np.int8)).astype(np.int8)


def frame_polarities(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(pos, neg)`` (bool) of a :func:`signed_frame`: the ON and the OFF pixels or blocks."""
    frame = np.asarray(frame)
    return frame > 0, (frame < 0) | (frame == BOTH)


@njit(cache=True, nogil=True)
def _any_in_block(frame, pool, out):
    """``out[block] = 1`` where any pixel of the block is non-zero."""
    for i in range(frame.shape[0]):
        for j in range(frame.shape[1]):
            if frame[i, j] != 0:
                out[i // pool, j // pool] = 1


def pool_events(events: np.ndarray, pool: int) -> np.ndarray:
    """A copy of ``events`` (:data:`~snn_fg.events.EVENT_DTYPE`) on the block grid."""
    if pool == 1:
        return events
    out = np.empty_like(events)
    if out.dtype.names == ("x", "y", "t", "p"):  # (one compiled pass: numpy's copy and two strided divisions
        _pooled(events, pool, out)  # of a packed record's fields took 58 us a live chunk of 1,700 events)
        return out
    out[...] = events
    out["x"] //= pool
    out["y"] //= pool
    return out


@njit(cache=True, nogil=True)
def _pooled(events, pool, out):
    for i in range(events.size):
        out[i].x, out[i].y = events[i].x // pool, events[i].y // pool
        out[i].t, out[i].p = events[i].t, events[i].p


def event_pixels(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.nonzero(frame)`` of a 2-D frame, the same arrays (row-major order), from
    the flat indices of its non-zero pixels: np.nonzero on a 320 x 240 uint8 frame
    took 0.27 ms, this 0.05 ms (a comparison, one flat pass over bools, a divmod)."""
    on = np.asarray(frame) != 0
    if on.ndim != 2 or on.shape[1] == 0:
        return np.nonzero(on)
    return np.divmod(np.flatnonzero(on), on.shape[1])


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
    coherence ``(l1 - l2) / (l1 + l2)`` of its eigenvalues. The Gaussians
    are ``scipy.ndimage.gaussian_filter``'s (radius 4 sigma, mirrored edges)
    and give its values to the last bit; the block average is taken only
    at the pixels asked for (a window's maps ask for its event pixels)."""
    e0 = np.asarray(edges, dtype=np.float64)
    shape = e0.shape
    if at is None:
        rows, cols = (a.ravel() for a in np.indices(shape))
    else:
        rows, cols = (np.asarray(a, dtype=np.int64) for a in at)
    if min(shape) < 2:  # (no gradient across a line one pixel wide: no direction)
        out = np.ones(rows.size), np.zeros(rows.size), np.zeros(rows.size)
        return out if at is not None else tuple(a.reshape(shape) for a in out)
    w1 = _gaussian_weights(NORMAL_SIGMA)
    smooth, e, live = np.zeros_like(e0), np.zeros_like(e0), np.empty(shape[0], np.bool_)
    _smooth_rows(e0, w1, smooth, live)
    _smooth_cols(smooth, w1, e, live)
    j = np.empty((3, rows.size))
    _block_tensor(e, _gaussian_weights(float(pool)), rows, cols, j)
    jxx, jyy, jxy = j
    phi = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    trace = jxx + jyy
    spread = np.hypot(jxx - jyy, 2.0 * jxy)
    coherence = np.divide(spread, trace, out=np.zeros_like(trace), where=trace > 1e-12)
    out = np.cos(phi), np.sin(phi), np.clip(coherence, 0.0, 1.0)
    return out if at is not None else tuple(a.reshape(shape) for a in out)


def _gaussian_weights(sigma: float) -> np.ndarray:
    """A normalised Gaussian of radius ``int(4 sigma + 0.5)``, computed as
    ``scipy.ndimage.gaussian_filter`` computes its own."""
    x = np.arange(-int(4.0 * sigma + 0.5), int(4.0 * sigma + 0.5) + 1)
    phi = np.exp(-0.5 / (sigma * sigma) * x**2)
    return phi / phi.sum()


@njit(cache=True, inline="always")
def _mirror(i, n):
    """Index ``i`` of a line of ``n`` extended by mirroring (``d c b a | a b c d``),
    again and again where the kernel is wider than the line."""
    if 0 <= i < n:
        return i
    m = i % (2 * n)
    return m if m < n else 2 * n - 1 - m


# The three passes below add a symmetric kernel's products in
# scipy.ndimage's order (the centre, then pairs from the outermost in),
# so their sums are its sums bit for bit.


@njit(cache=True, inline="always")
def _held(v):
    """Whether ``v`` is anything but +0.0 (a pass over +0.0 alone gives +0.0: no product
    of it, no sum with it changes a bit; -0.0 and NaN are passed over as they are)."""
    return v != 0.0 or math.copysign(1.0, v) < 0.0


@njit(cache=True, nogil=True)
def _smooth_rows(x, w, out, live):
    """``x`` smoothed along axis 0 by the symmetric kernel ``w`` into ``out``, which
    holds +0.0 (np.zeros): only the rows within the kernel's reach of a row of ``x``
    that holds a value (:func:`_held`), between the first and last column that
    does, are computed, the rest being +0.0 in ``x`` too (a window's events cover
    about two thirds of the frame's rows); ``live[i]``: row ``i`` was computed."""
    h, n = x.shape
    r = (w.size - 1) // 2
    held = np.zeros(h, np.bool_)
    c0, c1 = n, -1
    for i in range(h):
        for c in range(n):
            if _held(x[i, c]):
                held[i] = True
                c0, c1 = min(c0, c), max(c1, c)
    live[:] = False
    for i in range(h):
        for j in range(-r, r + 1):
            if held[_mirror(i + j, h)]:
                live[i] = True
                break
    for i in range(h):
        if not live[i]:
            continue
        o = out[i, c0 : c1 + 1]
        o[:] = x[i, c0 : c1 + 1] * w[r]
        for j in range(r, 0, -1):
            a, b, wj = x[_mirror(i - j, h), c0 : c1 + 1], x[_mirror(i + j, h), c0 : c1 + 1], w[r - j]
            for c in range(o.size):
                o[c] += (a[c] + b[c]) * wj


@njit(cache=True, nogil=True)
def _smooth_cols(x, w, out, live):
    """``x`` smoothed along axis 1 by the symmetric kernel ``w`` into ``out`` (+0.0),
    on the rows ``live`` only (the others of ``x`` are +0.0: :func:`_smooth_rows`)."""
    n = x.shape[1]
    r = (w.size - 1) // 2
    line = np.empty(n + 2 * r)
    for i in range(x.shape[0]):
        if not live[i]:
            continue
        for c in range(n + 2 * r):
            line[c] = x[i, _mirror(c - r, n)]
        o = out[i]
        for c in range(n):
            o[c] = line[c + r] * w[r]
        for j in range(r, 0, -1):
            wj = w[r - j]
            for c in range(n):
                o[c] += (line[c + r - j] + line[c + r + j]) * wj


@njit(cache=True, nogil=True)
def _block_tensor(e, w, rows, cols, out):
    """The structure tensor ``(jxx, jyy, jxy)`` of the smoothed frame ``e``
    at the pixels ``(rows, cols)`` into ``out`` (3 x pixels): the products of
    ``np.gradient``'s derivatives (x right, y up), smoothed by ``w`` along
    axis 0, then along axis 1 at the pixels. Each pass is computed only where
    the next one reads it: the products on the rows within reach of a pixel's
    row, the pass along axis 0 on the pixels' rows, between the columns
    within reach of their first and last pixel."""
    h, n = e.shape
    r = (w.size - 1) // 2
    slot = np.full(h, -1, np.int64)  # a pixel row's row in the axis-0 pass's arrays
    lo, hi = np.full(h, n, np.int64), np.full(h, -1, np.int64)  # its columns within reach
    for k in range(rows.size):
        i, c = rows[k], cols[k]
        slot[i] = 0
        lo[i], hi[i] = min(lo[i], max(c - r, 0)), max(hi[i], min(c + r, n - 1))
    reach = np.zeros(h, np.bool_)  # the rows the axis-0 pass reads
    m = 0
    for i in range(h):
        if slot[i] >= 0:
            slot[i], m = m, m + 1
            for j in range(-r, r + 1):
                reach[_mirror(i + j, h)] = True
    # the products once per pixel, not once per tap that reads them, between the columns
    # the pass along axis 0 reads (a window's events span about half the frame's)
    pa, pb = n, -1
    for i in range(h):
        if slot[i] >= 0:
            pa, pb = min(pa, lo[i]), max(pb, hi[i])
    ca, cb = max(pa, 1), min(pb, n - 2)  # (the columns with a neighbour on either side)
    pxx, pyy, pxy = np.empty_like(e), np.empty_like(e), np.empty_like(e)
    for i in range(h):
        if not reach[i]:
            continue
        # np.gradient's differences: one-sided (over 1.0) at the first and last row and column
        if i == 0:
            up, down, dy = e[1], e[0], 1.0
        elif i == h - 1:
            up, down, dy = e[h - 1], e[h - 2], 1.0
        else:
            up, down, dy = e[i + 1], e[i - 1], 2.0
        row = e[i]
        for c in (0, n - 1):  # (the first and last column, where asked for)
            if pa <= c <= pb:
                gx = (row[1] - row[0]) / 1.0 if c == 0 else (row[n - 1] - row[n - 2]) / 1.0
                gy = -((up[c] - down[c]) / dy)
                pxx[i, c], pyy[i, c], pxy[i, c] = gx * gx, gy * gy, gx * gy
        if cb < ca:
            continue
        # (the rest as slices walked from 0, with no branch: vector code)
        left, right, u, d = row[ca - 1 : cb], row[ca + 1 : cb + 2], up[ca : cb + 1], down[ca : cb + 1]
        oxx, oyy, oxy = pxx[i, ca : cb + 1], pyy[i, ca : cb + 1], pxy[i, ca : cb + 1]
        for k in range(oxx.size):
            gx = (right[k] - left[k]) / 2.0
            gy = -((u[k] - d[k]) / dy)
            oxx[k], oyy[k], oxy[k] = gx * gx, gy * gy, gx * gy
    txx, tyy, txy = np.empty((m, n)), np.empty((m, n)), np.empty((m, n))
    for i in range(h):
        s = slot[i]
        if s < 0:
            continue
        a0, b0 = lo[i], hi[i] + 1
        # (each array's row between the columns, walked from 0 one array at a time: vector code)
        for t, p in ((txx, pxx), (tyy, pyy), (txy, pxy)):
            out_s, mid = t[s, a0:b0], p[i, a0:b0]
            for c in range(out_s.size):
                out_s[c] = mid[c] * w[r]
            for j in range(r, 0, -1):
                up, down, wj = p[_mirror(i - j, h), a0:b0], p[_mirror(i + j, h), a0:b0], w[r - j]
                for c in range(out_s.size):
                    out_s[c] += (up[c] + down[c]) * wj
    for k in range(rows.size):
        s, c = slot[rows[k]], cols[k]
        axx, ayy, axy = txx[s, c] * w[r], tyy[s, c] * w[r], txy[s, c] * w[r]
        for j in range(r, 0, -1):
            a, b, wj = _mirror(c - j, n), _mirror(c + j, n), w[r - j]
            axx += (txx[s, a] + txx[s, b]) * wj
            ayy += (tyy[s, a] + tyy[s, b]) * wj
            axy += (txy[s, a] + txy[s, b]) * wj
        out[0, k], out[1, k], out[2, k] = axx, ayy, axy


def unpool_maps(fg_x, fg_y, grouping, edges: np.ndarray, pool: int, at=None):
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
    stays as it is. ``at``: ``np.nonzero(edges)``, where the caller has it."""
    if pool == 1:
        return fg_x, fg_y, grouping
    h, w = edges.shape
    on = np.asarray(edges) != 0
    at = event_pixels(on) if at is None else at
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
