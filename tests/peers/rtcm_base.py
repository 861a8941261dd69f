#!/usr/bin/env python3
"""An RTK base station streaming RTCM3 to a TCP server (RTKLIB's str2str `tcpsvr://`
input, which serves it on as an NTRIP caster), its frames serialized and checked by
pyrtcm (the reference RTCM3 library of the Python world).

Every second it sends one epoch, as a base receiver does: the reference station's
antenna position (message 1005, station --station-id at --lat/--lon/--alt) and GPS
observations (MSM4, message 1074) of eight satellites. Each message's payload is packed
here bit by bit (RTCM 10403.3 data fields), framed by pyrtcm (`RTCMMessage.serialize`:
preamble, length, CRC-24Q) and parsed back by pyrtcm's `RTCMReader` before it is sent: a
frame pyrtcm cannot read is never sent. With --corrupt-every N, every Nth epoch's MSM frame
goes out with one bit flipped (a bad CRC the receiving end must count and drop).

Runs until killed (or --seconds); prints `connected` once the server took the
connection, then one line per epoch sent. Exit code 1 if the server cannot be reached
within 10 s.

    python3 tests/peers/rtcm_base.py --port 2102 --lat 47.3977 --lon 8.5456 --alt 488
"""

import argparse
import io
import math
import socket
import sys
import time

from pyrtcm import RTCMMessage, RTCMReader

WGS84_A = 6378137.0
WGS84_F = 1 / 298.257223563


class Bits:
    """Packs unsigned and two's-complement fields most significant bit first."""

    def __init__(self):
        self.value = 0
        self.length = 0

    def put(self, width, v, signed=False):
        if signed and v < 0:
            v += 1 << width
        assert 0 <= v < (1 << width), (width, v)
        self.value = (self.value << width) | v
        self.length += width

    def bytes(self):
        pad = (-self.length) % 8
        return (self.value << pad).to_bytes((self.length + pad) // 8, "big")


def ecef(lat_deg, lon_deg, alt_m):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    e2 = WGS84_F * (2 - WGS84_F)
    n = WGS84_A / math.sqrt(1 - e2 * math.sin(lat) ** 2)
    return (
        (n + alt_m) * math.cos(lat) * math.cos(lon),
        (n + alt_m) * math.cos(lat) * math.sin(lon),
        (n * (1 - e2) + alt_m) * math.sin(lat),
    )


def msg_1005(station_id, position):
    """Stationary RTK reference station ARP (DF002, DF003, DF021-DF024, DF141, DF025,
    DF142, DF001, DF026, DF364, DF027)."""
    x, y, z = (round(c * 10000) for c in position)
    b = Bits()
    b.put(12, 1005)
    b.put(12, station_id)
    b.put(6, 0)  # ITRF realization year
    b.put(1, 1)  # GPS
    b.put(1, 0)  # GLONASS
    b.put(1, 1)  # Galileo
    b.put(1, 0)  # reference station
    b.put(38, x, signed=True)
    b.put(1, 0)  # single receiver oscillator
    b.put(1, 0)  # reserved
    b.put(38, y, signed=True)
    b.put(2, 0)  # quarter cycle indicator
    b.put(38, z, signed=True)
    return b.bytes()


def msg_1074(station_id, tow_ms, satellites):
    """GPS MSM4: header (DF002, DF003, DF004, DF393, DF409, DF001, DF411, DF412, DF417,
    DF418, DF394, DF395, DF396), satellite data (DF397, DF398), signal data (DF400,
    DF401, DF402, DF420, DF403) for L1 C/A (signal 2) of each satellite."""
    b = Bits()
    b.put(12, 1074)
    b.put(12, station_id)
    b.put(30, tow_ms % (7 * 24 * 3600 * 1000))
    b.put(1, 0)  # multiple message bit: the last of the epoch
    b.put(3, 0)  # IODS
    b.put(7, 0)  # reserved
    b.put(2, 0)  # clock steering
    b.put(2, 0)  # external clock
    b.put(1, 0)  # smoothing
    b.put(3, 0)  # smoothing interval
    sat_mask = 0
    for prn in satellites:
        sat_mask |= 1 << (64 - prn)
    b.put(64, sat_mask)
    b.put(32, 1 << (32 - 2))  # signal mask: 1C
    b.put(len(satellites), (1 << len(satellites)) - 1)  # cell mask: every cell
    ranges = [(20_000_000 + 37_000 * prn + 11 * (tow_ms // 1000)) / 299_792.458 for prn in satellites]
    for r in ranges:
        b.put(8, int(r))  # rough range, whole milliseconds
    for r in ranges:
        b.put(10, int((r % 1) * 1024))  # rough range modulo 1 ms, 2^-10 ms
    for i, _ in enumerate(satellites):
        b.put(15, (i * 97) % 2000 - 1000, signed=True)  # fine pseudorange
    for i, _ in enumerate(satellites):
        b.put(22, (i * 4099) % 60000 - 30000, signed=True)  # fine phase range
    for _ in satellites:
        b.put(4, 12)  # lock time indicator
    for _ in satellites:
        b.put(1, 0)  # half-cycle ambiguity
    for i, _ in enumerate(satellites):
        b.put(6, 40 + i % 8)  # CNR, dB-Hz
    return b.bytes()


def frame(payload, expect):
    """pyrtcm's frame of `payload`, checked by reading it back with pyrtcm."""
    raw = RTCMMessage(payload=payload).serialize()
    parsed = RTCMReader(io.BytesIO(raw)).read()[1]
    if parsed is None or parsed.identity != str(expect):
        raise SystemExit(f"pyrtcm could not read back message {expect}: {parsed}")
    return raw


def connect(port):
    deadline = time.time() + 10
    while True:
        try:
            return socket.create_connection(("127.0.0.1", port), timeout=5)
        except OSError:
            if time.time() > deadline:
                print(f"no server on port {port}", file=sys.stderr)
                sys.exit(1)
            time.sleep(0.1)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--port", type=int, required=True, help="the TCP server to stream to")
    p.add_argument("--lat", type=float, required=True, help="base latitude, degrees")
    p.add_argument("--lon", type=float, required=True, help="base longitude, degrees")
    p.add_argument("--alt", type=float, default=500.0, help="base ellipsoid height, m")
    p.add_argument("--station-id", type=int, default=42)
    p.add_argument("--corrupt-every", type=int, default=0, help="flip a bit of every Nth MSM frame")
    p.add_argument("--seconds", type=float, default=0.0, help="stop after this long (0: never)")
    args = p.parse_args()

    position = ecef(args.lat, args.lon, args.alt)
    sock = connect(args.port)
    print("connected", flush=True)
    satellites = [2, 5, 9, 12, 17, 21, 25, 30]
    started = time.time()
    epoch = 0
    while args.seconds <= 0 or time.time() - started < args.seconds:
        tow_ms = int(time.time() * 1000) % (7 * 24 * 3600 * 1000)
        base = frame(msg_1005(args.station_id, position), 1005)
        obs = bytearray(frame(msg_1074(args.station_id, tow_ms, satellites), 1074))
        corrupt = args.corrupt_every and epoch % args.corrupt_every == args.corrupt_every - 1
        if corrupt:
            obs[len(obs) // 2] ^= 0x10
        sock.sendall(base + bytes(obs))
        print(f"epoch {epoch} {len(base) + len(obs)} bytes{' corrupt' if corrupt else ''}", flush=True)
        epoch += 1
        time.sleep(max(0.0, started + epoch - time.time()))


if __name__ == "__main__":
    main()
