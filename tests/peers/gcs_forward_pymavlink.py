#!/usr/bin/env python3
"""pymavlink as QGroundControl on skein's ground-station forward (``skein up --sim N
--gcs-forward udpout:127.0.0.1:PORT``): listens on ``udpin:127.0.0.1:PORT`` as QGC
listens on 14550, as sysid 255 / compid 190, and checks, in order:

1. HEARTBEATs of N autopilots with N distinct sysids arrive (each vehicle's frames are
   forwarded with its own sysid);
2. a COMMAND_LONG MAV_CMD_DO_SET_MODE (POSCTL: main mode 3) to sysid 2 reaches that
   vehicle only: its HEARTBEAT custom_mode becomes 196608 and the API shows uav-2 in
   POSCTL, the others stay in HOLD;
3. a SET_POSITION_TARGET_LOCAL_NED to sysid 2 is dropped by skein and counted
   (``gcs_forward.setpoints_dropped`` in GET /api/v1/links).

Exit code 0 only on full success; the last line printed is a JSON summary.
"""

import argparse
import json
import os
import time
import urllib.request

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

HOLD = 50593792
POSCTL = 196608


class Failure(Exception):
    pass


def api(base, path):
    with urllib.request.urlopen(base + path, timeout=10) as r:
        return json.loads(r.read())


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--api", required=True, help="skein's base URL")
    ap.add_argument("--vehicles", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=90.0)
    args = ap.parse_args()
    deadline = time.monotonic() + args.timeout
    m = mavutil.mavlink_connection(
        f"udpin:127.0.0.1:{args.port}", source_system=255, source_component=190
    )
    modes = {}
    last_hb = 0.0
    summary = {}

    def pump(seconds):
        nonlocal last_hb
        end = min(time.monotonic() + seconds, deadline)
        while time.monotonic() < end:
            now = time.monotonic()
            if modes and now - last_hb >= 1.0:  # QGC's 1 Hz heartbeat, once skein spoke
                m.mav.heartbeat_send(
                    mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0
                )
                last_hb = now
            msg = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.05)
            if msg is not None and msg.autopilot != mavutil.mavlink.MAV_AUTOPILOT_INVALID:
                modes[msg.get_srcSystem()] = msg.custom_mode
        if time.monotonic() >= deadline:
            raise Failure("global timeout")

    def wait(what, timeout, pred):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            pump(0.1)
            if pred():
                return
        raise Failure(f"timed out after {timeout} s waiting for {what}; modes {modes}")

    def px4_modes():
        return {v["sysid"]: v.get("px4_mode") for v in api(args.api, "/api/v1/vehicles")}

    try:
        wanted = set(range(1, args.vehicles + 1))
        wait(f"heartbeats of sysids {sorted(wanted)}", 30, lambda: wanted <= set(modes))
        summary["sysids"] = sorted(modes)
        wait("every vehicle in HOLD", 30, lambda: all(modes.get(s) == HOLD for s in wanted))
        print(f"heartbeats from sysids {sorted(modes)}", flush=True)

        m.mav.command_long_send(
            2, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE, 0,
            mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 3, 0, 0, 0, 0, 0,
        )
        wait("sysid 2 in POSCTL", 15, lambda: modes.get(2) == POSCTL)
        wait("the API showing uav-2 in POSCTL", 10, lambda: px4_modes().get(2) == "POSCTL")
        pump(1.5)
        others = {s: modes[s] for s in wanted - {2}}
        if any(mode != HOLD for mode in others.values()):
            raise Failure(f"DO_SET_MODE to sysid 2 changed others: {others}")
        summary["api_modes"] = px4_modes()
        print("DO_SET_MODE reached sysid 2 only", flush=True)

        def dropped():
            for link in api(args.api, "/api/v1/links"):
                if "gcs_forward" in link:
                    return link["gcs_forward"]["setpoints_dropped"]
            raise Failure("no gcs_forward entry in /api/v1/links")

        before = dropped()
        m.mav.set_position_target_local_ned_send(
            0, 2, 1, mavutil.mavlink.MAV_FRAME_LOCAL_NED, 2552, 0, 0, -5, 0, 0, 0, 0, 0, 0, 0, 0
        )
        wait("the setpoint counted as dropped", 10, lambda: dropped() > before)
        summary["setpoints_dropped"] = dropped() - before
        print("SET_POSITION_TARGET_LOCAL_NED dropped and counted", flush=True)
    except Failure as e:
        summary["error"] = str(e)
        print(json.dumps(summary))
        raise SystemExit(1)
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
