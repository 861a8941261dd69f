#!/usr/bin/env python3
"""pymavlink plays the autopilots of a fleet with Remote ID transmitters and records what
the ground station sends for Remote ID (ASTM F3411 through MAVLink's Open Drone ID).

Vehicle i (sysid i+1) talks to the ground station's UDP port PORT+i from a socket of its
own, as PX4 does: a 1 Hz HEARTBEAT from its autopilot (compid 1), and, from its Remote
ID transmitter (compid 236, MAV_COMP_ID_ODID_TXRX_1), a 1 Hz OPEN_DRONE_ID_ARM_STATUS
that says PRE_ARM_FAIL_GENERIC "operator ID missing" until an OPEN_DRONE_ID_OPERATOR_ID
for it arrived, then GOOD_TO_ARM. It records every OPEN_DRONE_ID_SYSTEM and
OPEN_DRONE_ID_OPERATOR_ID addressed to it for --seconds after the first one, and with
--until-type T on until every vehicle's latest OPEN_DRONE_ID_SYSTEM has
operator_location_type T (the ground station's operator location fell back to it).

Prints one JSON line: {"<sysid>": {"system": {"count", "rate_hz", "last": {fields},
"changes": [...]}, "operator_id": {"count", "rate_hz", "last": {fields}}}}; the rate is
(count - 1) over the time between the first and the last; "changes" lists each
OPEN_DRONE_ID_SYSTEM whose operator_location_type differs from the one before (the first
included) as {"unix_s", "operator_location_type", "operator_latitude",
"operator_longitude", "operator_altitude_geo"}. Exit code 0 only if every vehicle heard
both (and, with --until-type, reached that type).

    python3 tests/peers/remote_id_pymavlink.py --port PORT --vehicles 3 --seconds 6 \
        [--until-type 2]
"""

import argparse
import json
import os
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

ODID_COMPID = 236
KINDS = {"OPEN_DRONE_ID_SYSTEM": "system", "OPEN_DRONE_ID_OPERATOR_ID": "operator_id"}
LOCATION_FIELDS = (
    "operator_location_type",
    "operator_latitude",
    "operator_longitude",
    "operator_altitude_geo",
)


class Vehicle:
    def __init__(self, port, sysid):
        self.sysid = sysid
        self.autopilot = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=sysid, source_component=1
        )
        # The transmitter shares the autopilot's socket (PX4 routes its messages).
        self.transmitter = mavutil.mavlink.MAVLink(
            self.autopilot, srcSystem=sysid, srcComponent=ODID_COMPID
        )
        self.heard = {kind: [] for kind in KINDS.values()}
        self.last = {}
        self.changes = []
        self.operator_heard = False
        self.next_beat = 0.0

    def beat(self, now):
        if now < self.next_beat:
            return
        self.next_beat = now + 1.0
        mav = mavutil.mavlink
        self.autopilot.mav.heartbeat_send(
            mav.MAV_TYPE_QUADROTOR,
            mav.MAV_AUTOPILOT_PX4,
            mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            (4 << 16) | (3 << 24),  # AUTO.LOITER
            mav.MAV_STATE_STANDBY,
        )
        if self.operator_heard:
            status, error = mav.MAV_ODID_ARM_STATUS_GOOD_TO_ARM, b""
        else:
            status, error = mav.MAV_ODID_ARM_STATUS_PRE_ARM_FAIL_GENERIC, b"operator ID missing"
        self.transmitter.open_drone_id_arm_status_send(status, error)

    def read(self, now):
        while True:
            m = self.autopilot.recv_match(blocking=False)
            if m is None:
                return
            kind = KINDS.get(m.get_type())
            if kind is None or m.target_system != self.sysid:
                continue
            self.heard[kind].append(now)
            fields = m.to_dict()
            fields.pop("mavpackettype", None)
            if kind == "operator_id":
                self.operator_heard = True
                fields["operator_id"] = fields["operator_id"].rstrip("\x00")
            fields["id_or_mac"] = list(fields["id_or_mac"])
            if kind == "system" and (
                not self.changes
                or self.changes[-1]["operator_location_type"] != fields["operator_location_type"]
            ):
                change = {"unix_s": time.time()}
                for key in LOCATION_FIELDS:
                    change[key] = fields[key]
                self.changes.append(change)
            self.last[kind] = fields

    def first(self):
        times = [t[0] for t in self.heard.values() if t]
        return min(times) if times else None

    def report(self):
        out = {}
        for kind, times in self.heard.items():
            span = times[-1] - times[0] if len(times) > 1 else 0.0
            out[kind] = {
                "count": len(times),
                "rate_hz": (len(times) - 1) / span if span > 0 else 0.0,
                "last": self.last.get(kind),
            }
        out["system"]["changes"] = self.changes
        return out

    def location_type(self):
        system = self.last.get("system")
        return system["operator_location_type"] if system else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--vehicles", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--until-type", type=int, default=None)
    args = ap.parse_args()
    vehicles = [Vehicle(args.port + i, i + 1) for i in range(args.vehicles)]
    deadline = time.monotonic() + args.timeout
    while time.monotonic() < deadline:
        now = time.monotonic()
        for v in vehicles:
            v.beat(now)
            v.read(now)
        firsts = [v.first() for v in vehicles]
        long_enough = all(f is not None and now - f >= args.seconds for f in firsts)
        reached = args.until_type is None or all(
            v.location_type() == args.until_type for v in vehicles
        )
        if long_enough and reached:
            break
        time.sleep(0.01)
    report = {str(v.sysid): v.report() for v in vehicles}
    print(json.dumps(report))
    heard_all = all(r[k]["count"] > 0 for r in report.values() for k in KINDS.values())
    reached = args.until_type is None or all(
        v.location_type() == args.until_type for v in vehicles
    )
    sys.exit(0 if heard_all and reached else 1)


if __name__ == "__main__":
    main()
