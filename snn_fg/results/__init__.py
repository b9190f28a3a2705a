"""What a run writes and reads back: the decoded maps (:mod:`~snn_fg.results.maps`), a
recording's maps growing window by window on disk (:mod:`~snn_fg.results.store`), the
figures of the maps (:mod:`~snn_fg.results.figures`) and the atomic writes every output goes
through (:mod:`~snn_fg.results.atomic`)."""
