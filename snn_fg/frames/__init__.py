"""What a model sees: a still input as an event frame (:mod:`.still`: an
``.npz`` frame, an image, the demo), the built-in scenes (:mod:`.scenes`),
the sensor pooled into blocks before stage 1 (:mod:`.pool`, the compact
network) and the pyramid of stage 2 (:mod:`.pyramid`)."""
