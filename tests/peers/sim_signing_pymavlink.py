#!/usr/bin/env python3
"""pymavlink against a simulator that requires MAVLink 2 signing (``skein sim
--signing-key-file FILE``, PX4 ``MAV_SIGN_CFG`` 2).

Listens where the vehicle sends (``udpin:127.0.0.1:PORT``) and checks, in order:

1. without the key: the vehicle's (signed) telemetry arrives, but NAV_TAKEOFF and arm
   sent unsigned get no COMMAND_ACK, the vehicle stays disarmed for 3 s, and the
   simulator's unsigned-drop counter (stats socket ``--stats``) rises;
2. with the key (``mav.setup_signing``): NAV_TAKEOFF and arm are accepted, the vehicle
   arms and climbs above 2 m (GLOBAL_POSITION_INT.relative_alt), and the simulator
   counts our frames as validly signed.

Exit code 0 only on full success; the last line printed is a JSON summary.
"""

import argparse
import json
import os
import socket
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

ARMED = 128  # MAV_MODE_FLAG_SAFETY_ARMED


class Failure(Exception):
    pass


def sim_stats(addr):
    host, port = addr.rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall(b"stats\n")
        line = s.makefile().readline()
    return json.loads(line)["vehicles"][0]


class Peer:
    def __init__(self, port, deadline):
        self.deadline = deadline
        self.m = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", source_system=250, source_component=191
        )
        self.sysid = None
        self.armed = False
        self.relative_alt_m = 0.0
        self.acks = []
        self.last_hb = 0.0

    def pump(self, seconds):
        """Reads for `seconds`, sending our heartbeat at 1 Hz once the vehicle spoke."""
        end = min(time.monotonic() + seconds, self.deadline)
        while time.monotonic() < end:
            msg = self.m.recv_match(blocking=True, timeout=0.05)
            now = time.monotonic()
            if self.sysid is not None and now - self.last_hb >= 1.0:
                self.m.mav.heartbeat_send(
                    mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0
                )
                self.last_hb = now
            if msg is None:
                continue
            t = msg.get_type()
            if t == "HEARTBEAT" and msg.autopilot != mavutil.mavlink.MAV_AUTOPILOT_INVALID:
                self.sysid = msg.get_srcSystem()
                self.armed = bool(msg.base_mode & ARMED)
            elif t == "GLOBAL_POSITION_INT":
                self.relative_alt_m = msg.relative_alt / 1000.0
            elif t == "COMMAND_ACK":
                self.acks.append((msg.command, msg.result))
        if time.monotonic() >= self.deadline:
            raise Failure("global timeout")

    def wait(self, what, timeout, pred):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.pump(0.1)
            if pred():
                return
        raise Failure(f"timed out after {timeout} s waiting for {what}")

    def command(self, cmd, *params):
        p = list(params) + [0.0] * (7 - len(params))
        self.m.mav.command_long_send(self.sysid, 1, cmd, 0, *p)

    def takeoff_and_arm(self):
        nan = float("nan")
        self.command(mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, nan, nan, nan, nan)
        self.pump(0.3)
        self.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--key-file", required=True)
    ap.add_argument("--stats", required=True, help="simulator stats socket host:port")
    ap.add_argument("--timeout", type=float, default=90.0)
    args = ap.parse_args()
    key = bytes.fromhex(open(args.key_file).read().strip())
    summary = {}
    peer = Peer(args.port, time.monotonic() + args.timeout)
    try:
        peer.wait("the vehicle's heartbeat", 20, lambda: peer.sysid is not None)
        peer.wait("a position", 20, lambda: peer.m.messages.get("GLOBAL_POSITION_INT") is not None)
        # The signed flag (incompat_flags bit 0); pymavlink's get_signed() is only set
        # once it verifies signatures itself.
        signed_in = bool(peer.m.messages["HEARTBEAT"].get_msgbuf()[2] & 1)
        summary["vehicle_frames_signed"] = signed_in
        if not signed_in:
            raise Failure("the signed simulator sent an unsigned HEARTBEAT")

        # 1. Without the key.
        before = sim_stats(args.stats)["signing"]["unsigned"]
        for _ in range(3):
            peer.takeoff_and_arm()
            peer.pump(1.0)
        if peer.armed or peer.acks:
            raise Failure(f"unsigned commands were obeyed: armed={peer.armed} acks={peer.acks}")
        after = sim_stats(args.stats)["signing"]["unsigned"]
        summary["unsigned_dropped"] = after - before
        if after - before < 6:
            raise Failure(f"unsigned-drop counter rose by {after - before}, expected >= 6")
        print(f"without the key: ignored, {after - before} unsigned frames dropped", flush=True)

        # 2. With the key.
        peer.m.setup_signing(key, sign_outgoing=True)
        peer.takeoff_and_arm()
        peer.wait("arm accepted", 15, lambda: (400, 0) in peer.acks)
        peer.wait("armed in the heartbeat", 10, lambda: peer.armed)
        peer.wait("climbing above 2 m", 30, lambda: peer.relative_alt_m > 2.0)
        stats = sim_stats(args.stats)["signing"]
        summary["signed_ok"] = stats["signed_ok"]
        summary["relative_alt_m"] = peer.relative_alt_m
        if stats["signed_ok"] < 2:
            raise Failure(f"the simulator counted {stats['signed_ok']} signed frames")
        print(f"with the key: armed, climbed to {peer.relative_alt_m:.1f} m", flush=True)
    except Failure as e:
        summary["error"] = str(e)
        print(json.dumps(summary))
        raise SystemExit(1)
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
