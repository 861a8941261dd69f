"""A ROS 2 camera node without ROS: CycloneDDS (PyPI `cyclonedds`) publishes
sensor_msgs/CompressedImage and sensor_msgs/Image, with type definitions written here
from the Jazzy .msg files alone, as a camera driver (usb_cam, v4l2_camera, a gimbal
camera's ROS 2 node) with image_transport's compressed plugin would.

Usage: image_publisher.py --domain D [--loopback] [--rate HZ]
         [--compressed TOPIC=FILE.jpg] [--raw TOPIC=FILE.ppm] [--corrupt TOPIC]
         [--wrong-type TOPIC]

--compressed publishes FILE's bytes (a JPEG) as CompressedImage, format "jpeg".
--raw publishes a binary PPM (P6) as Image, encoding "rgb8" (rows padded to a step of
  width*3+4 bytes, as some drivers align them).
--corrupt publishes, alternately, a JPEG cut in half (format "jpeg") and bytes that are
  no PNG (format "png"): a decoder must refuse both.
--wrong-type publishes samples named sensor_msgs/Image that hold a header and one byte:
  not an Image's CDR (a reader must count and drop them).
Every message's header stamp is the wall-clock time it is published (the capture time a
driver would give). Prints "PUBLISHING" once its writers exist, then publishes at --rate
until SIGTERM; dies with its parent (PR_SET_PDEATHSIG).

--loopback keeps CycloneDDS on 127.0.0.1 with unicast discovery (no multicast leaves
the host).
"""

import argparse
import ctypes
import re
import signal
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import sequence, uint8, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from cyclone_ros import XCDR1, Header, Time, use_loopback


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header
    format: str
    data: sequence[uint8]


@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header
    height: uint32
    width: uint32
    encoding: str
    is_bigendian: uint8
    step: uint32
    data: sequence[uint8]


@dataclass
class NotAnImage(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    """Image's type name on a sample that is no Image: a header and one byte."""

    header: Header
    height: uint8


def header():
    now = time.time_ns()
    return Header(Time(now // 1_000_000_000, now % 1_000_000_000), "camera_optical_frame")


def read_ppm(path):
    """A binary PPM (P6, maxval 255, no comments) as (width, height, rgb bytes)."""
    with open(path, "rb") as f:
        data = f.read()
    m = re.match(rb"P6\s+(\d+)\s+(\d+)\s+255\s", data)
    if not m:
        sys.exit(f"{path}: not a P6 PPM with maxval 255")
    w, h = int(m.group(1)), int(m.group(2))
    pixels = data[m.end() :]
    if len(pixels) < w * h * 3:
        sys.exit(f"{path}: {len(pixels)} bytes of pixels for {w}x{h}")
    return w, h, pixels[: w * h * 3]


def dds_name(topic):
    """ROS 2 topic /a/b as DDS names it: rt/a/b."""
    if not topic.startswith("/"):
        sys.exit(f"a topic is an absolute ROS 2 name: {topic}")
    return "rt" + topic


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--loopback", action="store_true")
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--compressed", action="append", default=[])
    ap.add_argument("--raw", action="append", default=[])
    ap.add_argument("--corrupt", action="append", default=[])
    ap.add_argument("--wrong-type", action="append", default=[])
    args = ap.parse_args()
    # PR_SET_PDEATHSIG = 1: SIGTERM when the test that started it dies, however it dies.
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)
    if args.loopback:
        use_loopback()
    # ROS 2's rmw_cyclonedds writes XCDR1, reliable keep-last (a driver's default QoS).
    qos = Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.History.KeepLast(2),
        XCDR1,
    )
    dp = DomainParticipant(args.domain)
    messages = []  # (writer, function making the next message)
    for spec in args.compressed:
        topic, _, path = spec.partition("=")
        with open(path, "rb") as f:
            jpeg = list(f.read())
        w = DataWriter(dp, Topic(dp, dds_name(topic), CompressedImage), qos=qos)
        messages.append((w, lambda jpeg=jpeg: CompressedImage(header(), "jpeg", jpeg)))
    for spec in args.raw:
        topic, _, path = spec.partition("=")
        width, height, rgb = read_ppm(path)
        step = width * 3 + 4
        padded = bytearray()
        for y in range(height):
            padded += rgb[y * width * 3 : (y + 1) * width * 3] + b"\0\0\0\0"
        data = list(padded)
        w = DataWriter(dp, Topic(dp, dds_name(topic), Image), qos=qos)
        messages.append(
            (w, lambda d=data, wd=width, h=height, s=step: Image(header(), h, wd, "rgb8", 0, s, d))
        )
    for topic in args.corrupt:
        half = [0xFF, 0xD8, 0xFF, 0xDB] + [7] * 300
        w = DataWriter(dp, Topic(dp, dds_name(topic), CompressedImage), qos=qos)
        turn = {"n": 0}

        def corrupt(turn=turn, half=half):
            turn["n"] += 1
            if turn["n"] % 2:
                return CompressedImage(header(), "jpeg", half)
            return CompressedImage(header(), "png", list(b"\x89PNG but not really"))

        messages.append((w, corrupt))
    for topic in args.wrong_type:
        w = DataWriter(dp, Topic(dp, dds_name(topic), NotAnImage), qos=qos)
        messages.append((w, lambda: NotAnImage(header(), 7)))
    if not messages:
        sys.exit("nothing to publish: give --compressed, --raw or --corrupt")

    running = {"on": True}

    def stop(*_):
        running["on"] = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print("PUBLISHING", flush=True)
    period = 1.0 / args.rate
    next_at = time.monotonic()
    sent = 0
    while running["on"]:
        for writer, make in messages:
            writer.write(make())
        sent += 1
        next_at += period
        # A publisher's own pace: the clock decides, not a fixed sleep after the work.
        time.sleep(max(0.0, next_at - time.monotonic()))
    print(f"SENT {sent}", flush=True)


if __name__ == "__main__":
    main()
