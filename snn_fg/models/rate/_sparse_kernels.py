"""Compiled loops of the event-driven grouping stages (numba).

Each loop touches only active pixels and the kernel footprint around them.
Kernels are stored as ``(channels, K, K)`` tables with, for every kernel row,
the half-open column range ``[lo, hi)`` of its non-zero entries, so a row costs
its support, not its width. The inner loops run over contiguous memory with
unsigned offsets, which lets LLVM vectorise them.
"""

from __future__ import annotations

import numba as nb
import numpy as np

# Re-association lets the compiler vectorise the dot products; contraction
# allows fused multiply-adds. Neither allows non-finite shortcuts.
_FAST = {"reassoc", "contract"}


@nb.njit(fastmath=_FAST, cache=True, nogil=True)
def scatter(a_l, a_d, rows, cols, ch, d_l, d_d, k_l, k_d, lo_l, hi_l, lo_d, hi_d):
    """Add ``d_l[e] * k_l[ch[e]]`` to ``a_l`` and ``d_d[e] * k_d[ch[e]]`` to ``a_d``.

    The kernel's corner lands on ``(rows[e], cols[e])`` of the padded maps;
    entries whose two deltas are both zero are skipped.
    """
    size = k_l.shape[1]
    width = a_l.shape[1]
    flat_l = a_l.ravel()
    flat_d = a_d.ravel()
    for e in range(rows.shape[0]):
        vl = d_l[e]
        vd = d_d[e]
        if vl == 0.0 and vd == 0.0:
            continue
        c = ch[e]
        ker_l = k_l[c].ravel()
        ker_d = k_d[c].ravel()
        # Unsigned offsets: no negative-index wrap-around test in the inner
        # loops, which lets them vectorise.
        base = np.uint64(rows[e] * width + cols[e])
        for i in range(size):
            off = base + np.uint64(i * width)
            koff = np.uint64(i * size)
            for j in range(np.uint64(lo_l[c, i]), np.uint64(hi_l[c, i])):
                flat_l[off + j] += vl * ker_l[koff + j]
            for j in range(np.uint64(lo_d[c, i]), np.uint64(hi_d[c, i])):
                flat_d[off + j] += vd * ker_d[koff + j]


@nb.njit(fastmath=_FAST, cache=True, nogil=True)
def gather(out, g_l, g_d, rows, cols, ch, k_l, k_d, lo_l, hi_l, lo_d, hi_d):
    """``out[e] = sum(g_l * k_l[ch[e]]) - sum(g_d * k_d[ch[e]])`` over the
    footprint whose corner is ``(rows[e], cols[e])`` of the padded maps."""
    size = k_l.shape[1]
    width = g_l.shape[1]
    flat_l = g_l.ravel()
    flat_d = g_d.ravel()
    for e in range(rows.shape[0]):
        c = ch[e]
        ker_l = k_l[c].ravel()
        ker_d = k_d[c].ravel()
        base = np.uint64(rows[e] * width + cols[e])
        acc_l = 0.0
        acc_d = 0.0
        for i in range(size):
            off = base + np.uint64(i * width)
            koff = np.uint64(i * size)
            for j in range(np.uint64(lo_l[c, i]), np.uint64(hi_l[c, i])):
                acc_l += flat_l[off + j] * ker_l[koff + j]
            for j in range(np.uint64(lo_d[c, i]), np.uint64(hi_d[c, i])):
                acc_d += flat_d[off + j] * ker_d[koff + j]
        out[e] = acc_l - acc_d


@nb.njit(cache=True, nogil=True)
def winner_take_all(g_l, g_d, a_l, a_d, pad):
    """Stage 7's rectification and polarity competition on the interior:
    ``GL = max(AL, 0)`` where it beats ``max(AD, 0)``, else 0; ``GD`` likewise."""
    for r in range(pad, a_l.shape[0] - pad):
        for c in range(pad, a_l.shape[1] - pad):
            vl = max(a_l[r, c], 0.0)
            vd = max(a_d[r, c], 0.0)
            g_l[r, c] = vl if vl > vd else 0.0
            g_d[r, c] = vd if vd > vl else 0.0


#: Every type ``pool_add`` is called with, compiled when this module is
#: imported and always in this order. Left to compile on demand, two processes
#: starting from an empty cache (the test workers of a fresh checkout) could
#: meet its float32 and float64 callers in different orders and save each
#: other's machine code under the wrong type in numba's cache index: the next
#: process then failed with "can't unbox array" (or worse).
POOL_ADD_SIGNATURES = [
    f"void({acc}[::1], i8[::1], i8[::1], i8[::1], {x}[:, :, :], i8[::1], f8[:, ::1], i8[::1], f8[:, ::1], f8)"
    for acc in ("f8", "f4")
    for x in ("f8", "f4")
]


@nb.njit(POOL_ADD_SIGNATURES, cache=True, nogil=True)
def pool_add(acc, rows, cols, ch, x, r_start, r_w, c_start, c_w, scale):
    """``acc[e] += scale * cubic(x[ch[e]])`` at target pixel ``(rows[e], cols[e])``.

    ``r_start``/``r_w`` (and ``c_*``) are the 4-tap source windows and weights
    of each target row (column): the separable resize as OpenCV computes it,
    columns first, then rows.
    """
    taps = r_w.shape[1]
    for e in range(rows.shape[0]):
        r = rows[e]
        c = cols[e]
        xc = x[ch[e]]
        rs = r_start[r]
        cs = c_start[c]
        total = 0.0
        for a in range(taps):
            line = 0.0
            for b in range(taps):
                line += c_w[c, b] * xc[rs + a, cs + b]
            total += r_w[r, a] * line
        acc[e] += scale * total


def row_ranges(kernels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per ``(channel, row)`` the column range ``[lo, hi)`` of non-zero entries
    (``lo == hi`` for an empty row)."""
    nz = kernels != 0
    any_ = nz.any(axis=-1)
    width = kernels.shape[-1]
    lo = np.where(any_, nz.argmax(axis=-1), 0)
    hi = np.where(any_, width - nz[..., ::-1].argmax(axis=-1), 0)
    return lo.astype(np.int64), hi.astype(np.int64)


@nb.njit(cache=True, nogil=True)
def mark_taps(mark, rows, cols, ch, r_start, c_start):
    """Set ``mark[ch[e]]`` on the 4 x 4 bicubic source window of each target
    pixel ``(rows[e], cols[e])`` (see :func:`pool_add`)."""
    taps_r = min(4, mark.shape[1])
    taps_c = min(4, mark.shape[2])
    for e in range(rows.shape[0]):
        rs = r_start[rows[e]]
        cs = c_start[cols[e]]
        m = mark[ch[e]]
        for a in range(taps_r):
            for b in range(taps_c):
                m[rs + a, cs + b] = True


@nb.njit(fastmath=_FAST, cache=True, nogil=True)
def dog_at(out, rows, cols, pos, neg, kernels):
    """Oriented responses at listed pixels: circular convolution of ``pos``
    with directions ``0..n-1`` and of ``neg`` with ``n..2n-1`` of
    ``kernels`` (laid out ``(K, K, 2n)``); ``out`` is ``(pixels, 2n)``, zeroed.
    Only non-zero input pixels cost more than a test."""
    size = kernels.shape[0]
    half = size // 2
    n = kernels.shape[2] // 2
    h, w = pos.shape
    wrap_c = np.empty(size, np.int64)
    for e in range(rows.shape[0]):
        acc = out[e]
        for j in range(size):
            wrap_c[j] = (cols[e] - (j - half)) % w
        for i in range(size):
            rr = (rows[e] - (i - half)) % h
            prow = pos[rr]
            nrow = neg[rr]
            for j in range(size):
                cc = wrap_c[j]
                vp = prow[cc]
                vn = nrow[cc]
                if vp != 0.0:
                    ker = kernels[i, j]
                    for k in range(n):
                        acc[k] += vp * ker[k]
                if vn != 0.0:
                    ker = kernels[i, j]
                    for k in range(n, 2 * n):
                        acc[k] += vn * ker[k]
