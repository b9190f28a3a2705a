"""The rate (non-spiking) models: the paper's event-driven model, the reference
every spiking result is compared with (:mod:`.edfg`, stages 1-9, with its
event-driven grouping stages in :mod:`.grouping`, their state in
:mod:`.grouping_state`, their kernels in :mod:`.grouping_tables`, and
compiled loops in :mod:`._sparse_kernels`); the frame-based model of Hu et
al. 2019 on an image (:mod:`.fbfg`, with the CORF contour operator of
:mod:`.corf`); the natural-scene variant (:mod:`.natural`, its pooled
grouping in :mod:`.pooled` and its side cue in :mod:`.side_cue`); and
Fourier-domain convolution helpers (:mod:`.fourier`). The command line and
:func:`snn_fg.models.get_model` reach them by name (``rate``, ``fbfg``,
``natural``)."""
