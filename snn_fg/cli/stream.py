"""``snn-fg stream``: a recording replayed as a live stream, in real time or
``--speed`` times faster, to ``udp://`` (SPIF packets) or ``dv://`` (a DV
network stream) (:mod:`snn_fg.events.replay`), so that ``snn-fg live`` can be
tried without a camera."""

from __future__ import annotations

import os
import sys
import time

import numpy as np

from ..errors import InputError
from ..events import EVENT_DTYPE, iter_recording
from ..events.replay import SEND_WAIT_S, UdpSender, looped, open_sender, paced, parse_address, recording_from_ms
from .options import add_camera_options, camera_options, number, recording_or_demo, sensor_size, subcommand


def add_stream_command(sub):
    p = subcommand(
        sub,
        "stream",
        description="Replay the recording REC to udp://HOST:PORT (SpiNNaker interface board packets, with "
        "timestamps) or dv://HOST:PORT (a DV network stream served there; pip install -e '.[live]'), in "
        "real time or --speed X faster. Events keep the recording's own timestamps (udp://: modulo 2^32 us), "
        "so that snn-fg compare pairs a live run's windows with snn-fg run's on the same events. The "
        "recording is read whole before the replay starts.",
    )
    p.add_argument(
        "recording",
        metavar="REC",
        help="an event recording (any format snn-fg run reads), or demo: 2 s of the built-in demo scene's events",
    )
    p.add_argument("--to", required=True, metavar="URL", help="udp://HOST:PORT or dv://HOST:PORT")
    p.add_argument("--speed", type=number(float, 0), default=1.0, metavar="X", help="times real time (1)")
    p.add_argument("--loop", type=number(int, 1), default=1, metavar="N", help="play the recording N times (1)")
    p.add_argument(
        "--start-ms",
        type=number(float, 0),
        default=0.0,
        metavar="MS",
        help="each time from MS after the recording's first event (past a start-up burst, which --loop would repeat)",
    )
    p.add_argument("--sensor-size", type=sensor_size, metavar="WxH", help="as snn-fg run (RAW files, arrays)")
    add_camera_options(p)
    p.add_argument("--no-timestamps", action="store_true", help="udp://: events without times (stamped on arrival)")
    p.add_argument(
        "--wait-s",
        type=number(float, 0),
        default=SEND_WAIT_S,
        metavar="S",
        help=f"dv://: seconds the server waits for a reader to connect ({SEND_WAIT_S:g}: a first snn-fg live "
        "compiles its model for up to a minute before it connects, and longer on a busy machine)",
    )
    p.set_defaults(handler=cmd_stream)
    return p


def cmd_stream(args) -> int:
    parse_address(args.to, "--to")  # (a wrong address before the recording is read and warned about)
    source = recording_or_demo(args.recording)
    read = {"sensor_size": args.sensor_size, **camera_options(args)}
    size = iter_recording(source, **read).sensor_size
    parts = looped(lambda: recording_from_ms(source, args.start_ms, **read), args.loop)
    events = np.concatenate(list(parts) or [np.zeros(0, EVENT_DTYPE)])
    if not len(events):
        raise InputError(args.recording, f"no event from --start-ms {args.start_ms:g} on")
    sender = open_sender(args.to, size, timestamps=not args.no_timestamps, wait_s=args.wait_s)
    sender.load(events)
    args.interrupt_note = "the replay stopped"
    t = time.perf_counter()
    try:
        for part in paced([events], args.speed):
            sender.send(part)
    finally:
        end_process = sender.close()
    print(
        f"snn-fg: sent {sender.sent:,} events of {args.recording} to {args.to} in {time.perf_counter() - t:.2f} s "
        f"({(events['t'][-1] - events['t'][0]) / 1e6:.2f} s of events at {args.speed:g}x)"
        + ("; UDP does not tell whether anything received them" if isinstance(sender, UdpSender) else ""),
        file=sys.stdout,
    )
    if end_process:  # (a DV server with a reader still connected: see DvSender.close)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
    return 0
