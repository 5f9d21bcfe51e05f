#!/usr/bin/env python3
"""A ROS 2 arm publishing its camera pose the rmw_zenoh way, with no code of
acch: rosbags serialises geometry_msgs/msg/PoseStamped (or TransformStamped),
the key, attachment and liveliness token follow rmw_zenoh's source.

    publish_arm.py --listen tcp/127.0.0.1:PORT --topic /arm/camera_pose \
        --seconds 20 --rate 100

Pose k (k = 0, 1, ...) is the camera at (0.01 k, 0.2, 0.5) m, turned by
0.5 k degrees about z: a test knows every pose it may see.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import zenoh
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_JAZZY)


def pose(k: int):
    """Translation and quaternion (x, y, z, w) of pose k."""
    half = math.radians(0.5 * k) / 2
    return (0.01 * k, 0.2, 0.5), (0.0, 0.0, math.sin(half), math.cos(half))


def message(kind: str, k: int, stamp_ns: int):
    (x, y, z), (qx, qy, qz, qw) = pose(k)
    Time = TS.types['builtin_interfaces/msg/Time']
    Header = TS.types['std_msgs/msg/Header']
    Quaternion = TS.types['geometry_msgs/msg/Quaternion']
    header = Header(stamp=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id='base_link')
    q = Quaternion(x=qx, y=qy, z=qz, w=qw)
    if kind == 'pose_stamped':
        Pose = TS.types['geometry_msgs/msg/Pose']
        Point = TS.types['geometry_msgs/msg/Point']
        msg = TS.types['geometry_msgs/msg/PoseStamped'](header=header, pose=Pose(position=Point(x=x, y=y, z=z), orientation=q))
        return msg, 'geometry_msgs/msg/PoseStamped'
    Transform = TS.types['geometry_msgs/msg/Transform']
    Vector3 = TS.types['geometry_msgs/msg/Vector3']
    msg = TS.types['geometry_msgs/msg/TransformStamped'](
        header=header, child_frame_id='camera_optical_frame',
        transform=Transform(translation=Vector3(x=x, y=y, z=z), rotation=q))
    return msg, 'geometry_msgs/msg/TransformStamped'


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--listen', required=True)
    p.add_argument('--topic', default='/arm/camera_pose')
    p.add_argument('--type', choices=['pose_stamped', 'transform_stamped'], default='pose_stamped')
    p.add_argument('--domain', type=int, default=0)
    p.add_argument('--seconds', type=float, default=20.0)
    p.add_argument('--rate', type=float, default=100.0)
    p.add_argument('--out', help='JSON file: how many poses were published')
    args = p.parse_args()

    conf = zenoh.Config()
    conf.insert_json5('mode', '"peer"')
    conf.insert_json5('listen/endpoints', json.dumps([args.listen]))
    conf.insert_json5('scouting/multicast/enabled', 'false')
    session = zenoh.open(conf)
    _, ros_type = message(args.type, 0, 0)
    pkg, _, name = ros_type.split('/')
    dds = f'{pkg}::msg::dds_::{name}_'
    type_hash = TS.hash_rihs01(ros_type)
    key = f'{args.domain}/{args.topic.strip("/")}/{dds}/{type_hash}'
    zid = str(session.zid())
    mangled = args.topic.replace('/', '%')
    token = session.liveliness().declare_token(
        f'@ros2_lv/{args.domain}/{zid}/0/0/NN/%/%/arm')
    pub_token = session.liveliness().declare_token(
        f'@ros2_lv/{args.domain}/{zid}/0/1/MP/%/%/arm/{mangled}/{dds}/{type_hash}/1:2:1,10:,:,:,,')
    publisher = session.declare_publisher(key)
    gid = os.urandom(16)
    k, t0 = 0, time.monotonic()
    try:
        while time.monotonic() - t0 < args.seconds:
            now = time.time_ns()
            msg, _ = message(args.type, k, now)
            payload = bytes(TS.serialize_cdr(msg, ros_type))
            # rmw_zenoh's attachment: sequence (from 1), source time, GID.
            attachment = (k + 1).to_bytes(8, 'little', signed=True) + now.to_bytes(8, 'little', signed=True) + bytes([16]) + gid
            publisher.put(payload, attachment=attachment)
            k += 1
            time.sleep(max(0.0, t0 + k / args.rate - time.monotonic()))
    except KeyboardInterrupt:
        pass  # the test is done with the arm
    if args.out:
        with open(args.out, 'w') as f:
            json.dump({'published': k, 'key': key}, f)
    pub_token.undeclare()
    token.undeclare()
    session.close()
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
