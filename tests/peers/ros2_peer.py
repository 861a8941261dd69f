"""A ROS 2 node against skein: rclpy on rmw_fastrtps_cpp (Fast DDS), with skein_msgs built
from ros2/skein_msgs by ROS 2's own generators (tests/peers/ros2/setup.sh), run in
.venv-ros2 with the environment of .venv-ros2/skein.env.

Usage: ros2_peer.py read --api URL --vehicles uav-1,uav-2 --node NAME[,NAME] [--seconds S]
                          [--standard-only] [--rtcm]
       ros2_peer.py command --api URL --vehicle uav-1
       ros2_peer.py serialise --samples FILE

`read` subscribes as a ROS 2 user would (default QoS, as RViz's displays and a default
rclpy subscriber do, and `qos_profile_sensor_data` for the poses; tf2's own QoS for /tf
and /tf_static), finds skein's nodes NAME in the ROS graph with every topic's type,
counts each topic's samples over S seconds, compares what it read with skein's HTTP API
(poses, fixes, batteries, states; /tf against the poses; /tf_static against the swarm
origin), and checks that nothing reads /skein/<vehicle>/command (skein without
--dds-commands). With --standard-only, only the topics of ROS 2's standard messages
(pose, navsat, battery): a distribution without skein_msgs and tf2_msgs built. With
--rtcm, also the RTK corrections on /skein/rtcm (rtcm_msgs/Message, default QoS), each
sample checked as an RTCM3 frame (preamble, length, CRC-24Q) and counted by message
number.

`command` commands one vehicle through skein_msgs/Command and its CommandResult: an
unknown command and a land on the ground (both refused, with the reason), then arm,
takeoff to 8 m, goto, land, watching the vehicle on its pose and state topics and /tf.

`serialise` reads skein's samples of every message type (JSON and skein's CDR bytes,
written by tests/e2e_ros2.rs), builds each with the rosidl-generated Python type,
serialises it with rclpy and compares the bytes with skein's (padding aside: Fast CDR
leaves it uninitialised), and deserialises skein's bytes into the Python type.

ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE (LOCALHOST in the tests) come from the
environment. Prints one JSON line with what it saw; exits non-zero with the reason on a
failure.
"""

import argparse
import importlib
import json
import math
import sys
import time
import urllib.request

import rclpy
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)


def fail(why, **seen):
    print(json.dumps({"ok": False, "error": why, **seen}), flush=True)
    sys.exit(1)


def api(base, path):
    with urllib.request.urlopen(f"{base}{path}", timeout=5) as r:
        return json.load(r)


def enu(position):
    """skein's swarm-frame NED as the topics' ENU (REP 103)."""
    return (position["east_m"], position["north_m"], -position["down_m"])


def ros_name(vehicle):
    return "".join(c if c.isalnum() or c == "_" else "_" for c in vehicle)


def xyz(p):
    return (p.x, p.y, p.z)


def spin_until(node, deadline, done):
    """Spins `node` until `done()` or the monotonic `deadline`; whether `done()`."""
    while not done():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        rclpy.spin_once(node, timeout_sec=min(remaining, 0.1))
    return True


# tf2_ros's listener QoS (tf2_ros/qos.hpp): /tf reliable, volatile, depth 100; /tf_static
# reliable, transient-local, depth 100.
TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
TF_STATIC_QOS = QoSProfile(
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


class Seen:
    """The samples of one subscription: count, first and last arrival, last sample."""

    def __init__(self):
        self.count = 0
        self.first = None
        self.last_at = None
        self.last = None

    def __call__(self, msg):
        now = time.monotonic()
        self.count += 1
        self.first = self.first or now
        self.last_at = now
        self.last = msg

    def rate_hz(self):
        if self.count < 2:
            return 0.0
        return (self.count - 1) / (self.last_at - self.first)


def crc24q(data):
    """RTCM 10403's CRC-24Q of `data`."""
    crc = 0
    for b in data:
        crc ^= b << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= 0x1864CFB
    return crc & 0xFFFFFF


class Rtcm:
    """The RTCM3 frames of /skein/rtcm: how many, by message number, and how many are no
    whole frame with a good CRC."""

    def __init__(self):
        self.count = 0
        self.types = {}
        self.bad = 0

    def __call__(self, msg):
        frame = bytes(msg.message)
        self.count += 1
        length = ((frame[1] & 0x03) << 8 | frame[2]) if len(frame) >= 3 else -1
        if (len(frame) < 8 or frame[0] != 0xD3 or len(frame) != length + 6
                or crc24q(frame[:-3]) != int.from_bytes(frame[-3:], "big")):
            self.bad += 1
            return
        t = str(frame[3] << 4 | frame[4] >> 4)
        self.types[t] = self.types.get(t, 0) + 1

    def report(self):
        return {"count": self.count, "types": self.types, "bad": self.bad}


def ecef(lat_deg, lon_deg, alt_m):
    """WGS84 geodetic to ECEF, metres."""
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    n = a / math.sqrt(1 - e2 * math.sin(lat) ** 2)
    return (
        (n + alt_m) * math.cos(lat) * math.cos(lon),
        (n + alt_m) * math.cos(lat) * math.sin(lon),
        (n * (1 - e2) + alt_m) * math.sin(lat),
    )


def read(args):
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import BatteryState, NavSatFix

    full = not args.standard_only
    if full:
        from skein_msgs.msg import Command, Tracks, VehicleState
        from tf2_msgs.msg import TFMessage

    node = Node("skein_ros2_peer")
    deadline = time.monotonic() + args.timeout
    vehicles = args.vehicles.split(",")
    seen = {}

    def sub(msg_type, topic, qos, key=None):
        s = seen.setdefault(key or topic, Seen())
        node.create_subscription(msg_type, topic, s, qos)

    expected_types = {"/skein/tracks": "skein_msgs/msg/Tracks"}
    for v in vehicles:
        ns = f"/skein/{ros_name(v)}"
        # Default QoS (reliable, depth 10), as a ROS 2 user subscribes.
        sub(PoseStamped, f"{ns}/pose", 10)
        sub(PoseStamped, f"{ns}/pose", qos_profile_sensor_data, f"{ns}/pose sensor_data")
        sub(NavSatFix, f"{ns}/navsat", 10)
        sub(BatteryState, f"{ns}/battery", 10)
        expected_types.update({
            f"{ns}/pose": "geometry_msgs/msg/PoseStamped",
            f"{ns}/navsat": "sensor_msgs/msg/NavSatFix",
            f"{ns}/battery": "sensor_msgs/msg/BatteryState",
            f"{ns}/state": "skein_msgs/msg/VehicleState",
        })
        if full:
            sub(VehicleState, f"{ns}/state", 10)
    # The latest transform of each child frame, as a tf2 buffer keeps it.
    tf_latest = {}
    if full:
        sub(Tracks, "/skein/tracks", 10)
        sub(TFMessage, "/tf", TF_QOS)
        sub(TFMessage, "/tf_static", TF_STATIC_QOS)
        expected_types["/tf"] = "tf2_msgs/msg/TFMessage"
        expected_types["/tf_static"] = "tf2_msgs/msg/TFMessage"

        def on_tf(msg):
            for t in msg.transforms:
                tf_latest[t.child_frame_id] = t

        node.create_subscription(TFMessage, "/tf", on_tf, TF_QOS)
        commands = node.create_publisher(
            Command, f"/skein/{ros_name(vehicles[0])}/command", 10)
    rtcm = Rtcm()
    if args.rtcm:
        from rtcm_msgs.msg import Message

        sub(Message, "/skein/rtcm", 10)
        node.create_subscription(Message, "/skein/rtcm", rtcm, 10)
        expected_types["/skein/rtcm"] = "rtcm_msgs/msg/Message"

    # 1. The graph: skein's nodes, and every topic with its type (the graph names the
    # types of skein_msgs even where they are not built).
    def graph_ready():
        nodes = node.get_node_names_and_namespaces()
        types = dict(node.get_topic_names_and_types())
        return all((n, "/skein") in nodes for n in args.node.split(",")) and all(
            types.get(t) == [ty] for t, ty in expected_types.items()
        )

    if not spin_until(node, deadline, graph_ready):
        fail("skein's node or a topic is missing from the ROS graph",
             nodes=node.get_node_names_and_namespaces(),
             types={t: ty for t, ty in node.get_topic_names_and_types()})
    found_after_s = args.timeout - (deadline - time.monotonic())

    # 2. Every subscription has a sample (the battery comes at a tenth of the rate).
    if not spin_until(node, deadline, lambda: all(s.count > 0 for s in seen.values())):
        fail("no sample on some topics",
             silent=[t for t, s in seen.items() if s.count == 0])
    for s in seen.values():
        s.count, s.first = 0, None
    window_end = time.monotonic() + args.seconds
    spin_until(node, window_end, lambda: False)
    rates = {t: round(s.rate_hz(), 2) for t, s in seen.items() if t != "/tf_static"}

    # 3. What was read against skein's API (the vehicles stand still on the ground).
    pose_errors, navsat_errors_deg, alt_errors, battery_errors, states = [], [], [], [], {}
    tf_errors, tf_parents = [], set()
    for v in vehicles:
        ns = f"/skein/{ros_name(v)}"
        a = api(args.api, f"/api/v1/vehicles/{v}")
        pose = seen[f"{ns}/pose"].last
        if pose.header.frame_id != "skein_swarm":
            fail(f"{v}: pose frame_id {pose.header.frame_id!r}")
        pose_errors.append(math.dist(xyz(pose.pose.position), enu(a["position"])))
        fix = seen[f"{ns}/navsat"].last
        navsat_errors_deg.append(max(abs(fix.latitude - a["position"]["lat_deg"]),
                                     abs(fix.longitude - a["position"]["lon_deg"])))
        alt_errors.append(abs(fix.altitude - a["position"]["alt_amsl_m"]))
        battery = seen[f"{ns}/battery"].last
        battery_errors.append(max(abs(battery.percentage - a["battery"]["percent"] / 100),
                                  abs(battery.voltage - a["battery"]["voltage_v"]) / 10))
        if not full:
            continue
        st = seen[f"{ns}/state"].last
        states[v] = {
            "id": st.id, "sysid": st.sysid, "model": st.model, "state": st.state,
            "px4_mode": st.px4_mode, "armed": st.armed, "link_connected": st.link_connected,
            "slot": st.slot,
            "api": [a["id"], a["sysid"], a["model"], a["state"], a["px4_mode"], a["armed"],
                    a["link"]["connected"]],
        }
        t = tf_latest.get(f"{ros_name(v)}/base_link")
        if t is None:
            fail(f"no /tf transform for {ros_name(v)}/base_link", frames=list(tf_latest))
        tf_parents.add(t.header.frame_id)
        tf_errors.append(math.dist(xyz(t.transform.translation), xyz(pose.pose.position)))
    report = {
        "ok": True,
        "graph_found_after_s": round(found_after_s, 2),
        "rates_hz": rates,
        "worst_pose_error_m": max(pose_errors),
        "worst_navsat_error_deg": max(navsat_errors_deg),
        "worst_navsat_alt_error_m": max(alt_errors),
        "worst_battery_error": max(battery_errors),
    }
    if full:
        tracks = seen["/skein/tracks"].last
        # /tf_static: the swarm frame's anchor, earth (ECEF) -> skein_swarm.
        anchor = seen["/tf_static"].last.transforms
        origin = api(args.api, "/api/v1/health")["swarm_origin"]
        want = ecef(origin["lat_deg"], origin["lon_deg"], origin["alt_amsl_m"])
        report.update({
            "states": states,
            "tracks": {"frame_id": tracks.header.frame_id, "count": len(tracks.tracks)},
            "tf_frames": sorted(tf_latest),
            "tf_parents": sorted(tf_parents),
            "worst_tf_vs_pose_m": max(tf_errors),
            "tf_static": [[t.header.frame_id, t.child_frame_id] for t in anchor],
            "anchor_error_m": math.dist(xyz(anchor[0].transform.translation), want),
            # 4. Nothing reads commands (skein runs without --dds-commands): the writer
            # stays unmatched though skein's other endpoints were found seconds ago.
            "command_readers": commands.get_subscription_count(),
        })
    if args.rtcm:
        report["rtcm"] = rtcm.report()
    print(json.dumps(report), flush=True)


def command(args):
    from geometry_msgs.msg import Point, PoseStamped
    from skein_msgs.msg import Command, CommandResult, VehicleState
    from tf2_msgs.msg import TFMessage

    node = Node("skein_ros2_commander")
    deadline = time.monotonic() + args.timeout
    ns = f"/skein/{ros_name(args.vehicle)}"
    frame = f"{ros_name(args.vehicle)}/base_link"
    latest = {}
    results = {}
    recent = []  # the last second of poses, to tell when the vehicle stands still

    def on_pose(m):
        latest["pose"] = m
        recent.append(xyz(m.pose.position))
        del recent[:-10]

    node.create_subscription(PoseStamped, f"{ns}/pose", on_pose, 10)
    node.create_subscription(VehicleState, f"{ns}/state", lambda m: latest.update(state=m), 10)
    node.create_subscription(
        CommandResult, f"{ns}/command_result", lambda m: results.update({m.request_id: m}), 10
    )

    tf_history = []  # this vehicle's transforms, oldest first, as a tf2 buffer keeps them

    def on_tf(msg):
        for t in msg.transforms:
            if t.child_frame_id == frame:
                tf_history.append(t)
                del tf_history[:-50]

    node.create_subscription(TFMessage, "/tf", on_tf, TF_QOS)
    node.create_subscription(TFMessage, "/tf_static", lambda m: latest.update(tf_static=m),
                             TF_STATIC_QOS)
    pub = node.create_publisher(Command, f"{ns}/command", 10)
    result_sub_matched = lambda: node.count_publishers(f"{ns}/command_result") > 0  # noqa: E731
    if not spin_until(node, deadline, lambda: pub.get_subscription_count() > 0
                      and result_sub_matched() and "pose" in latest and "state" in latest):
        fail("skein's command reader never matched (is --dds-commands on?)")

    def send(request_id, name, altitude_m=math.nan, target=(0.0, 0.0, 0.0)):
        pub.publish(Command(source="ros2_peer.py", request_id=request_id, command=name,
                            altitude_m=altitude_m, force=False,
                            target=Point(x=target[0], y=target[1], z=target[2])))
        if not spin_until(node, deadline, lambda: request_id in results):
            fail(f"no CommandResult for request {request_id} ({name})")
        return results[request_id]

    def wait(what, done):
        started = time.monotonic()
        if not spin_until(node, deadline, done):
            fail(f"timed out waiting for {what}",
                 pose=list(xyz(latest["pose"].pose.position)), state=latest["state"].state)
        return round(time.monotonic() - started, 2)

    def position():
        return xyz(latest["pose"].pose.position)

    seen = {}
    unknown = send(1, "explode")
    if unknown.accepted or "command" not in unknown.reason:
        fail(f"an unknown command was answered {unknown}")
    seen["unknown_refused"] = unknown.reason
    land = send(2, "land")
    if land.accepted:
        fail("a land on the ground was accepted")
    seen["land_refused"] = land.reason
    arm = send(3, "arm")
    if not arm.accepted:
        fail(f"arm refused: {arm.reason}")
    seen["armed_after_s"] = wait("armed", lambda: latest["state"].armed)
    takeoff = send(4, "takeoff", altitude_m=8.0)
    if not takeoff.accepted:
        fail(f"takeoff refused: {takeoff.reason}")
    seen["hovering_after_s"] = wait(
        "hovering at 8 m",
        lambda: latest["state"].state == "Hovering" and abs(position()[2] - 8.0) < 0.15,
    )
    seen["hover_altitude_m"] = position()[2]
    start = position()
    goal = (start[0] + 6.0, start[1] - 4.0, 8.0)
    goto = send(5, "goto", target=goal)
    if not goto.accepted:
        fail(f"goto refused: {goto.reason}")
    seen["goto_after_s"] = wait(
        "the goto's goal",
        lambda: math.dist(position(), goal) < 0.15 and latest["state"].state == "Hovering",
    )
    seen["goal_enu_m"] = goal
    seen["goal_error_m"] = math.dist(position(), goal)
    # /tf and the pose topic agree: once the vehicle stands still (its last second of
    # poses within 2 cm), its frame looked up at a pose's stamp as tf2 does it
    # (interpolated between the transforms around that time) is the pose. (Each is
    # stamped when published, its own round a period apart from the other's.)
    seen["still_after_s"] = wait("the vehicle still", lambda: len(recent) == 10 and max(
        math.dist(p, recent[-1]) for p in recent) < 0.02)
    pose = latest["pose"]
    at = stamp_s(pose.header.stamp)
    wait("/tf transforms after the pose", lambda: tf_history and
         stamp_s(tf_history[-1].header.stamp) >= at)
    seen["tf_parent"] = tf_history[-1].header.frame_id
    seen["tf_vs_pose_m"] = math.dist(tf_at(tf_history, at), xyz(pose.pose.position))
    down = send(6, "land")
    if not down.accepted:
        fail(f"land refused: {down.reason}")
    seen["landed_after_s"] = wait("the vehicle on the ground", lambda: position()[2] < 0.3)
    seen["final_state"] = latest["state"].state
    wait("/tf_static", lambda: "tf_static" in latest)
    seen["tf_static"] = [[t.header.frame_id, t.child_frame_id, list(xyz(t.transform.translation)),
                          t.transform.rotation.w] for t in latest["tf_static"].transforms]
    seen["command_ids"] = [results[i].command_id for i in (3, 4, 5, 6)]
    seen["api_position_enu_m"] = enu(api(args.api, f"/api/v1/vehicles/{args.vehicle}")["position"])
    print(json.dumps({"ok": True, **seen}), flush=True)


def stamp_s(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def tf_at(history, at):
    """The translation of a frame at time `at` (s), linearly interpolated between the
    transforms of `history` (oldest first) around it, as tf2's lookupTransform."""
    for a, b in zip(history, history[1:]):
        ta, tb = stamp_s(a.header.stamp), stamp_s(b.header.stamp)
        if ta <= at <= tb:
            w = 0.0 if tb == ta else (at - ta) / (tb - ta)
            pa, pb = xyz(a.transform.translation), xyz(b.transform.translation)
            return tuple(x + w * (y - x) for x, y in zip(pa, pb))
    fail(f"no /tf transforms around {at}",
         stamps=[stamp_s(t.header.stamp) for t in history])


# CDR sizes of rosidl_parser's basic types.
SIZES = {"boolean": 1, "octet": 1, "char": 1, "wchar": 2, "int8": 1, "uint8": 1,
         "int16": 2, "uint16": 2, "int32": 4, "uint32": 4, "int64": 8, "uint64": 8,
         "float": 4, "double": 8}


def message_class(namespaced):
    module = importlib.import_module(".".join(namespaced.namespaces))
    return getattr(module, namespaced.name)


def data_ranges(msg):
    """The (start, end) byte ranges of `msg`'s CDR (XCDR1, after the 4-byte
    encapsulation) that hold data; the rest is alignment padding."""
    from rosidl_parser.definition import (
        AbstractGenericString, AbstractNestedType, AbstractSequence, BasicType,
        NamespacedType)

    ranges = []
    off = 0

    def align(n):
        nonlocal off
        off += (-off) % n

    def value(slot, v):
        nonlocal off
        if isinstance(slot, BasicType):
            n = SIZES[slot.typename]
            align(n)
            ranges.append((off, off + n))
            off += n
        elif isinstance(slot, AbstractGenericString):
            align(4)
            n = 4 + len(v.encode()) + 1
            ranges.append((off, off + n))
            off += n
        elif isinstance(slot, NamespacedType):
            message(v)
        elif isinstance(slot, AbstractNestedType):
            if isinstance(slot, AbstractSequence):
                align(4)
                ranges.append((off, off + 4))
                off += 4
            for item in v:
                value(slot.value_type, item)
        else:
            raise ValueError(f"no CDR layout for {slot}")

    def message(m):
        for field, slot in zip(m.get_fields_and_field_types(), type(m).SLOT_TYPES):
            value(slot, getattr(m, field))

    message(msg)
    return ranges


def build(cls, value):
    """A `cls` message from its JSON form (serde's: fields by name)."""
    from rosidl_parser.definition import AbstractNestedType, NamespacedType

    msg = cls()
    for field, slot in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES):
        v = value[field]
        if isinstance(slot, NamespacedType):
            v = build(message_class(slot), v)
        elif isinstance(slot, AbstractNestedType) and isinstance(slot.value_type, NamespacedType):
            v = [build(message_class(slot.value_type), x) for x in v]
        setattr(msg, field, v)
    return msg


def serialise(args):
    from rclpy.serialization import deserialize_message, serialize_message

    with open(args.samples) as f:
        samples = json.load(f)
    compared = {}
    for s in samples:
        pkg, _, name = s["type"].split("/")
        cls = getattr(importlib.import_module(f"{pkg}.msg"), name)
        msg = build(cls, s["value"])
        py = serialize_message(msg)
        rust = bytes.fromhex(s["cdr_hex"])
        if py[:4] != b"\x00\x01\x00\x00":
            fail(f"{s['type']}: rclpy wrote encapsulation {py[:4].hex()}, not CDR_LE")
        py = py[4:]
        if len(py) != len(rust):
            fail(f"{s['type']}: {len(rust)} bytes from skein, {len(py)} from rclpy",
                 rust=rust.hex(), rclpy=py.hex())
        ranges = data_ranges(msg)
        for a, b in ranges:
            if py[a:b] != rust[a:b]:
                fail(f"{s['type']}: bytes {a}..{b} differ", rust=rust.hex(), rclpy=py.hex())
        data = sum(b - a for a, b in ranges)
        if ranges[-1][1] != len(rust):
            fail(f"{s['type']}: the layout ends at {ranges[-1][1]}, the bytes at {len(rust)}")
        back = deserialize_message(b"\x00\x01\x00\x00" + rust, cls)
        if back != msg:
            fail(f"{s['type']}: skein's bytes read back as {back}, not {msg}")
        compared[s["type"]] = {"bytes": len(rust), "data_bytes": data}
    print(json.dumps({"ok": True, "compared": compared}), flush=True)


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="mode", required=True)
    r = sub.add_parser("read")
    r.add_argument("--api", required=True)
    r.add_argument("--vehicles", required=True)
    r.add_argument("--node", required=True)
    r.add_argument("--seconds", type=float, default=4.0)
    r.add_argument("--timeout", type=float, default=60.0)
    r.add_argument("--standard-only", action="store_true")
    r.add_argument("--rtcm", action="store_true")
    c = sub.add_parser("command")
    c.add_argument("--api", required=True)
    c.add_argument("--vehicle", required=True)
    c.add_argument("--timeout", type=float, default=120.0)
    s = sub.add_parser("serialise")
    s.add_argument("--samples", required=True)
    args = ap.parse_args()
    rclpy.init()
    try:
        {"read": read, "command": command, "serialise": serialise}[args.mode](args)
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
