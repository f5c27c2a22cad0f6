#!/usr/bin/env python3
"""Stretch a simulated flight into a long one: its laps flown again and
again (every message re-stamped by a whole number of laps) until the
recording holds FRAMES camera frames. /tf_static and /map are written once.
The benchmark of memory and time against flight length (BENCHMARKS.md) runs
`postflight run` on these.

Written with the mcap package, independently of postflight's reader. Only
messages whose CDR payload starts with a std_msgs/Header are re-stamped
(bytes 4..12, little-endian); the others keep their payload.

Run: .venv/bin/python scripts/long_flight.py SIM/flight.mcap FRAMES OUT.mcap
"""

import struct
import sys

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

ONCE = {"/tf_static", "/map"}
HEADERLESS = {"std_msgs/msg/Float64"}
IMAGE = "sensor_msgs/msg/CompressedImage"


def restamp(data, shift_ns):
    """The payload with its header stamp moved by shift_ns."""
    sec, nanosec = struct.unpack_from("<iI", data, 4)
    t = sec * 10**9 + nanosec + shift_ns
    return data[:4] + struct.pack("<iI", t // 10**9, t % 10**9) + data[12:]


def main():
    src, frames, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    with open(src, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = list(reader.iter_messages(log_time_order=True))
    lap_images = sum(1 for s, c, _ in messages if s.name == IMAGE)
    stamps = [m.log_time for s, c, m in messages if c.topic not in ONCE]
    image_times = [m.log_time for s, c, m in messages if s.name == IMAGE]
    # One lap later: the flight's span plus one frame interval.
    lap_ns = stamps[-1] - stamps[0] + (image_times[1] - image_times[0])
    with open(out, "wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="postflight long_flight.py")
        schema_ids = {
            sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()
        }
        channel_ids = {
            cid: writer.register_channel(c.topic, c.message_encoding, schema_ids[c.schema_id], c.metadata)
            for cid, c in summary.channels.items()
        }
        written, lap, last = 0, 0, 0
        for schema, channel, m in messages:
            if channel.topic == "/tf_static":
                writer.add_message(channel_ids[channel.id], m.log_time, m.data, m.publish_time)
        while written < frames:
            shift = lap * lap_ns
            for schema, channel, m in messages:
                if channel.topic in ONCE:
                    continue
                if schema.name == IMAGE:
                    if written == frames:
                        break
                    written += 1
                data = m.data if schema.name in HEADERLESS else restamp(m.data, shift)
                last = m.log_time + shift
                writer.add_message(channel_ids[channel.id], last, data, m.publish_time + shift)
            lap += 1
        for schema, channel, m in messages:
            if channel.topic == "/map":
                # Half a second after the last message, as the simulator logs it.
                at = last + 500_000_000
                writer.add_message(channel_ids[channel.id], at, restamp(m.data, at - m.log_time), at)
        writer.finish()
    print(f"{out}: {written} frames in {lap} laps of {lap_images} ({lap_ns / 1e9:.0f} s each)")


if __name__ == "__main__":
    main()
