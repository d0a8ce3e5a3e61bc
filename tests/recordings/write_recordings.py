#!/usr/bin/python3
"""Writes a KITTI-layout sequence as recordings, for the recording readers' tests.

    write_recordings.py KITTI_DIR OUT_DIR [--frames N] [--stamp0 S]

Writes into OUT_DIR:
  poses.tum            the KITTI poses with the scans' stamps (t = stamp0 + 0.1 s * index)
  street.bag           ROS 1 bag, uncompressed     } written by Debian's python3-rosbag
  street_bz2.bag       ROS 1 bag, bz2 chunks       } (an independent writer); PointCloud2 with
  street_lz4.bag       ROS 1 bag, lz4 chunks       } x y z intensity float32, ring uint16,
                                                     t uint32 ns, point_step padded to 32
  street_db3/          ROS 2 bag: metadata.yaml + street_db3_0.db3 (python3's sqlite3 module,
                       rosbag2's humble schema); organised clouds (height 2, a NaN pad point when
                       the count is odd), x y z float64, time float32 s relative, reflectivity
                       uint16 (the KITTI intensity rounded)
  street_mcap/         ROS 2 bag: metadata.yaml + two MCAP files (zstd chunks, then lz4 chunks),
                       written from the MCAP spec by this script; x y z float32, i uint8 (the
                       KITTI intensity rounded, clamped to 0..255), timestamp float64 absolute
  street.mcap          one MCAP file, uncompressed chunks, schema/channel inside the chunks
  two_topics.bag       two PointCloud2 topics (/points, /points_b)
  strings.bag          only std_msgs/String messages
Also a ROS 1 bag with a PointCloud2 lacking z (no_z.bag).

CDR serialisation here follows the OMG CDR rules ROS 2 uses (4-byte encapsulation header 00 01
00 00, primitives aligned to their size from the end of that header).
"""
import argparse
import math
import os
import sqlite3
import struct
import sys
import zlib

UINT8, FLOAT32, FLOAT64, UINT16, UINT32 = 2, 7, 8, 4, 6
SIZES = {UINT8: 1, FLOAT32: 4, FLOAT64: 8, UINT16: 2, UINT32: 4}
PACK = {UINT8: "<B", FLOAT32: "<f", FLOAT64: "<d", UINT16: "<H", UINT32: "<I"}


def as_integer(value, largest):
    """An intensity as an unsigned integer field holds it: rounded, clamped, NaN as 0."""
    if math.isnan(value):
        return 0
    return max(0, min(largest, int(round(value))))


def read_kitti(kitti_dir, frames):
    velodyne = os.path.join(kitti_dir, "velodyne")
    names = sorted(n for n in os.listdir(velodyne) if n.endswith(".bin"))[:frames]
    scans = []
    for n in names:
        with open(os.path.join(velodyne, n), "rb") as f:
            data = f.read()
        scans.append([struct.unpack_from("<4f", data, i) for i in range(0, len(data), 16)])
    poses = []
    with open(os.path.join(kitti_dir, "poses.txt")) as f:
        for line in f:
            if line.strip():
                poses.append([float(v) for v in line.split()])
    return scans, poses[: len(scans)]


def matrix_to_quaternion(m):
    """3x4 row-major [R|t] -> (qx, qy, qz, qw) (Shepperd's method)."""
    r = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]]
    tr = r[0][0] + r[1][1] + r[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return ((r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s, 0.25 * s)
    if r[0][0] > r[1][1] and r[0][0] > r[2][2]:
        s = math.sqrt(1.0 + r[0][0] - r[1][1] - r[2][2]) * 2
        return (0.25 * s, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s, (r[2][1] - r[1][2]) / s)
    if r[1][1] > r[2][2]:
        s = math.sqrt(1.0 + r[1][1] - r[0][0] - r[2][2]) * 2
        return ((r[0][1] + r[1][0]) / s, 0.25 * s, (r[1][2] + r[2][1]) / s, (r[0][2] - r[2][0]) / s)
    s = math.sqrt(1.0 + r[2][2] - r[0][0] - r[1][1]) * 2
    return ((r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, 0.25 * s, (r[1][0] - r[0][1]) / s)


def stamp_parts(t):
    sec = int(math.floor(t))
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1000000000:
        sec, nsec = sec + 1, nsec - 1000000000
    return sec, nsec


def cloud_data(points, fields, point_step, times, nan_pad_to=None):
    """Packs points into PointCloud2 data. fields: (name, offset, datatype); times per point."""
    rows = []
    count = len(points) if nan_pad_to is None else nan_pad_to
    for i in range(count):
        buf = bytearray(point_step)
        if i < len(points):
            x, y, z, intensity = points[i]
            values = {"x": x, "y": y, "z": z, "intensity": intensity, "ring": i % 16}
        else:
            values = {"x": math.nan, "y": math.nan, "z": math.nan, "intensity": 0.0, "ring": 0}
        values["t"] = values["time"] = values["timestamp"] = times[min(i, len(times) - 1)]
        values["reflectivity"] = as_integer(values["intensity"], 65535)
        values["i"] = as_integer(values["intensity"], 255)
        for name, offset, datatype in fields:
            struct.pack_into(PACK[datatype], buf, offset, values[name])
        rows.append(bytes(buf))
    return b"".join(rows)


# --- CDR -------------------------------------------------------------------------------------


class Cdr:
    def __init__(self):
        self.b = bytearray()

    def align(self, n):
        while len(self.b) % n:
            self.b.append(0)

    def u8(self, v):
        self.b += struct.pack("<B", v)

    def u32(self, v):
        self.align(4)
        self.b += struct.pack("<I", v)

    def i32(self, v):
        self.align(4)
        self.b += struct.pack("<i", v)

    def string(self, s):
        raw = s.encode() + b"\0"
        self.u32(len(raw))
        self.b += raw

    def octets(self, data):
        self.u32(len(data))
        self.b += data


def cdr_point_cloud2(stamp, frame_id, height, width, fields, point_step, data):
    c = Cdr()
    sec, nsec = stamp_parts(stamp)
    c.i32(sec)
    c.u32(nsec)
    c.string(frame_id)
    c.u32(height)
    c.u32(width)
    c.u32(len(fields))
    for name, offset, datatype in fields:
        c.string(name)
        c.u32(offset)
        c.u8(datatype)
        c.u32(1)
    c.u8(0)  # is_bigendian
    c.u32(point_step)
    c.u32(point_step * width)
    c.octets(data)
    c.u8(0)  # is_dense
    return b"\x00\x01\x00\x00" + bytes(c.b)


POINT_CLOUD2_MSG = """std_msgs/Header header
uint32 height
uint32 width
sensor_msgs/PointField[] fields
bool is_bigendian
uint32 point_step
uint32 row_step
uint8[] data
bool is_dense
"""

# --- ROS 1 (python3-rosbag) --------------------------------------------------------------------


def ros1_cloud(stamp, points, fields, point_step, times):
    import genpy
    from sensor_msgs.msg import PointCloud2, PointField

    msg = PointCloud2()
    sec, nsec = stamp_parts(stamp)
    msg.header.stamp = genpy.Time(sec, nsec)
    msg.header.frame_id = "lidar"
    msg.height, msg.width = 1, len(points)
    msg.fields = [PointField(name=n, offset=o, datatype=d, count=1) for n, o, d in fields]
    msg.is_bigendian = False
    msg.point_step = point_step
    msg.row_step = point_step * len(points)
    msg.data = cloud_data(points, fields, point_step, times)
    msg.is_dense = True
    return msg


def write_ros1(path, scans, stamps, compression, topics=("/points",), drop_z=False):
    import genpy
    import rosbag

    fields = [("x", 0, FLOAT32), ("y", 4, FLOAT32), ("z", 8, FLOAT32), ("intensity", 12, FLOAT32),
              ("ring", 16, UINT16), ("t", 20, UINT32)]
    if drop_z:
        fields = [f for f in fields if f[0] != "z"]
    with rosbag.Bag(path, "w", compression=compression) as bag:
        for points, stamp in zip(scans, stamps):
            times = [int(1e8 * i / max(1, len(points))) for i in range(len(points))]  # 0..0.1 s, ns
            msg = ros1_cloud(stamp, points, fields, 32, times)
            sec, nsec = stamp_parts(stamp + 0.01)  # received 10 ms after the stamp
            for topic in topics:
                bag.write(topic, msg, t=genpy.Time(sec, nsec))


def write_ros1_strings(path, count):
    import genpy
    import rosbag
    from std_msgs.msg import String

    with rosbag.Bag(path, "w") as bag:
        for i in range(count):
            bag.write("/chatter", String(data="hello %d" % i), t=genpy.Time(100 + i, 0))


# --- ROS 2 SQLite ------------------------------------------------------------------------------


def metadata_yaml(storage, files, topic, type_name, count, stamps):
    start = int(stamps[0] * 1e9)
    end = int(stamps[-1] * 1e9)
    lines = [
        "rosbag2_bagfile_information:",
        "  version: 5",
        "  storage_identifier: %s" % storage,
        "  duration:",
        "    nanoseconds: %d" % (end - start),
        "  starting_time:",
        "    nanoseconds_since_epoch: %d" % start,
        "  message_count: %d" % count,
        "  topics_with_message_count:",
        "    - topic_metadata:",
        "        name: %s" % topic,
        "        type: %s" % type_name,
        "        serialization_format: cdr",
        "        offered_qos_profiles: \"\"",
        "      message_count: %d" % count,
        "  compression_format: \"\"",
        "  compression_mode: \"\"",
        "  relative_file_paths:",
    ] + ["    - %s" % f for f in files] + ["  files: []", ""]
    return "\n".join(lines)


def db3_messages(scans, stamps):
    fields = [("x", 0, FLOAT64), ("y", 8, FLOAT64), ("z", 16, FLOAT64), ("time", 24, FLOAT32),
              ("reflectivity", 28, UINT16)]
    for points, stamp in zip(scans, stamps):
        width = (len(points) + 1) // 2
        times = [0.1 * i / max(1, len(points)) for i in range(len(points))]
        data = cloud_data(points, fields, 32, times, nan_pad_to=2 * width)
        yield stamp, cdr_point_cloud2(stamp, "lidar", 2, width, fields, 32, data)


def write_db3(bag_dir, scans, stamps):
    os.makedirs(bag_dir)
    name = os.path.basename(bag_dir) + "_0.db3"
    db = sqlite3.connect(os.path.join(bag_dir, name))
    db.executescript(
        "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);"
        "INSERT INTO schema VALUES(3, 'humble');"
        "CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,"
        " metadata TEXT NOT NULL);"
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,"
        " serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,"
        " timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
        "CREATE INDEX timestamp_idx ON messages (timestamp ASC);")
    db.execute("INSERT INTO topics VALUES(1, '/points', 'sensor_msgs/msg/PointCloud2', 'cdr', '')")
    db.execute("INSERT INTO topics VALUES(2, '/rosout', 'rcl_interfaces/msg/Log', 'cdr', '')")
    for stamp, data in db3_messages(scans, stamps):
        db.execute("INSERT INTO messages(topic_id, timestamp, data) VALUES(1, ?, ?)",
                   (int(round((stamp + 0.01) * 1e9)), data))
    db.commit()
    db.close()
    with open(os.path.join(bag_dir, "metadata.yaml"), "w") as f:
        f.write(metadata_yaml("sqlite3", [name], "/points", "sensor_msgs/msg/PointCloud2",
                              len(scans), stamps))


# --- MCAP (https://mcap.dev/spec) --------------------------------------------------------------

MAGIC = b"\x89MCAP0\r\n"


def record(op, body):
    return struct.pack("<BQ", op, len(body)) + body


def mstr(s):
    raw = s.encode()
    return struct.pack("<I", len(raw)) + raw


def compress(data, compression):
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdCompressor().compress(data)
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.compress(data)
    return data


def write_mcap(path, messages, compression, per_chunk=4, channel_in_chunk=False):
    """messages: (log_time_ns, cdr bytes). One schema, one channel /points."""
    schema = record(0x03, struct.pack("<H", 1) + mstr("sensor_msgs/msg/PointCloud2") +
                    mstr("ros2msg") + mstr(POINT_CLOUD2_MSG))
    channel = record(0x04, struct.pack("<HH", 1, 1) + mstr("/points") + mstr("cdr") +
                     struct.pack("<I", 0))
    out = bytearray(MAGIC)
    out += record(0x01, mstr("ros2") + mstr("shinevdb test writer"))
    if not channel_in_chunk:
        out += schema + channel
    for start in range(0, len(messages), per_chunk):
        group = messages[start:start + per_chunk]
        records = bytearray()
        if channel_in_chunk and start == 0:
            records += schema + channel
        index = []
        for seq, (log_time, data) in enumerate(group):
            index.append((log_time, len(records)))
            records += record(0x05, struct.pack("<HIQQ", 1, start + seq, log_time, log_time) + data)
        packed = compress(bytes(records), compression)
        body = struct.pack("<QQQI", group[0][0], group[-1][0], len(records),
                           zlib.crc32(bytes(records))) + mstr(compression)
        body += struct.pack("<Q", len(packed)) + packed
        out += record(0x06, body)
        entries = b"".join(struct.pack("<QQ", t, o) for t, o in index)
        out += record(0x07, struct.pack("<HI", 1, len(entries)) + entries)  # Message Index
    out += record(0x0F, struct.pack("<I", 0))  # Data End
    out += record(0x02, struct.pack("<QQI", 0, 0, 0))  # Footer: no summary section
    out += MAGIC
    with open(path, "wb") as f:
        f.write(out)


def mcap_messages(scans, stamps):
    fields = [("x", 0, FLOAT32), ("y", 4, FLOAT32), ("z", 8, FLOAT32), ("i", 12, UINT8),
              ("timestamp", 16, FLOAT64)]
    out = []
    for points, stamp in zip(scans, stamps):
        times = [stamp + 0.1 * i / max(1, len(points)) for i in range(len(points))]
        data = cloud_data(points, fields, 24, times)
        out.append((int(round((stamp + 0.01) * 1e9)),
                    cdr_point_cloud2(stamp, "lidar", 1, len(points), fields, 24, data)))
    return out


def write_mcap_bag(bag_dir, scans, stamps):
    os.makedirs(bag_dir)
    messages = mcap_messages(scans, stamps)
    half = len(messages) // 2
    name = os.path.basename(bag_dir)
    files = [name + "_0.mcap", name + "_1.mcap"]
    write_mcap(os.path.join(bag_dir, files[0]), messages[:half], "zstd")
    write_mcap(os.path.join(bag_dir, files[1]), messages[half:], "lz4")
    with open(os.path.join(bag_dir, "metadata.yaml"), "w") as f:
        f.write(metadata_yaml("mcap", files, "/points", "sensor_msgs/msg/PointCloud2",
                              len(scans), stamps))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("kitti_dir")
    parser.add_argument("out_dir")
    parser.add_argument("--frames", type=int, default=1000000)
    parser.add_argument("--stamp0", type=float, default=1700000000.0)
    args = parser.parse_args()
    scans, poses = read_kitti(args.kitti_dir, args.frames)
    if not scans:
        sys.exit("no scans in %s/velodyne" % args.kitti_dir)
    stamps = [args.stamp0 + 0.1 * i for i in range(len(scans))]
    os.makedirs(args.out_dir, exist_ok=True)
    with open(os.path.join(args.out_dir, "poses.tum"), "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for stamp, m in zip(stamps, poses):
            q = matrix_to_quaternion(m)
            f.write("%.9f %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n" %
                    (stamp, m[3], m[7], m[11], q[0], q[1], q[2], q[3]))
    o = lambda name: os.path.join(args.out_dir, name)
    write_ros1(o("street.bag"), scans, stamps, "none")
    write_ros1(o("street_bz2.bag"), scans, stamps, "bz2")
    write_ros1(o("street_lz4.bag"), scans, stamps, "lz4")
    write_ros1(o("two_topics.bag"), scans[:2], stamps[:2], "none", topics=("/points", "/points_b"))
    write_ros1(o("no_z.bag"), scans[:1], stamps[:1], "none", drop_z=True)
    write_ros1_strings(o("strings.bag"), 3)
    write_db3(o("street_db3"), scans, stamps)
    write_mcap_bag(o("street_mcap"), scans, stamps)
    write_mcap(o("street.mcap"), mcap_messages(scans, stamps), "", channel_in_chunk=True)
    print("wrote %d scans as recordings into %s" % (len(scans), args.out_dir))


if __name__ == "__main__":
    main()
