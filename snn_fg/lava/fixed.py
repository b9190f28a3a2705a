"""Loihi 2's neuron and synapse arithmetic as Lava 0.10 computes it in fixed point.

STANDALONE: numpy only. Every Lava export carries it as ``fg_loihi.py``;
inside snn_fg the lowering (:mod:`snn_fg.lowering.loihi2`) and the tests
use it. It is read off Lava 0.10's own code: the LIF process model
``PyLifModelBitAcc`` and its base ``AbstractPyLifModelFixed``
(``lava/proc/lif/models.py``), the connection models ``PySparseModelBitAcc``
and ``PyDelaySparseModelBitAcc`` (``lava/proc/sparse/models.py``, the Dense
ones alike) and ``lava/utils/weightutils.py``.

One time step ``t`` (Lava's ``LoihiProtocol`` runs every process's
``run_spk`` once per step; the first step is ``t = 1``):

1. **Connections** (Sparse, DelaySparse). Once, at their first step, the
   weights are clipped to 8 bits and truncated (``clip_weights``,
   ``truncate_weights``): with weights of both signs the range is
   ``[-256, 255]`` with the lowest bit cleared, so an 8-bit signed mantissa
   ``m`` in ``[-128, 127]`` is stored as ``W = 2 m`` (one sign only:
   ``[0, 255]`` or ``[-255, 0]`` as they are; ``W = 2 m`` fits every mode).
   At step ``t`` a connection first sends what it accumulated at step
   ``t - 1``, then receives the spikes its source sent at step ``t`` and
   accumulates ``a = sum W`` over the synapses of the sources that spiked
   (:func:`accumulate`), shifted by the connection's ``weight_exp`` ``e``:
   ``a << e`` for ``e > 0``, ``a >> -e`` (arithmetic, i.e. floor) otherwise.
   A synapse of delay ``k`` (DelaySparse, 0..63 steps) puts its ``W`` into
   the slot sent at step ``t + 1 + k``; a Sparse is a DelaySparse of delay 0.
2. **Neurons** (LIF). ``a_in``, the sum of what every connection into the
   population sent (16 bits on the chip; Lava's simulation does not limit
   it), updates the 24-bit current ``u`` and voltage ``v``
   (:func:`lif_fixed`)::

       u = trunc(u * (4096 - (du + 1)) / 4096) + (a_in << 6)   # wrapped into 24 bits
       v = trunc(v * (4096 - dv) / 4096) + u + (bias_mant << bias_exp)
       v = clip(v, -(2**23 - 1), 2**23 - 1)
       spike where v > vth << 6;  v = 0 there

   ``trunc`` rounds toward zero (``sign(x) * (|x| >> 12)``); the current's
   decay constant is ``du + 1`` (Loihi's 1-bit offset lets it reach 4096),
   the voltage's ``dv``. A current outside 24 bits wraps around (``2**23 + k``
   becomes ``k - 2**23``), a voltage saturates. ``du``, ``dv``: 12-bit
   unsigned; ``bias_mant``: 13-bit signed, ``bias_exp`` 0..7; ``vth``: 17-bit
   unsigned, compared after the same 6-bit shift as the input.
3. **Refractoriness** (not in Lava 0.10's fixed point: its ``LIFRefractory``
   has a floating-point model only; this export's neuron adds it the way
   that model does it): a cell that spikes at step ``t`` keeps ``v`` (0) at
   steps ``t + 1 .. t + refractory_steps`` (no decay, no bias, no input into
   ``v``, no spike) while ``u`` goes on as above.

Timing against the network description (snn_fg's engines, Brian2's
schedule): our step ``n`` is Lava's step ``n + 1``; a spike of step ``n``
through a projection of delay ``d`` steps moves the target's ``v`` at our
step ``n + d + 1`` in both when the connection's Lava delay is ``d``
(:func:`lava_delay`); an input spike of our step ``n`` is sent by the
source at Lava's step ``n + 1``.

Floating point (``select_tag="floating_pt"``, Lava's ``PyLifModelFloat``,
``PyLifRefractoryModelFloat``, ``PySparseModelFloat``) runs the same update
without truncation, wrap-around or saturation: ``u = u (1 - du_f) + a_in``,
``v = v (1 - dv_f) + u + bias``; an export passes it the same numbers
(:func:`float_constants`), so the two differ only in arithmetic.
"""

from __future__ import annotations

import numpy as np

#: decays are 12-bit fractions of this
DECAY_UNITY = 4096
DECAY_SHIFT = 12
#: Loihi's 1-bit offset added to ``du`` (not to ``dv``)
DU_OFFSET = 1
#: input and threshold are shifted left by this many bits to align with the 24-bit state
ACT_SHIFT = 6
VTH_SHIFT = 6
#: the state's bits: |u| wraps and |v| saturates at 2**23
STATE_BITS = 24
STATE_MAX = 2 ** (STATE_BITS - 1)
#: the registers' ranges
DECAY_MAX = 4095
VTH_MAX = 2**17 - 1
BIAS_MANT_MAX = 4095
BIAS_EXP_MAX = 7
#: an 8-bit signed mantissa, stored as W = 2 m by a connection with weights of both signs
MANTISSA_MAX = 127
#: Lava's DelaySparse takes delays of 0..63 steps (Loihi 2's 6 bits)
DELAY_MAX = 63


def trunc_decay(x, d: int) -> np.ndarray:
    """``x * (4096 - d) / 4096`` rounded toward zero, as int64."""
    y = np.asarray(x, np.int64) * (DECAY_UNITY - int(d))
    return np.sign(y) * (np.abs(y) >> DECAY_SHIFT)


def shift(a, e: int) -> np.ndarray:
    """``a << e`` for ``e > 0``, else ``a >> -e`` (floor): a connection's weight exponent."""
    a = np.asarray(a, np.int64)
    return np.left_shift(a, e) if e > 0 else np.right_shift(a, -e)


def effective_bias(bias_mant: int, bias_exp: int) -> int:
    return int(shift(np.int64(bias_mant), int(bias_exp)))


def wrap_current(u) -> np.ndarray:
    """A current outside 24 bits wrapped as Lava wraps it."""
    u = np.asarray(u, np.int64)
    out = np.where(u > STATE_MAX, u - 2 * STATE_MAX, u)
    return np.where(out <= -STATE_MAX, u + 2 * STATE_MAX, out)


def lif_fixed(u, v, a_in, *, du: int, dv: int, bias: int, vth: int, frozen=None):
    """One step of the fixed-point LIF (module docstring, 2 and 3): new ``(u, v, spikes)``.

    ``bias`` is the effective bias (``bias_mant << bias_exp``); ``vth`` the
    17-bit register (compared as ``vth << 6``); ``frozen``: the cells held
    refractory at this step (their ``v`` is kept).
    """
    u = wrap_current(trunc_decay(u, du + DU_OFFSET) + np.left_shift(np.asarray(a_in, np.int64), ACT_SHIFT))
    new_v = np.clip(trunc_decay(v, dv) + u + bias, -(STATE_MAX - 1), STATE_MAX - 1)
    v = new_v if frozen is None else np.where(frozen, v, new_v)
    spikes = v > (int(vth) << VTH_SHIFT)
    return u, np.where(spikes, 0, v), spikes


def lif_float(u, v, a_in, *, du: float, dv: float, bias: float, vth: float, frozen=None):
    """One step of Lava's floating-point LIF with :func:`float_constants`: new ``(u, v, spikes)``."""
    u = u * (1.0 - du) + a_in
    new_v = v * (1.0 - dv) + u + bias
    v = new_v if frozen is None else np.where(frozen, v, new_v)
    spikes = v > vth
    return u, np.where(spikes, 0.0, v), spikes


def float_constants(du: int, dv: int, bias_mant: int, bias_exp: int, vth: int) -> dict:
    """The fixed-point registers as the numbers Lava's floating-point LIF
    takes, in the same units: its decays, bias and threshold."""
    return {
        "du": (du + DU_OFFSET) / DECAY_UNITY,
        "dv": dv / DECAY_UNITY,
        "bias": float(effective_bias(bias_mant, bias_exp)),
        "vth": float(int(vth) << VTH_SHIFT),
    }


def float_weights(w2m, weight_exp: int) -> np.ndarray:
    """A connection's stored weights ``W = 2 m`` as the floating-point
    model's weights in the same units as ``u`` (``W 2**e << 6``, unrounded)."""
    return np.asarray(w2m, np.float64) * 2.0 ** (int(weight_exp) + ACT_SHIFT)


def mantissas(drive, factor: float) -> np.ndarray:
    """8-bit signed mantissas of synaptic drives: ``round(drive * factor)``
    clipped to +-127 (``factor``: mantissa steps per mV of drive, from the
    lowering). A connection stores ``2 m`` (module docstring, 1)."""
    return np.clip(np.round(np.asarray(drive, np.float64) * factor), -MANTISSA_MAX, MANTISSA_MAX).astype(np.int64)


def lava_delay(delay_steps: int) -> int:
    """The DelaySparse delay that gives a projection of ``delay_steps`` of
    our steps its timing (module docstring, last paragraph): the same number."""
    if not 1 <= int(delay_steps) <= DELAY_MAX + 1:
        raise ValueError(f"a delay of {delay_steps} steps: Loihi 2 delays are 0..{DELAY_MAX} steps (ours 1..64)")
    return int(delay_steps)


def accumulate(pre, post, w2m, spiking, n_post: int, weight_exp: int) -> np.ndarray:
    """What one connection sends for the sources ``spiking`` (bool per
    source): ``sum W`` per target over the synapses ``pre -> post`` of
    spiking sources, shifted by the weight exponent."""
    on = np.asarray(spiking, bool)[pre]
    return shift(np.bincount(post[on], weights=w2m[on], minlength=n_post).astype(np.int64), weight_exp)
