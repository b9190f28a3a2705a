"""What one spike adds to its target's input, as the fast engine holds it:
a Conv's *stencil* rows and a Resize's interpolation factors.

A Conv's kept taps are grouped by the class of the source (its input
channel and its level pixel modulo the target's stride, see
:func:`~snn_fg.backends.fast.tables.conv_classes`); each lands ``(qr, qc)``
lattice points before the source's own, on output channel ``co``. The taps
of one class, output channel and ``qr`` with consecutive ``qc`` form a
*row*: one contiguous run of weights in the target's ``(channel, row,
column)`` layout (zeros where a tap was pruned), its taps added one by one.
More than :data:`MAX_GAP` empty columns between two taps start a new row,
and a row spans at most :data:`MAX_COLS` columns (its taps are the bits of
one 64-bit word, the row's ``R_NZ`` value: bit ``j`` for value ``j``).

For a source at lattice point ``(row, column)`` (its level pixel divided by
the target stride), a row lands on target row ``row - qr`` of channel
``co``, from column ``column - qc_hi`` on; with wrap-around padding both
are taken modulo the target grid, otherwise what falls outside is dropped.
"""

from __future__ import annotations

import numpy as np

from ...lowering.connect import resize_factors, resize_kept_mass
from ..base import receptor_weights

#: volts per millivolt (Brian2's ``mV``): weights and potentials are scaled
#: by it exactly as Brian2 scales them
MV = 1e-3
#: more empty columns than this between two taps of a stencil row split it
#: (adding a few zeros costs less than starting another row)
MAX_GAP = 4
#: the most columns of one stencil row (a row's taps are one 64-bit mask)
MAX_COLS = 64
#: a stencil row's values in ``row_tab`` (8 int64 a row, one cache line): its output channel,
#: lattice offsets, columns, first value in ``st_w``, which values are taps (bits, as int64), its
#: (channel, row) and its first value's place in the summed input from lattice point (0, 0)
R_CO, R_QR, R_QC, R_NCOL, R_W0, R_NZ, R_DR, R_OFF = range(8)
R_N = 8


def tap_weights(pr, k: np.ndarray) -> np.ndarray:
    """What a Conv's taps with kernel values ``k`` add to their receptor
    (volts); exactly 0.0 where ``k`` is 0 (the padding of stencil rows)."""
    w = receptor_weights(pr.sign, pr.sign * pr.gain_mv * k) * MV
    return np.where(k == 0, 0.0, w)


def stencil_rows(co, cls, qr, qc, k, n_cls: int) -> dict:
    """The stencil rows of one Conv from its taps (output channel ``co``,
    class ``cls``, lattice offset ``(qr, qc)``, kernel value ``k``).

    Returns ``cls_ptr`` (rows of class ``c`` are ``cls_ptr[c] .. cls_ptr[c +
    1]``) and per row ``co``, ``qr``, ``qc_hi`` (its values are offsets
    ``qc_hi`` down to ``qc_hi - ncol + 1``: ascending target columns),
    ``ncol`` and ``w0`` (its first value in ``k``); ``k`` the values, 0 in the gaps.
    """
    order = np.lexsort((qc, qr, co, cls))
    co, cls, qr, qc, k = (
        np.asarray(a, np.int64)[order] if i < 4 else np.asarray(a)[order] for i, a in enumerate((co, cls, qr, qc, k))
    )
    n = cls.size
    if n == 0:
        none = np.zeros(0, np.int64)
        return {
            "cls_ptr": np.zeros(n_cls + 1, np.int64),
            "co": none,
            "qr": none,
            "qc_hi": none,
            "ncol": none,
            "w0": none,
            "k": np.zeros(0),
        }
    new_row = np.ones(n, bool)
    new_row[1:] = (cls[1:] != cls[:-1]) | (co[1:] != co[:-1]) | (qr[1:] != qr[:-1]) | (qc[1:] - qc[:-1] > MAX_GAP + 1)
    # (a row longer than MAX_COLS columns is cut where a tap would make it longer)
    start = np.maximum.accumulate(np.where(new_row, np.arange(n), 0))
    while True:
        too_long = qc - qc[start] >= MAX_COLS
        if not too_long.any():
            break
        first_long = too_long & ~np.roll(too_long, 1) | (too_long & new_row)
        new_row |= first_long
        start = np.maximum.accumulate(np.where(new_row, np.arange(n), 0))
    row = np.cumsum(new_row) - 1
    first = np.nonzero(new_row)[0]
    last = np.append(first[1:] - 1, n - 1)
    qc_hi = qc[last]
    ncol = qc_hi - qc[first] + 1
    w0 = np.zeros(ncol.size, np.int64)
    np.cumsum(ncol[:-1], out=w0[1:])
    values = np.zeros(int(ncol.sum()))
    j = qc_hi[row] - qc
    values[w0[row] + j] = k
    nz = np.zeros(ncol.size, np.uint64)
    np.bitwise_or.at(nz, row, np.left_shift(np.uint64(1), j.astype(np.uint64)))
    return {
        "cls_ptr": np.searchsorted(cls[first], np.arange(n_cls + 1)).astype(np.int64),
        "co": co[first],
        "qr": qr[first],
        "qc_hi": qc_hi,
        "ncol": ncol,
        "w0": w0,
        "nz": nz,
        "k": values,
    }


class StencilCollector:
    """Concatenates the stencil rows and interpolation factors of every
    projection into the flat arrays the compiled loops read."""

    def __init__(self):
        self.parts = {name: [] for name in ("cls_ptr", "co", "qr", "qc_hi", "ncol", "w0", "nz", "k", "w", "dr", "off")}
        self.parts["cls_ptr"].append(np.zeros(1, np.int64))
        self.n_cls = self.n_rows = self.n_values = 0
        self.csr = [[np.zeros(1, np.int64)], [], []]
        self.n_csr_rows = self.n_csr = 0

    def conv(self, pr, rows: dict, grid: tuple[int, int]) -> tuple[int, int, int]:
        """Add one Conv's rows (:func:`stencil_rows`) onto a target of
        ``grid`` (rows, columns); returns its first class, and the span of
        its values (for remaking the weights).

        Each row also gets where it lands from a source at lattice point
        ``(0, 0)``, as offsets into the target's ``(channel, row)`` rows
        (``dr = co * rows - qr``) and into its summed input (``off = dr *
        columns - qc_hi``): a spike that lands whole then finds a row's
        place with one addition each."""
        base, first = self.n_cls, self.n_values
        n_rows, k = rows["qr"].size, rows["k"]
        self.parts["cls_ptr"].append(rows["cls_ptr"][1:] + self.n_rows)
        for name in ("co", "qr", "qc_hi", "ncol", "nz"):
            self.parts[name].append(rows[name])
        dr = np.asarray(rows["co"], np.int64) * grid[0] - rows["qr"]
        self.parts["dr"].append(dr)
        self.parts["off"].append(dr * grid[1] - rows["qc_hi"])
        self.parts["w0"].append(rows["w0"] + self.n_values)
        self.parts["k"].append(k)
        self.parts["w"].append(tap_weights(pr, k))
        self.n_cls += rows["cls_ptr"].size - 1
        self.n_rows += n_rows
        self.n_values += k.size
        return base, first, self.n_values

    def factor(self, a: np.ndarray) -> int:
        """Add one interpolation matrix, transposed (each source index, its
        targets and weights); returns its first row."""
        tgt, src = np.nonzero(a)
        order = np.lexsort((tgt, src))
        ptr = np.searchsorted(src[order], np.arange(a.shape[1] + 1))
        base = self.n_csr_rows
        self.csr[0].append(ptr[1:] + self.n_csr)
        self.csr[1].append(tgt[order])
        self.csr[2].append(a[tgt[order], src[order]])
        self.n_csr_rows += ptr.size - 1
        self.n_csr += ptr[-1]
        return base

    def arrays(self) -> dict:
        cat = {name: np.concatenate(x) if x else np.zeros(0) for name, x in self.parts.items()}
        csr = [np.concatenate(x) if x else np.zeros(0) for x in self.csr]
        return {
            "cls_ptr": cat["cls_ptr"].astype(np.int64),
            "row_tab": row_table(cat),
            "st_w": cat["w"].astype(np.float64),
            "st_k": cat["k"].astype(np.float64),
            "csr_ptr": csr[0].astype(np.int64),
            "csr_idx": csr[1].astype(np.int32),
            "csr_val": csr[2].astype(np.float64),
        }


def row_table(cat: dict) -> np.ndarray:
    """The stencil rows' values (``cat``: the collector's columns), 8 int64 a
    row (columns ``R_*``) in one flat array starting on a 64-byte boundary:
    a row is read from one cache line through one pointer (8 arrays held the
    delivery's row loop's registers, and it kept its own counters on the stack)."""
    cols = ("co", "qr", "qc_hi", "ncol", "w0", "nz", "dr", "off")
    n = cat["co"].size
    raw = np.zeros(n * R_N + R_N, np.int64)
    skip = (-raw.ctypes.data % 64) // 8  # (numpy aligns to 16 bytes)
    tab = raw[skip : skip + n * R_N].reshape(n, R_N)
    for k, name in enumerate(cols):
        x = cat[name]
        tab[:, k] = x.astype(np.uint64).view(np.int64) if name == "nz" else x.astype(np.int64)
    return tab.reshape(-1)


def resize_factors_of(pr, src, tgt, collector: StencilCollector, weight_bits=None):
    """A Resize's two factors added to ``collector``: ``(row base, column
    base, kept mass, taps, prune threshold, quantisation step)``."""
    ar, ac, peak = resize_factors(pr, src, tgt)
    base, colbase = collector.factor(ar), collector.factor(ac)
    taps = int(np.count_nonzero(ar)) * int(np.count_nonzero(ac))
    step = 0.0 if weight_bits is None else peak / (2 ** (weight_bits - 1) - 1)
    return base, colbase, resize_kept_mass(ar, ac, pr.prune, peak), taps, pr.prune * peak, step
