#!/usr/bin/env python3
"""Independent check of what acch-ros2 puts on the wire and into bags.

Uses no code of ours: eclipse-zenoh (1.10.x) to receive, rosbags (0.11.9) for
type hashes, CDR and rosbag2, and rmw_zenoh's formats re-implemented here from
its source (liveliness_utils.cpp, attachment_helpers.cpp).

    check_ros2.py --connect tcp/127.0.0.1:7447 --domain 0 \
        --expect-topic /acch/fruitbox/seed:geometry_msgs/msg/PoseWithCovarianceStamped \
        --min-samples 5 --timeout 20 --bag /tmp/demo_bag --out result.json

Exit code 0 only if there are no errors, and every expected topic got at least
--min-samples samples of its type and has a matching MP (publisher) token.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import re
import sys
import threading
import time
from pathlib import Path

import numpy as np
import zenoh
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

ADMIN_SPACE = '@ros2_lv'
HUMBLE_HASH = 'TypeHashNotSupported'
HASH_RE = re.compile(r'RIHS01_[0-9a-f]{64}')
ZID_RE = re.compile(r'[0-9a-f]{1,32}')
DDS_RE = re.compile(r'((?:[A-Za-z0-9_]+::)+)dds_::([A-Za-z0-9_]+)_')
NAME_RE = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
NUMBER_RE = re.compile(r'[0-9]+')
# rmw_zenoh's keyexpr_to_qos lookup tables (rmw/types.h values it accepts).
QOS_ENUMS = {
    'reliability': {'0', '1', '2', '3'},
    'durability': {'0', '1', '2', '3'},
    'history': {'0', '1', '2', '3'},
    'liveliness': {'0', '1', '3', '4', '5'},
}
LEGACY_LABELS = (b'sequence_number', b'source_timestamp', b'source_gid')

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def ros_type(dds: str) -> str | None:
    """geometry_msgs::msg::dds_::Pose_ -> geometry_msgs/msg/Pose."""
    m = DDS_RE.fullmatch(dds)
    return f'{m[1][:-2].replace("::", "/")}/{m[2]}' if m else None


def demangle(s: str) -> str:
    return s.replace('%', '/')


def dump(value, max_array: int):
    """A JSON-able copy of a rosbags message, field by field."""
    if dataclasses.is_dataclass(value):
        return {
            f.name: dump(getattr(value, f.name), max_array)
            for f in dataclasses.fields(value)
            if not f.name.startswith('__')
        }
    if isinstance(value, np.ndarray):
        if value.size > max_array:
            return {
                'length': int(value.size),
                'sha256': hashlib.sha256(value.tobytes()).hexdigest(),
                'head': value[:16].tolist(),
            }
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [dump(v, max_array) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def parse_attachment(b: bytes) -> dict:
    """rmw_zenoh's attachment: 33 bytes (current) or 77 (legacy, labelled)."""
    if len(b) == 33:
        if b[16] != 0x10:
            raise ValueError(f'GID length prefix {b[16]:#x}, expected 0x10')
        fields, fmt = (b[0:8], b[8:16], b[17:33]), 'current'
    elif len(b) == 77:
        pos, parts = 0, []
        for label, size in zip(LEGACY_LABELS, (8, 8, 17)):
            if b[pos] != len(label) or b[pos + 1 : pos + 1 + len(label)] != label:
                raise ValueError(f'legacy label {label.decode()} missing at byte {pos}')
            pos += 1 + len(label)
            parts.append(b[pos : pos + size])
            pos += size
        if parts[2][0] != 0x10:
            raise ValueError(f'GID length prefix {parts[2][0]:#x}, expected 0x10')
        fields, fmt = (parts[0], parts[1], parts[2][1:]), 'legacy'
    else:
        raise ValueError(f'{len(b)} bytes, expected 33 (current) or 77 (legacy)')
    return {
        'format': fmt,
        'sequence': int.from_bytes(fields[0], 'little', signed=True),
        'source_timestamp_ns': int.from_bytes(fields[1], 'little', signed=True),
        'gid': fields[2].hex(),
    }


def parse_qos(q: str) -> dict:
    """The QoS chunk with exactly the component counts rmw_zenoh writes."""
    groups = q.split(':')
    if len(groups) != 6:
        raise ValueError(f'{len(groups)} ":" groups, expected 6')
    parts = [g.split(',') for g in groups]
    counts = [len(p) for p in parts]
    if counts != [1, 1, 2, 2, 2, 3]:
        raise ValueError(f'"," components per group {counts}, expected [1, 1, 2, 2, 2, 3]')
    out = {
        'reliability': parts[0][0],
        'durability': parts[1][0],
        'history': parts[2][0],
        'depth': parts[2][1],
        'deadline': parts[3],
        'lifespan': parts[4],
        'liveliness': parts[5][0],
        'liveliness_lease': parts[5][1:],
    }
    for name, allowed in QOS_ENUMS.items():
        if out[name] and out[name] not in allowed:
            raise ValueError(f'{name} {out[name]!r} is not one rmw_zenoh accepts {sorted(allowed)}')
    for n in [out['depth'], *out['deadline'], *out['lifespan'], *out['liveliness_lease']]:
        if n and not NUMBER_RE.fullmatch(n):
            raise ValueError(f'{n!r} is not a decimal number')
    return out


def check_hash(ros: str | None, h: str, distro: str) -> str | None:
    """An error message if `h` is not the right hash of type `ros`."""
    if distro == 'humble':
        return None if h == HUMBLE_HASH else f'hash {h}, Humble expects {HUMBLE_HASH}'
    if not HASH_RE.fullmatch(h):
        return f'hash {h!r} is not RIHS01_ + 64 hex digits'
    try:
        want = TYPESTORE.hash_rihs01(ros)
    except Exception as e:  # unknown type
        return f'rosbags cannot hash {ros}: {e}'
    return None if h == want else f'hash {h} != rosbags {want} for {ros}'


def parse_token(key: str, domain: int, distro: str) -> tuple[dict, list[str]]:
    """A liveliness token field by field, per rmw_zenoh's Entity::make."""
    parts = key.split('/')
    t: dict = {'key': key}
    errs: list[str] = []
    if len(parts) < 9 or any(p == '' for p in parts):
        return t, [f'{len(parts)} parts (need >= 9, none empty)']
    names = ['admin_space', 'domain', 'zid', 'nid', 'eid', 'kind', 'enclave', 'namespace', 'node']
    t.update(zip(names, parts))
    if t['admin_space'] != ADMIN_SPACE:
        errs.append(f'admin space {t["admin_space"]!r}')
    if t['domain'] != str(domain):
        errs.append(f'domain {t["domain"]!r}, expected {domain}')
    if not ZID_RE.fullmatch(t['zid']):
        errs.append(f'zid {t["zid"]!r} is not lowercase hex of 1-32 digits')
    for f in ('nid', 'eid'):
        if not NUMBER_RE.fullmatch(t[f]):
            errs.append(f'{f} {t[f]!r} is not a decimal number')
    if t['enclave'] != '%':
        errs.append(f'enclave {t["enclave"]!r}, expected "%" (the default "/")')
    ns = demangle(t['namespace'])
    if not (ns == '/' or (ns.startswith('/') and all(NAME_RE.fullmatch(x) for x in ns[1:].split('/')))):
        errs.append(f'namespace {ns!r} is not a valid absolute ROS namespace')
    t['namespace_demangled'] = ns
    if not NAME_RE.fullmatch(t['node']):
        errs.append(f'node name {t["node"]!r} is not valid')
    kind = t['kind']
    if kind == 'NN':
        if len(parts) != 9:
            errs.append(f'node token has {len(parts)} parts, expected 9')
        if t['nid'] != t['eid']:
            errs.append('a node token repeats its node id as entity id')
    elif kind in ('MP', 'MS', 'SS', 'SC'):
        if len(parts) != 13:
            return t, [*errs, f'{kind} token has {len(parts)} parts, expected 13']
        t.update(zip(['topic', 'dds_type', 'type_hash', 'qos'], parts[9:]))
        topic = demangle(t['topic'])
        t['topic_demangled'] = topic
        if not (topic.startswith('/') and all(NAME_RE.fullmatch(x) for x in topic[1:].split('/'))):
            errs.append(f'topic {topic!r} is not a valid fully qualified name')
        t['ros_type'] = ros_type(t['dds_type'])
        if t['ros_type'] is None:
            errs.append(f'dds type {t["dds_type"]!r} is not pkg::msg::dds_::Type_')
        elif e := check_hash(t['ros_type'], t['type_hash'], distro):
            errs.append(e)
        try:
            t['qos_parsed'] = parse_qos(t['qos'])
        except ValueError as e:
            errs.append(f'qos {t["qos"]!r}: {e}')
    else:
        errs.append(f'entity kind {kind!r} not in NN/MP/MS/SS/SC')
    return t, errs


class Collector:
    """Receives every data sample under <domain>/**."""

    def __init__(self, args):
        self.args = args
        self.lock = threading.Lock()
        self.topics: dict[str, dict] = {}
        self.error_counts: dict[str, int] = {}  # insertion-ordered
        self.last_seq: dict[str, int] = {}
        self.lost: dict[str, int] = {}  # samples skipped in a publisher's sequence

    def error(self, msg: str):
        """Records an error once, counting repeats (one per sample is common)."""
        with self.lock:
            self.error_counts[msg] = self.error_counts.get(msg, 0) + 1

    def errors(self) -> list[str]:
        with self.lock:
            return [m if n == 1 else f'{m} ({n} samples)' for m, n in self.error_counts.items()]

    def on_sample(self, sample):
        key = str(sample.key_expr)
        parts = key.split('/')
        if len(parts) < 4:
            return self.error(f'data key {key!r} has fewer than 4 chunks')
        domain, dds, h = parts[0], parts[-2], parts[-1]
        topic = '/' + '/'.join(parts[1:-2])
        ros = ros_type(dds)
        if domain != str(self.args.domain):
            self.error(f'{key}: domain {domain!r}')
        if ros is None:
            return self.error(f'{key}: dds type {dds!r} is not pkg::msg::dds_::Type_')
        if e := check_hash(ros, h, self.args.distro):
            self.error(f'{key}: {e}')
        payload = sample.payload.to_bytes()
        entry = {'key': key, 'bytes': len(payload)}
        att = sample.attachment
        if att is None:
            self.error(f'{topic}: sample without attachment (rmw_zenoh drops it)')
        else:
            try:
                a = parse_attachment(att.to_bytes())
                entry['attachment'] = a
                if a['format'] != self.args.attachment:
                    self.error(f'{topic}: {a["format"]} attachment, expected {self.args.attachment}')
                with self.lock:
                    prev = self.last_seq.get(a['gid'])
                    self.last_seq[a['gid']] = a['sequence']
                if prev is not None and a['sequence'] <= prev:
                    self.error(f'{topic}: sequence {a["sequence"]} after {prev} (gid {a["gid"]})')
                elif prev is not None:
                    # A forward gap is a sample zenoh dropped under load
                    # (congestion control Drop, as rmw_zenoh's KEEP_LAST):
                    # counted, not a format error.
                    with self.lock:
                        self.lost[topic] = self.lost.get(topic, 0) + a['sequence'] - prev - 1
            except ValueError as e:
                self.error(f'{topic}: attachment: {e}')
        try:
            msg = TYPESTORE.deserialize_cdr(payload, ros)
            entry['message'] = dump(msg, self.args.max_array)
            # rosbags re-encoding what it decoded must give the same bytes.
            if TYPESTORE.serialize_cdr(msg, ros) != payload:
                self.error(f'{topic}: payload is not byte-identical to rosbags serialize_cdr')
        except Exception as e:
            self.error(f'{topic}: rosbags cannot deserialize {ros}: {e!r}')
        with self.lock:
            t = self.topics.setdefault(topic, {'type': ros, 'key': key, 'samples': []})
            t['samples'].append(entry)
        if t['type'] != ros:
            self.error(f'{topic}: types {t["type"]} and {ros} on one topic')

    def counts(self) -> dict[str, int]:
        with self.lock:
            return {k: len(v['samples']) for k, v in self.topics.items()}


def query_tokens(session, domain: int) -> list[str]:
    replies = session.liveliness().get(f'{ADMIN_SPACE}/{domain}/**', timeout=3.0)
    return [str(r.ok.key_expr) for r in replies if r.ok is not None]


def read_bag(path: Path, max_array: int, errors: list[str]) -> dict:
    """Every message of a rosbag2 bag, via rosbags' Reader. Bags always carry
    the RIHS01 hash (rosbag2 metadata v9), whatever the wire distro."""
    out: dict = {'path': str(path), 'topics': {}}
    with Reader(path) as reader:
        out['message_count'] = reader.message_count
        out['ros_distro'] = reader.ros_distro
        for c in reader.connections:
            t = out['topics'].setdefault(c.topic, {'type': c.msgtype, 'count': 0, 'messages': []})
            t['metadata_count'] = c.msgcount
            t['digest'] = c.digest
            if e := check_hash(c.msgtype, c.digest, 'jazzy'):
                errors.append(f'bag {c.topic}: {e}')
            want_def, _ = TYPESTORE.generate_msgdef(c.msgtype, ros_version=2)
            if c.msgdef.data.strip() != want_def.strip():
                errors.append(f'bag {c.topic}: schema differs from rosbags generate_msgdef')
            qos = c.ext.offered_qos_profiles
            t['offered_qos_profiles'] = [
                {'history': q.history.name, 'depth': q.depth, 'reliability': q.reliability.name,
                 'durability': q.durability.name} for q in qos
            ]
            if not qos:
                errors.append(f'bag {c.topic}: no offered_qos_profiles')
        for c, stamp, raw in reader.messages(connections=reader.connections):
            t = out['topics'][c.topic]
            t['count'] += 1
            msg = TYPESTORE.deserialize_cdr(raw, c.msgtype)
            t['messages'].append({'log_time_ns': stamp, 'message': dump(msg, max_array)})
        for name, t in out['topics'].items():
            if t['count'] != t['metadata_count']:
                errors.append(f'bag {name}: {t["count"]} messages, metadata.yaml says {t["metadata_count"]}')
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--connect', action='append', required=True, help='zenoh endpoint, e.g. tcp/127.0.0.1:7447')
    p.add_argument('--mode', choices=['peer', 'client'], default='peer')
    p.add_argument('--domain', type=int, default=0)
    p.add_argument('--expect-topic', action='append', default=[], metavar='TOPIC:TYPE')
    p.add_argument('--min-samples', type=int, default=1)
    p.add_argument('--timeout', type=float, default=20.0, help='seconds to wait for samples (and the bag)')
    p.add_argument('--distro', choices=['jazzy', 'humble'], default='jazzy')
    p.add_argument('--attachment', choices=['current', 'legacy'], default='current')
    p.add_argument('--max-array', type=int, default=4096, help='longer arrays are dumped as length + sha256')
    p.add_argument('--bag', type=Path, help='rosbag2 directory to read once its metadata.yaml exists')
    p.add_argument('--out', type=Path, required=True)
    args = p.parse_args()

    expected = {}
    for spec in args.expect_topic:
        topic, sep, ty = spec.partition(':')
        if not sep:
            p.error(f'--expect-topic {spec!r}: want TOPIC:TYPE')
        expected[topic] = ty

    conf = zenoh.Config()
    conf.insert_json5('mode', json.dumps(args.mode))
    conf.insert_json5('connect/endpoints', json.dumps(args.connect))
    conf.insert_json5('scouting/multicast/enabled', 'false')
    session = zenoh.open(conf)
    collector = Collector(args)
    sub = session.declare_subscriber(f'{args.domain}/**', collector.on_sample)

    deadline = time.monotonic() + args.timeout
    keys = set(query_tokens(session, args.domain))
    while time.monotonic() < deadline:
        counts = collector.counts()
        if all(counts.get(t, 0) >= args.min_samples for t in expected):
            break
        time.sleep(0.1)
    keys |= set(query_tokens(session, args.domain))
    sub.undeclare()

    errors = collector.errors()
    tokens = []
    for key in sorted(keys):
        tok, errs = parse_token(key, args.domain, args.distro)
        tok['errors'] = errs
        tokens.append(tok)
        errors.extend(f'token {key}: {e}' for e in errs)

    counts = collector.counts()
    for topic, ty in expected.items():
        got = collector.topics.get(topic)
        if counts.get(topic, 0) < args.min_samples:
            errors.append(f'{topic}: {counts.get(topic, 0)} samples, expected >= {args.min_samples}')
        if got and got['type'] != ty:
            errors.append(f'{topic}: type {got["type"]}, expected {ty}')
        if not any(t.get('kind') == 'MP' and t.get('topic_demangled') == topic and t.get('ros_type') == ty
                   for t in tokens):
            errors.append(f'{topic}: no MP token for {ty}')

    bag = None
    if args.bag:
        while not (args.bag / 'metadata.yaml').exists() and time.monotonic() < deadline + 10:
            time.sleep(0.2)
        try:
            bag = read_bag(args.bag, args.max_array, errors)
            # Every live sample should be in the bag when the publisher recorded it.
            for topic, t in collector.topics.items():
                in_bag = {json.dumps(m['message'], sort_keys=True) for m in bag['topics'].get(topic, {}).get('messages', [])}
                live = [json.dumps(s['message'], sort_keys=True) for s in t['samples'] if 'message' in s]
                t['live_in_bag'] = sum(m in in_bag for m in live)
        except Exception as e:
            errors.append(f'bag {args.bag}: {e!r}')
    session.close()

    formats: dict[str, int] = {}
    for t in collector.topics.values():
        for smp in t['samples']:
            f = smp.get('attachment', {}).get('format', 'none or unreadable')
            formats[f] = formats.get(f, 0) + 1
    result = {
        'ok': not errors,
        'errors': errors,
        'counts': counts,
        'lost': collector.lost,
        'attachment_formats': formats,
        'topics': collector.topics,
        'tokens': tokens,
        'bag': bag,
    }
    args.out.write_text(json.dumps(result, indent=1))
    for e in errors[:20]:
        print(f'error: {e}', file=sys.stderr)
    print(f'{"OK" if not errors else "FAILED"}: {counts}, {len(tokens)} tokens, {len(errors)} errors')
    return 0 if not errors else 1


if __name__ == '__main__':
    sys.exit(main())
