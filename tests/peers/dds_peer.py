"""A ROS 2 peer without ROS: CycloneDDS (PyPI `cyclonedds`) reads skein's topics and
commands a vehicle, with type definitions written here from the .msg files alone.

Usage: dds_peer.py --domain D --vehicle uav-1 --api http://127.0.0.1:PORT
                   [--loopback] [--expect-no-command-reader] [--tracks]

1. Subscribes to rt/skein/<vehicle>/pose as geometry_msgs::msg::dds_::PoseStamped_
   (best-effort: skein's reliable writer serves it too) and compares 10 poses with the
   vehicle's position from skein's HTTP API, converted to ENU (x east, y north, z up):
   each must match within 0.5 m.
2. Once skein's command reader has matched, publishes three skein_msgs Commands on
   rt/skein/<vehicle>/command and reads each CommandResult: an unknown command (refused,
   naming the field `command`), a land on the ground (refused by the vehicle's state),
   and a takeoff to 6 m (accepted); then watches the poses until the vehicle is 5 m up.
   With --expect-no-command-reader, checks instead that no command reader matches in 5 s
   (skein without --dds-commands).

With --tracks, reads rt/skein/tracks (skein_msgs Tracks) instead and compares 5
samples' confirmed tracks with skein's GET /api/v1/tracks by id (within 3 m, ENU).

--loopback keeps CycloneDDS on 127.0.0.1 with unicast discovery (no multicast leaves
the host), matching `skein up --dds-network 127.0.0.1`.

Prints one JSON line with what it saw; exits non-zero with the reason on any failure.
"""

import argparse
import json
import math
import sys
import time
import urllib.request
from dataclasses import dataclass

from cyclonedds.core import DDSStatus, Policy, Qos, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float64, sequence, uint32, uint64
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from cyclone_ros import XCDR1, Header, use_loopback


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header
    pose: Pose


@dataclass
class Command(IdlStruct, typename="skein_msgs::msg::dds_::Command_"):
    source: str
    request_id: uint64
    command: str
    altitude_m: float64
    force: bool
    target: Point


@dataclass
class CommandResult(IdlStruct, typename="skein_msgs::msg::dds_::CommandResult_"):
    request_id: uint64
    command_id: uint64
    accepted: bool
    reason: str


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Track(IdlStruct, typename="skein_msgs::msg::dds_::Track_"):
    id: str
    status: str
    position: Point
    velocity: Vector3
    position_sigma_m: float64
    covariance_en_m2: array[float64, 4]
    hits: uint32
    age_s: float64
    unseen_s: float64


@dataclass
class Tracks(IdlStruct, typename="skein_msgs::msg::dds_::Tracks_"):
    header: Header
    tracks: sequence[Track]


def compare_tracks(args, dp, qos, deadline):
    """--tracks: 5 samples of rt/skein/tracks with a confirmed track, each matched by id
    to skein's GET /api/v1/tracks and within 3 m of its position (ENU)."""
    reader = DataReader(dp, Topic(dp, "rt/skein/tracks", Tracks), qos=qos)
    errors = []
    for s in arrivals(reader, deadline):
        confirmed = [t for t in s.tracks if t.status == "confirmed"]
        if not confirmed:
            continue
        with urllib.request.urlopen(f"{args.api}/api/v1/tracks", timeout=5) as r:
            api = {t["id"]: t for t in json.load(r)["tracks"]}
        for t in confirmed:
            a = api.get(t.id)
            if a is None:
                continue
            p = a["position"]
            enu = (p["east_m"], p["north_m"], -p["down_m"])
            errors.append(math.dist((t.position.x, t.position.y, t.position.z), enu))
        if len(errors) >= 5:
            break
    if len(errors) < 5:
        fail(f"only {len(errors)} track samples compared")
    if max(errors) > 3.0:
        fail(f"a track was {max(errors):.2f} m from the API's (limit 3 m)")
    print(json.dumps({"ok": True, "tracks_compared": len(errors),
                      "worst_track_error_m": max(errors)}), flush=True)


def arrivals(reader, deadline):
    """The samples of `reader` as they arrive (waiting on a DDS WaitSet, no polling), until
    the monotonic `deadline`."""
    remaining = deadline - time.monotonic()
    if remaining <= 0:
        return
    for s in reader.take_iter(timeout=duration(seconds=remaining)):
        yield s
        if time.monotonic() > deadline:
            return


def wait_matched(participant, writer, deadline):
    """True once `writer` has matched a reader, waiting on a DDS WaitSet for its
    PublicationMatched status (no polling); False at the monotonic `deadline`."""
    writer.set_status_mask(DDSStatus.PublicationMatched)
    ws = WaitSet(participant)
    ws.attach(writer)
    try:
        while not writer.get_matched_subscriptions():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            ws.wait(duration(seconds=remaining))
            writer.take_status()
        return True
    finally:
        ws.detach(writer)


def fail(why):
    print(json.dumps({"ok": False, "error": why}), flush=True)
    sys.exit(1)


def api_position(api, vehicle):
    with urllib.request.urlopen(f"{api}/api/v1/vehicles/{vehicle}", timeout=5) as r:
        v = json.load(r)
    p = v.get("position")
    if p is None:
        return None
    # skein's swarm frame is NED; the topic is ENU (REP 103).
    return (p["east_m"], p["north_m"], -p["down_m"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--vehicle", required=True)
    ap.add_argument("--api", required=True)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--loopback", action="store_true")
    ap.add_argument("--expect-no-command-reader", action="store_true")
    ap.add_argument("--tracks", action="store_true")
    args = ap.parse_args()
    if args.loopback:
        use_loopback()
    ros = args.vehicle.replace("-", "_")
    deadline = time.monotonic() + args.timeout

    dp = DomainParticipant(args.domain)
    pose_reader = DataReader(
        dp,
        Topic(dp, f"rt/skein/{ros}/pose", PoseStamped),
        qos=Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1), XCDR1),
    )
    reliable = Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.History.KeepLast(16),
        XCDR1,
    )
    cmd_writer = DataWriter(dp, Topic(dp, f"rt/skein/{ros}/command", Command), qos=reliable)
    result_reader = DataReader(
        dp, Topic(dp, f"rt/skein/{ros}/command_result", CommandResult), qos=reliable
    )

    if args.tracks:
        compare_tracks(args, dp, reliable, deadline)
        return

    # 1. Poses against the API.
    compared = []
    for s in arrivals(pose_reader, deadline):
        api = api_position(args.api, args.vehicle)
        if api is None:
            continue
        if s.header.frame_id != "skein_swarm":
            fail(f"frame_id {s.header.frame_id!r}, expected 'skein_swarm'")
        p = s.pose.position
        compared.append(math.dist((p.x, p.y, p.z), api))
        if len(compared) >= 10:
            break
    if len(compared) < 10:
        fail(f"only {len(compared)} poses in {args.timeout} s")
    worst = max(compared)
    if worst > 0.5:
        fail(f"a pose was {worst:.3f} m from the API's position (limit 0.5 m)")

    # 2. Commands, once skein's reader has matched our writer.
    if args.expect_no_command_reader:
        if wait_matched(dp, cmd_writer, time.monotonic() + 5.0):
            fail("skein has a command reader although commands are off")
        print(json.dumps({"ok": True, "poses_compared": len(compared),
                          "worst_pose_error_m": worst, "command_reader": False}), flush=True)
        return
    if not wait_matched(dp, cmd_writer, deadline):
        fail("skein's command reader never matched (is --dds-commands on?)")

    def command(request_id, name, altitude_m=math.nan):
        cmd_writer.write(
            Command(
                source="dds_peer.py",
                request_id=request_id,
                command=name,
                altitude_m=altitude_m,
                force=False,
                target=Point(0.0, 0.0, 0.0),
            )
        )
        for r in arrivals(result_reader, deadline):
            if r.request_id == request_id:
                return r
        fail(f"no CommandResult for request {request_id} ({name})")

    unknown = command(1, "explode")
    if unknown.accepted or "command" not in unknown.reason:
        fail(f"an unknown command was answered {unknown}")
    land = command(2, "land")
    if land.accepted:
        fail("a land on the ground was accepted")
    result = command(3, "takeoff", 6.0)
    if not result.accepted:
        fail(f"takeoff refused: {result.reason}")
    top = -math.inf
    for s in arrivals(pose_reader, deadline):
        top = max(top, s.pose.position.z)
        if top >= 5.0:
            break
    if top < 5.0:
        fail(f"the vehicle rose only to {top:.2f} m after takeoff")
    # 3. Poses in flight against the API (z up, non-zero).
    in_flight = []
    for s in arrivals(pose_reader, deadline):
        p = s.pose.position
        in_flight.append(math.dist((p.x, p.y, p.z), api_position(args.api, args.vehicle)))
        if len(in_flight) >= 5:
            break
    if len(in_flight) < 5:
        fail(f"only {len(in_flight)} poses compared in flight")
    if max(in_flight) > 0.5:
        fail(f"a pose in flight was {max(in_flight):.3f} m from the API's (limit 0.5 m)")
    print(
        json.dumps(
            {
                "ok": True,
                "in_flight_worst_pose_error_m": max(in_flight),
                "ground_position_enu_m": list(api_position(args.api, args.vehicle) or []),
                "poses_compared": len(compared),
                "worst_pose_error_m": worst,
                "command_id": result.command_id,
                "unknown_refused": unknown.reason,
                "land_refused": land.reason,
                "climbed_to_m": top,
            }
        ),
        flush=True,
    )


if __name__ == "__main__":
    main()
