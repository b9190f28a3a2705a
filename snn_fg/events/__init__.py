"""Event-camera input for snn-fg.

* :func:`open_recording` / :func:`iter_recording`: read any supported
  recording (``.es`` DVS or ATIS, ``.raw`` EVT2/EVT3, ``.dat``, ``.aedat``
  (AEDAT 2.0, 3.1), ``.aedat4``, N-MNIST ``.bin``, iCub YARP ``data.log``,
  events ``.txt``, ``.npy``/``.npz``, HDF5 ``.h5``/``.hdf5`` (DSEC,
  MVSEC, Prophesee), or an
  in-memory structured array) whole or in bounded chunks; see
  :mod:`snn_fg.events.formats` for the format table, which formats stream, and
  the keyword-only format options.  One module per format family decodes
  (:mod:`~snn_fg.events.eventstream`, :mod:`~snn_fg.events.prophesee`,
  :mod:`~snn_fg.events.yarp`, :mod:`~snn_fg.events.aedat23`,
  :mod:`~snn_fg.events.aedat4`, :mod:`~snn_fg.events.nmnist`,
  :mod:`~snn_fg.events.text_events`, :mod:`~snn_fg.events.numpy_files`).
* :func:`events_to_frame` (model stage 1), :func:`iter_windows` and
  :class:`RecordingWindows` (windows read again on every iteration).
* :func:`image_to_events` / :func:`image_to_frame`: an ESIM-style simulator
  for still images under the paper's described ``shift4`` motion, the iCub's
  ``circle`` microsaccade, or ``paper``, the authors' own BSDS conversion
  (:mod:`snn_fg.events.esim`, :mod:`snn_fg.events.paper_motion`).
* :func:`save_events`: write ``.npy``/``.npz``/EVT2/EVT3/``.es`` atomically
  (:func:`snn_fg.events.writers.encode_es_atis` encodes ATIS streams).
* :mod:`~snn_fg.events.images`: still images read as float images, the
  simulator's input (and the frame-based model's).
"""

from snn_fg.events.core import EVENT_DTYPE, MAX_SENSOR_SIDE, Recording
from snn_fg.events.esim import PixelOptions, image_to_events, image_to_frame, motion_frames
from snn_fg.events.formats import detect_format
from snn_fg.events.frame import EmptyWindowWarning, EventWindow, events_to_frame
from snn_fg.events.io import RecordingStream, iter_recording, open_recording
from snn_fg.events.source import STREAMING_FORMATS
from snn_fg.events.window import RecordingWindows, iter_windows
from snn_fg.events.writers import save_events

__all__ = [
    "EVENT_DTYPE",
    "MAX_SENSOR_SIDE",
    "EmptyWindowWarning",
    "EventWindow",
    "Recording",
    "RecordingStream",
    "RecordingWindows",
    "STREAMING_FORMATS",
    "detect_format",
    "events_to_frame",
    "PixelOptions",
    "image_to_events",
    "image_to_frame",
    "iter_recording",
    "iter_windows",
    "motion_frames",
    "open_recording",
    "save_events",
]
