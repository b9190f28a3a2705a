"""What a run writes and reads back: the decoded maps (:mod:`~snn_fg.results.maps`), a
recording's maps growing window by window on disk (:mod:`~snn_fg.results.store`), the
figures of the maps (:mod:`~snn_fg.results.figures`), what a recording's run writes beside them
(:mod:`~snn_fg.results.overview`: its table and timeline, :mod:`~snn_fg.results.timeline`; any
window as a figure; its animation, :mod:`~snn_fg.results.animation`), a recording's activity
over time and its figure (:mod:`~snn_fg.results.activity`), the atomic writes every output goes
through (:mod:`~snn_fg.results.atomic`), what a command may write over
(:mod:`~snn_fg.results.outputs`) and the progress long work shows meanwhile
(:mod:`~snn_fg.results.progress`)."""
