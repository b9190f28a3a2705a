"""The natural-scene figure-ground variant (model ``natural``): the event-driven
model with contrast-invariant grouping.

The paper's model (``docs/model.md``) keeps two kinds of grouping cell, one
for light figures on dark ground and one for dark on light, and lets them
compete per pixel. A drawn disc has one contrast along its whole outline, so
the competition picks its polarity. A natural object rarely does: a leaf is
lighter than the ground on one side and darker on the other, and the events
of a moving camera add a polarity that follows the motion as much as the
contrast. On the BSDS labels the competing form assigns sides at chance
(``docs/model.md``, "A variant for natural scenes").

This variant changes stages 7 and 8 and the parameters, nothing else:

* **pooled polarities** (``ModelParams.grouping_polarity = "pool"``,
  :class:`~snn_fg.models.rate.pooled.PooledGrouping`): no
  light/dark competition; each grouping cell keeps its own rectified input,
  and the feedback of stage 8 reads the sum of the light and dark grouping
  maps on both sides, ``z1 = z2 = G (*) m1 - G (*) m2`` with ``G = GL + GD``
  (and likewise with the halves swapped): a border-ownership cell is
  enhanced when its side holds more grouping activity of either polarity;
* **no rival inhibition** (``w_inh = 0``): with pooled polarities a rival
  family's inhibition would subtract the same border's other side from each
  grouping cell; without it grouping is excitatory only, which also makes
  the spiking form exact (rectifying each polarity separately and adding, as
  two LIF populations do, equals rectifying the sum);
* **a smaller grouping radius** (``r0 = 4`` px instead of 8): the ownership
  of a natural boundary is decided mostly by what lies just beside it;
  coarser objects are still reached through the pyramid;
* **the side cue** (``side_cue = 3e3``, :mod:`snn_fg.models.rate.side_cue`): at
  level 1 the feedback signal also leans towards the side of a border with
  more events within 160 px, which decides where the grouping is weak.

The choices were made on the tuning half of the shared BSDS images
(``experiments.validation.natural_scenes``, ``docs/model.md``).

Everything else (events, pyramid, oriented responses, border-ownership
cells, feedback gain, read-out) is the reference's.
"""

from __future__ import annotations

from ...params import NATURAL_PARAMS, ModelParams
from ...results.maps import Maps
from .edfg import run_edfg_state


def run_natural(pos, neg, params: ModelParams = NATURAL_PARAMS, progress=None) -> Maps:
    """The natural-scene variant on one event frame (see the module docstring).

    Parameters and result as :func:`snn_fg.models.rate.edfg.run_edfg`, whose stages
    it runs with ``params`` (default :data:`NATURAL_PARAMS`); ``params["model"]``
    is ``"natural"``.

    Examples
    --------
    >>> from snn_fg.events import image_to_frame
    >>> from snn_fg.scoring.metrics import truth_scores
    >>> from snn_fg.frames.scenes import disc
    >>> scene = disc(radius=16)
    >>> maps = run_natural(*image_to_frame(scene.image))
    >>> truth_scores(maps.fg_x, maps.fg_y, scene)["frac_within_45"] > 0.95
    True
    """
    maps = run_edfg_state(pos, neg, params, progress).maps()
    maps.params["model"] = "natural"
    return maps
