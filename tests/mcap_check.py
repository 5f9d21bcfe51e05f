#!/usr/bin/env python3
"""Reads an acch MCAP recording with the reference Python reader (`mcap`),
every CRC validated, and prints what it found as one JSON line.

Usage: mcap_check.py FILE.mcap

Two passes: a linear pass (StreamReader: every record, chunk CRCs and the
data-section CRC) and an indexed pass (make_reader: the summary, chunk
indexes and every message of every channel, chunk CRCs). JSON messages are
parsed; protobuf messages are checked for their schema's encoding and a
non-empty FileDescriptorSet.
"""
import json
import sys
from collections import Counter

from mcap.reader import make_reader
from mcap.records import DataEnd, Footer, Message
from mcap.stream_reader import StreamReader


def main(path):
    linear = Counter()
    data_end_crc = None
    with open(path, "rb") as f:
        for record in StreamReader(f, validate_crcs=True).records:
            if isinstance(record, Message):
                linear["messages"] += 1
            elif isinstance(record, DataEnd):
                data_end_crc = record.data_section_crc
            elif isinstance(record, Footer):
                linear["footer"] += 1
    counts = Counter()
    schemas = {}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        for ch in summary.channels.values():
            s = summary.schemas[ch.schema_id]
            schemas[ch.topic] = [s.name, s.encoding, ch.message_encoding]
            if s.encoding == "protobuf":
                assert ch.message_encoding == "protobuf", ch
                assert len(s.data) > 0, s.name
            elif s.encoding == "jsonschema":
                json.loads(s.data)
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] += 1
            if channel.message_encoding == "json":
                json.loads(message.data)
        statistics = dict(summary.statistics.channel_message_counts)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    by_id = {ch.id: ch.topic for ch in summary.channels.values()}
    print(json.dumps({
        "counts": counts,
        "statistics": {by_id[k]: v for k, v in statistics.items()},
        "schemas": schemas,
        "linear_messages": linear["messages"],
        "footer": linear["footer"],
        "data_section_crc": data_end_crc,
        "metadata": metadata,
    }))


if __name__ == "__main__":
    main(sys.argv[1])
