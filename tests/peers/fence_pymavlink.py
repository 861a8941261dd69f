#!/usr/bin/env python3
"""pymavlink as a second ground station on skein's ground-station forward (``skein up
--gcs-forward udpout:127.0.0.1:PORT``) reads every autopilot's geofence and rally points
with the MAVLink mission protocol, as QGroundControl does: MISSION_REQUEST_LIST,
MISSION_COUNT, MISSION_REQUEST_INT / MISSION_ITEM_INT for each item, MISSION_ACK;
requests resent after 1.5 s, at most 5 times. It speaks as sysid 254 (skein itself is
255), so skein's own mission client ignores the answers.

Prints one JSON line: {"<sysid>": {"fence": [item...], "rally": [item...]}}, each item
{"command", "param1", "lat_deg", "lon_deg", "z"}; exit code 0 only if every vehicle
answered.

    python3 tests/peers/fence_pymavlink.py --port PORT --vehicles 3
"""

import argparse
import json
import os
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

ME = (254, 190)
TIMEOUT_S = 1.5
ATTEMPTS = 5


class Failure(Exception):
    pass


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--vehicles", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=45.0)
    args = ap.parse_args()
    deadline = time.monotonic() + args.timeout
    m = mavutil.mavlink_connection(
        f"udpin:127.0.0.1:{args.port}", source_system=ME[0], source_component=ME[1]
    )
    mav = mavutil.mavlink
    last_hb = 0.0

    def heartbeat():
        nonlocal last_hb
        if time.monotonic() - last_hb >= 1.0:
            m.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            last_hb = time.monotonic()

    def answer(sysid, kind, accept, send):
        """Sends with send() until a message of `kind` from sysid, addressed to us, that
        accept() takes (returning a value) arrives."""
        for _ in range(ATTEMPTS):
            send()
            end = time.monotonic() + TIMEOUT_S
            while time.monotonic() < end:
                if time.monotonic() > deadline:
                    raise Failure("global timeout")
                heartbeat()
                msg = m.recv_match(type=kind, blocking=True, timeout=0.05)
                if msg is None or msg.get_srcSystem() != sysid:
                    continue
                if getattr(msg, "target_system", ME[0]) != ME[0]:
                    continue
                v = accept(msg)
                if v is not None:
                    return v
        raise Failure(f"sysid {sysid}: no {kind} after {ATTEMPTS} tries")

    def download(sysid, mission_type):
        count = answer(
            sysid, "MISSION_COUNT",
            lambda c: c.count if c.mission_type == mission_type else None,
            lambda: m.mav.mission_request_list_send(sysid, 1, mission_type),
        )
        items = []
        for seq in range(count):
            item = answer(
                sysid, "MISSION_ITEM_INT",
                lambda i, seq=seq: i if i.seq == seq and i.mission_type == mission_type else None,
                lambda seq=seq: m.mav.mission_request_int_send(sysid, 1, seq, mission_type),
            )
            items.append({
                "command": mav.enums["MAV_CMD"][item.command].name,
                "param1": item.param1,
                "lat_deg": item.x * 1e-7,
                "lon_deg": item.y * 1e-7,
                "z": item.z,
            })
        m.mav.mission_ack_send(sysid, 1, mav.MAV_MISSION_ACCEPTED, mission_type)
        return items

    # Wait for skein to forward the vehicles' heartbeats (it sends once we are heard).
    seen = set()
    while len(seen) < args.vehicles:
        if time.monotonic() > deadline:
            raise Failure(f"heartbeats of {sorted(seen)} only")
        heartbeat()
        hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.1)
        if hb is not None and hb.autopilot != mav.MAV_AUTOPILOT_INVALID:
            seen.add(hb.get_srcSystem())
    out = {}
    for sysid in sorted(seen):
        out[str(sysid)] = {
            "fence": download(sysid, mav.MAV_MISSION_TYPE_FENCE),
            "rally": download(sysid, mav.MAV_MISSION_TYPE_RALLY),
        }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Failure as e:
        print(json.dumps({"error": str(e)}))
        sys.exit(1)
