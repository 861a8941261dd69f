"""What the CycloneDDS peers (`dds_peer.py`, `image_publisher.py`) share to speak ROS 2
without ROS: the standard types they use, written from the Jazzy .msg files alone, the
QoS representation ROS 2 writes, and a loopback-only configuration."""

import os
from dataclasses import dataclass

from cyclonedds.core import Policy
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import int32, uint32

# ROS 2's rmw_cyclonedds writes XCDR1; so does skein (RustDDS).
XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


def use_loopback():
    """Keeps CycloneDDS on 127.0.0.1 with unicast discovery (no multicast leaves the
    host); call it before the first DomainParticipant."""
    os.environ["CYCLONEDDS_URI"] = (
        "<CycloneDDS><Domain Id='any'><General><Interfaces>"
        "<NetworkInterface address='127.0.0.1'/></Interfaces>"
        "<AllowMulticast>false</AllowMulticast></General>"
        "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
        "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>"
        "<Peers><Peer address='127.0.0.1'/></Peers></Discovery></Domain></CycloneDDS>"
    )
