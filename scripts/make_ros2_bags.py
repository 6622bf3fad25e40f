#!/usr/bin/env python3
"""Write a robimu session as rosbag2 bags with an independent writer.

The test fixtures of `robimu import ros2` (host/cli/tests/fixtures/ros2/)
are made by this script with the `rosbags` package (not by robimu):

    python3 -m venv /tmp/rosbags-venv && /tmp/rosbags-venv/bin/pip install rosbags
    target/debug/robimu simulate --duration 4 --rate 40 --joint-rate 20 --seed 3 --out /tmp/src
    /tmp/rosbags-venv/bin/python scripts/make_ros2_bags.py /tmp/src host/cli/tests/fixtures/ros2

It copies the session (joints.csv, imu.csv, session.toml) to OUT/source and
writes, with header stamps BASE_NS + round(t·1e9) and log times 1 ms later:

* run_mcap/   MCAP storage, one file
* run_db3/    sqlite3 storage, one file (ROS 2 Humble's default)
* run_split/  MCAP storage split in two files at the middle of the session
              (two rosbags bags, their metadata merged into one)
* run_zstd_file/     sqlite3, per-file zstd (`run_zstd_file_0.db3.zstd`)
* run_zstd_message/  MCAP, per-message zstd

Topics: /joint_states (sensor_msgs/msg/JointState, the arm's six joints,
and every 25th sample also a gripper message on the same topic, which the
import skips), /imu/data_raw (sensor_msgs/msg/Imu), /rosout-like
/status (std_msgs/msg/String). Every bag is read back with rosbags' own
reader and checked against the session.
"""

import csv
import shutil
import sys
from pathlib import Path

from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

BASE_NS = 1_700_000_000_123_456_789
JOINTS = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]

TS = get_typestore(Stores.ROS2_HUMBLE)
Time = TS.types["builtin_interfaces/msg/Time"]
Header = TS.types["std_msgs/msg/Header"]
JointState = TS.types["sensor_msgs/msg/JointState"]
Imu = TS.types["sensor_msgs/msg/Imu"]
Quaternion = TS.types["geometry_msgs/msg/Quaternion"]
Vector3 = TS.types["geometry_msgs/msg/Vector3"]
String = TS.types["std_msgs/msg/String"]

import numpy as np  # noqa: E402  (rosbags' own dependency)


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], [[float(x) for x in r] for r in rows[1:]]


def stamp_ns(t):
    # t is a decimal string's float; round to the nearest ns as robimu does.
    return BASE_NS + round(t * 1e9)


def header(ns, frame):
    return Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)


def messages(session):
    """(log time ns, topic, type, message), in log-time order."""
    _, joints = read_csv(session / "joints.csv")
    _, imu = read_csv(session / "imu.csv")
    out = []
    for k, row in enumerate(joints):
        ns = stamp_ns(row[0])
        m = JointState(
            header=header(ns, ""),
            name=list(JOINTS),
            position=np.array(row[1:], dtype=np.float64),
            velocity=np.array([], dtype=np.float64),
            effort=np.array([], dtype=np.float64),
        )
        out.append((ns + 1_000_000, "/joint_states", JointState.__msgtype__, m))
        if k % 25 == 0:
            g = JointState(
                header=header(ns, ""),
                name=["gripper_finger_joint"],
                position=np.array([0.01]),
                velocity=np.array([], dtype=np.float64),
                effort=np.array([], dtype=np.float64),
            )
            out.append((ns + 1_000_000, "/joint_states", JointState.__msgtype__, g))
    zero9 = np.zeros(9, dtype=np.float64)
    for k, row in enumerate(imu):
        ns = stamp_ns(row[0])
        ax, ay, az, gx, gy, gz = row[1:7]
        m = Imu(
            header=header(ns, "imu_link"),
            orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.array([-1.0] + [0.0] * 8),
            angular_velocity=Vector3(x=gx, y=gy, z=gz),
            angular_velocity_covariance=zero9,
            linear_acceleration=Vector3(x=ax, y=ay, z=az),
            linear_acceleration_covariance=zero9,
        )
        out.append((ns + 1_000_000, "/imu/data_raw", Imu.__msgtype__, m))
        if k % 40 == 0:
            out.append((ns + 1_000_000, "/status", String.__msgtype__, String(data=f"ok {k}")))
    out.sort(key=lambda m: m[0])
    return out


def write_bag(path, msgs, storage, compression=None):
    w = Writer(path, version=8, storage_plugin=storage)
    if compression is not None:
        w.set_compression(compression, CompressionFormat.ZSTD)
    with w:
        conns = {}
        for topic, msgtype in [
            ("/joint_states", JointState.__msgtype__),
            ("/imu/data_raw", Imu.__msgtype__),
            ("/status", String.__msgtype__),
        ]:
            conns[topic] = w.add_connection(topic, msgtype, typestore=TS)
        for ns, topic, msgtype, m in msgs:
            w.write(conns[topic], ns, TS.serialize_cdr(m, msgtype))


def write_split(path, msgs):
    """Two single-file bags (first and second half), merged into one bag
    directory whose metadata lists both files in order."""
    half = len(msgs) // 2
    tmp = path.with_name(path.name + ".parts")
    parts = [tmp / f"part{i}" for i in range(2)]
    tmp.mkdir()
    for p, chunk in zip(parts, [msgs[:half], msgs[half:]]):
        write_bag(p, chunk, StoragePlugin.MCAP)
    path.mkdir()
    yaml = YAML(typ="safe")
    metas = [yaml.load((p / "metadata.yaml").read_text())["rosbag2_bagfile_information"] for p in parts]
    files = []
    for i, (p, meta) in enumerate(zip(parts, metas)):
        (src,) = meta["relative_file_paths"]
        name = f"{path.name}_{i}.mcap"
        shutil.move(p / src, path / name)
        f = dict(meta["files"][0])
        f["path"] = name
        files.append(f)
    merged = dict(metas[0])
    merged["relative_file_paths"] = [f["path"] for f in files]
    merged["files"] = files
    merged["message_count"] = sum(m["message_count"] for m in metas)
    start = metas[0]["starting_time"]["nanoseconds_since_epoch"]
    end = max(
        m["starting_time"]["nanoseconds_since_epoch"] + m["duration"]["nanoseconds"] for m in metas
    )
    merged["duration"] = {"nanoseconds": end - start}
    counts = {}
    for m in metas:
        for t in m["topics_with_message_count"]:
            counts[t["topic_metadata"]["name"]] = counts.get(t["topic_metadata"]["name"], 0) + t["message_count"]
    merged["topics_with_message_count"] = [
        dict(t, message_count=counts[t["topic_metadata"]["name"]])
        for t in metas[0]["topics_with_message_count"]
    ]
    yaml.default_flow_style = False
    with open(path / "metadata.yaml", "w") as f:
        yaml.dump({"rosbag2_bagfile_information": merged}, f)
    shutil.rmtree(tmp)


def check(path, msgs):
    """rosbags' reader gives back every message, in order."""
    got = []
    with Reader(path) as r:
        for conn, ns, raw in r.messages():
            got.append((ns, conn.topic, TS.deserialize_cdr(raw, conn.msgtype)))
    assert len(got) == len(msgs), (path, len(got), len(msgs))
    for (ns, topic, m), (ns0, topic0, _, m0) in zip(got, msgs):
        assert (ns, topic) == (ns0, topic0), (path, ns, topic, ns0, topic0)
        if topic == "/imu/data_raw":
            assert m.linear_acceleration.x == m0.linear_acceleration.x
            assert m.angular_velocity.z == m0.angular_velocity.z
        if topic == "/joint_states":
            assert list(m.position) == list(m0.position)


def main():
    session, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    src = out / "source"
    if src.exists():
        shutil.rmtree(src)
    src.mkdir()
    for f in ["joints.csv", "imu.csv", "session.toml"]:
        shutil.copy(session / f, src / f)
    msgs = messages(session)
    bags = {
        "run_mcap": lambda p: write_bag(p, msgs, StoragePlugin.MCAP),
        "run_db3": lambda p: write_bag(p, msgs, StoragePlugin.SQLITE3),
        "run_split": lambda p: write_split(p, msgs),
        "run_zstd_file": lambda p: write_bag(p, msgs, StoragePlugin.SQLITE3, CompressionMode.FILE),
        "run_zstd_message": lambda p: write_bag(p, msgs, StoragePlugin.MCAP, CompressionMode.MESSAGE),
    }
    for name, make in bags.items():
        p = out / name
        if p.exists():
            shutil.rmtree(p)
        make(p)
        if name != "run_zstd_message":
            check(p, msgs)
        size = sum(f.stat().st_size for f in p.iterdir())
        print(f"wrote {p}: {len(msgs)} messages, {size} bytes")


if __name__ == "__main__":
    main()
