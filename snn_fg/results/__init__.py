"""What a run writes and reads back: the decoded maps (:mod:`.maps`), a
recording's maps growing window by window on disk (:mod:`.store`), the
figures of the maps (:mod:`.figures`) and the atomic writes every output goes
through (:mod:`.atomic`)."""
