#!/usr/bin/env python3
"""Reads an acch MCAP recording with the reference Python reader (`mcap`),
every CRC validated, and prints what it found as one JSON line.

Usage: mcap_check.py FILE.mcap [LAYOUT.json]

Two passes: a linear pass (StreamReader: every record, chunk CRCs and the
data-section CRC) and an indexed pass (make_reader: the summary, chunk
indexes and every message of every channel, chunk CRCs). JSON messages are
parsed; every protobuf message is decoded against its own schema's
FileDescriptorSet by the small protobuf reader below (independent of the
Rust encoder: it parses the descriptors and the wire format itself), which
fails on a field its schema does not declare or of another wire type.

With a Foxglove layout, every message path of its panels (`/topic.field[0]`,
`/topic{field=="x"}.field`, `/topic.values[:]`) is resolved against the
recording: its topic must be a channel and, on a JSON or protobuf channel,
its fields must be present in a message and, on a JSON channel, declared in
its JSON schema (a Foxglove viewer checks paths against the schema). Paths
that do not resolve are listed under `layout.unresolved`; a filter no message
matches (no rejected frame in the run) is listed under
`layout.filter_matched_nothing`, its fields checked on every message.
"""
import json
import re
import struct
import sys
from collections import Counter

from mcap.reader import make_reader
from mcap.records import DataEnd, Footer, Message
from mcap.stream_reader import StreamReader


def check(ok, what):
    """An assert that python -O keeps: fails the check, saying what."""
    if not ok:
        sys.exit(f"check failed: {what}")

# descriptor.proto FieldDescriptorProto.Type -> wire type
WIRE = {1: 1, 2: 5, 3: 0, 4: 0, 5: 0, 6: 1, 7: 5, 8: 0, 9: 2, 11: 2, 12: 2,
        13: 0, 14: 0, 15: 5, 16: 1, 17: 0, 18: 0}


def fields(buf):
    """(number, wire type, value) of every field of a message."""
    pos = 0

    def varint():
        nonlocal pos
        v, shift = 0, 0
        while True:
            b = buf[pos]
            pos += 1
            v |= (b & 0x7F) << shift
            if b < 0x80:
                return v
            shift += 7

    while pos < len(buf):
        k = varint()
        number, wire = k >> 3, k & 7
        if wire == 0:
            value = varint()
        elif wire == 1:
            value = buf[pos:pos + 8]
            pos += 8
        elif wire == 2:
            n = varint()
            value = buf[pos:pos + n]
            pos += n
        elif wire == 5:
            value = buf[pos:pos + 4]
            pos += 4
        else:
            raise ValueError(f"wire type {wire}")
        if pos > len(buf):
            raise ValueError("field runs past the end")
        yield number, wire, value


def descriptors(fds):
    """Message full name -> {number: (name, type, repeated, type name)} and
    the set of enum full names, from a FileDescriptorSet."""
    messages, enums = {}, set()

    def message(prefix, d):
        name = None
        out = {}
        nested = []
        for n, _, v in fields(d):
            if n == 1:
                name = v.decode()
            elif n == 2:
                f = {k: val for k, _, val in fields(v)}
                out[f[3]] = (f[1].decode(), f[5], f.get(4) == 3,
                             f.get(6, b"").decode().lstrip("."))
            elif n == 3:
                nested.append(v)
            elif n == 4:
                e = {k: val for k, _, val in fields(v)}
                enums.add(f"{prefix}{name}.{e[1].decode()}")
        messages[f"{prefix}{name}"] = out
        for v in nested:
            message(f"{prefix}{name}.", v)

    for n, _, file in fields(fds):
        check(n == 1, 'n == 1')
        f = list(fields(file))
        package = next((v.decode() for k, _, v in f if k == 2), "")
        for k, _, v in f:
            if k == 4:
                message(f"{package}." if package else "", v)
    return messages, enums


def decode(messages, enums, name, buf):
    """A message as a dict (repeated fields as lists; bytes as their length)."""
    out = {}
    schema = messages[name]
    for number, wire, value in fields(buf):
        if number not in schema:
            raise ValueError(f"{name}: field {number} not in its schema")
        fname, ftype, repeated, tname = schema[number]
        if repeated and wire == 2 and WIRE[ftype] != 2:
            fmt = {1: "<d", 5: "<i", 7: "<I"}.get(ftype)
            size = struct.calcsize(fmt)
            items = [struct.unpack(fmt, value[i:i + size])[0]
                     for i in range(0, len(value), size)]
            out.setdefault(fname, []).extend(items)
            continue
        if WIRE[ftype] != wire:
            raise ValueError(f"{name}.{fname}: wire type {wire}, schema type {ftype}")
        if ftype == 1:
            v = struct.unpack("<d", value)[0]
        elif ftype == 7:
            v = struct.unpack("<I", value)[0]
        elif ftype == 9:
            v = value.decode()
        elif ftype == 12:
            v = len(value)
        elif ftype == 11:
            v = decode(messages, enums, tname, value)
        elif ftype == 14:
            check(tname in enums, tname)
            v = value
        elif ftype == 8:
            v = bool(value)
        else:
            v = value
        if repeated:
            out.setdefault(fname, []).append(v)
        else:
            out[fname] = v
    return out


PATH = re.compile(r"^(/[A-Za-z0-9_/]+)((?:\{[^}]*\})?)((?:\.[A-Za-z0-9_]+|\[[0-9:]*\])*)$")


def resolves(sample, filters, rest):
    """Whether the field path `rest` (".a.b[0]", "[:]") exists in `sample`."""
    for part in re.findall(r"\.[A-Za-z0-9_]+|\[[0-9:]*\]", rest):
        if part.startswith("."):
            if not isinstance(sample, dict) or part[1:] not in sample:
                return False
            sample = sample[part[1:]]
        elif part == "[:]":
            if not isinstance(sample, list) or not sample:
                return False
            sample = sample[0]
        else:
            i = int(part[1:-1])
            if not isinstance(sample, list) or len(sample) <= i:
                return False
            sample = sample[i]
    return sample is not None


def schema_has(schema, rest):
    """Whether the JSON schema declares the field path `rest`: a Foxglove
    viewer validates message paths against the schema, not the data."""
    for part in re.findall(r"\.[A-Za-z0-9_]+|\[[0-9:]*\]", rest):
        if part.startswith("."):
            props = schema.get("properties", {})
            if part[1:] in props:
                schema = props[part[1:]]
            elif isinstance(schema.get("additionalProperties"), dict):
                schema = schema["additionalProperties"]
            else:
                return False
        else:
            if schema.get("type") != "array":
                return False
            schema = schema.get("items", {})
        # One type name a field: Foxglove rejects ["number", "null"].
        if not isinstance(schema.get("type"), str):
            return False
    return True


def check_layout(path, samples, topics, json_schemas):
    """Every message path in the layout's panels, resolved."""
    layout = json.load(open(path))
    found, unresolved, unmatched = [], [], []

    def walk(v):
        if isinstance(v, dict):
            for k, x in v.items():
                # Topic names as keys (e.g. the annotation topics of an image panel).
                if isinstance(k, str) and k.startswith("/"):
                    found.append(k)
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v.startswith("/"):
            found.append(v)

    walk(layout["configById"])
    for p in found:
        m = PATH.match(p)
        if not m:
            unresolved.append(p)
            continue
        topic, flt, rest = m.groups()
        if topic not in topics:
            unresolved.append(p)
            continue
        msgs = samples.get(topic, [])
        field_filter = re.findall(r'([A-Za-z0-9_]+)==("?)([^"}]*)\2', flt)
        if field_filter:
            key, _, want = field_filter[0]
            if not all(isinstance(x, dict) and key in x for x in msgs):
                unresolved.append(p + " (filter field missing)")
                continue
            matched = [x for x in msgs if str(x.get(key)) == want]
            # A run with no rejected frame still has the fields to plot.
            if matched:
                msgs = matched
            else:
                unmatched.append(p)
        if rest and not any(resolves(x, flt, rest) for x in msgs):
            unresolved.append(p)
        elif topic in json_schemas and not schema_has(json_schemas[topic], rest):
            unresolved.append(p + " (not in its JSON schema)")
    return {"paths": len(found), "topics": sorted({PATH.match(p).group(1) for p in found
                                                   if PATH.match(p)}),
            "unresolved": unresolved, "filter_matched_nothing": unmatched}


def main(path, layout=None):
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
    decoded = Counter()
    schemas = {}
    json_schemas = {}
    samples = {}
    overlay = Counter()
    child_frames = set()
    calibration = None
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        pools = {}
        for ch in summary.channels.values():
            s = summary.schemas[ch.schema_id]
            schemas[ch.topic] = [s.name, s.encoding, ch.message_encoding]
            if s.encoding == "protobuf":
                check(ch.message_encoding == "protobuf", ch)
                check(len(s.data) > 0, s.name)
                pools[s.id] = descriptors(s.data)
                check(s.name in pools[s.id][0], f"{s.name} not in its own descriptors")
            elif s.encoding == "jsonschema":
                json_schemas[ch.topic] = json.loads(s.data)
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] += 1
            if channel.message_encoding == "json":
                v = json.loads(message.data)
            else:
                messages, enums = pools[schema.id]
                v = decode(messages, enums, schema.name, message.data)
                decoded[channel.topic] += 1
                if schema.name == "foxglove.ImageAnnotations":
                    for p in v.get("points", []):
                        overlay[f"{channel.topic} points type {p.get('type', 0)}"] += 1
                    overlay[f"{channel.topic} texts"] += len(v.get("texts", []))
                elif schema.name == "foxglove.FrameTransforms":
                    child_frames.update(t["child_frame_id"] for t in v.get("transforms", []))
                elif schema.name == "foxglove.CameraCalibration" and calibration is None:
                    calibration = v
            # A few messages per topic to resolve the layout's paths in.
            keep = samples.setdefault(channel.topic, [])
            if len(keep) < 400:
                keep.append(v)
        statistics = dict(summary.statistics.channel_message_counts)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    by_id = {ch.id: ch.topic for ch in summary.channels.values()}
    out = {
        "counts": counts,
        "decoded": decoded,
        "statistics": {by_id[k]: v for k, v in statistics.items()},
        "schemas": schemas,
        "linear_messages": linear["messages"],
        "footer": linear["footer"],
        "data_section_crc": data_end_crc,
        "metadata": metadata,
        "overlay": overlay,
        "child_frames": sorted(child_frames),
        "calibration": calibration,
    }
    if layout:
        out["layout"] = check_layout(layout, samples, set(schemas), json_schemas)
    print(json.dumps(out))


if __name__ == "__main__":
    main(*sys.argv[1:3])
