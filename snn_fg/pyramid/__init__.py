"""Scales of the input: the image pyramid of stage 2 (:mod:`.levels`) and the
sensor pooled into blocks before stage 1 (:mod:`.pool`, the compact network)."""
