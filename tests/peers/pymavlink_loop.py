#!/usr/bin/env python3
"""A plain pymavlink control loop, the baseline `skein bench swarm --peer pymavlink`
measures skein against in the same run.

What a user comparing controllers would write: one pymavlink `udpin` connection per
vehicle (the port the vehicle sends to, as skein's per-vehicle endpoints), a 1 Hz
heartbeat, and one loop that every period sends each vehicle a position setpoint
(SET_POSITION_TARGET_LOCAL_NED, type_mask 2552) and reads whatever telemetry arrived. It
takes every vehicle off in OFFBOARD (stream first, then DO_SET_MODE and arm, as PX4
v1.16 accepts) to --altitude-m, prints ``ready`` once all hover, waits for a ``go`` line
on stdin, measures its own CPU time over --seconds of hovering and prints one JSON line:

    {"vehicles": N, "rate_hz": R, "seconds": S, "cpu_s": C, "setpoints_sent": K,
     "messages_received": M, "late_loops": L}

    pymavlink_loop.py --base-port P --vehicles N [--rate-hz 50] [--seconds 10]
"""

import argparse
import json
import os
import select
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

POSITION_YAW = 2552  # type_mask: position + yaw (skein_model::px4::type_mask)
PX4_OFFBOARD_MAIN_MODE = 6


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--base-port", type=int, required=True, help="vehicle i sends to this + i")
    p.add_argument("--vehicles", type=int, required=True)
    p.add_argument("--rate-hz", type=float, default=50.0)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--altitude-m", type=float, default=2.0)
    p.add_argument("--timeout", type=float, default=120.0, help="longest setup, s")
    return p.parse_args()


class Vehicle:
    def __init__(self, port):
        self.conn = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", source_system=255, source_component=190
        )
        self.sysid = None
        self.position = None  # (x, y, z) local NED
        self.hold = None
        self.armed = False
        self.offboard = False

    def drain(self):
        n = 0
        while True:
            m = self.conn.recv_msg()
            if m is None:
                return n
            n += 1
            t = m.get_type()
            if t == "HEARTBEAT" and m.autopilot != mavutil.mavlink.MAV_AUTOPILOT_INVALID:
                self.sysid = m.get_srcSystem()
                self.armed = bool(m.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                self.offboard = (m.custom_mode >> 16) & 0xFF == PX4_OFFBOARD_MAIN_MODE
            elif t == "LOCAL_POSITION_NED":
                self.position = (m.x, m.y, m.z)

    def setpoint(self, boot_ms):
        x, y, z = self.hold
        self.conn.mav.set_position_target_local_ned_send(
            boot_ms, self.sysid, 1, mavutil.mavlink.MAV_FRAME_LOCAL_NED, POSITION_YAW,
            x, y, z, 0, 0, 0, 0, 0, 0, 0, 0,
        )

    def command(self, cmd, *params):
        p = list(params) + [0] * (7 - len(params))
        self.conn.mav.command_long_send(self.sysid, 1, cmd, 0, *p)


def main():
    a = parse_args()
    vehicles = [Vehicle(a.base_port + i) for i in range(a.vehicles)]
    period = 1.0 / a.rate_hz
    start = time.monotonic()
    deadline = start + a.timeout
    next_beat = 0.0
    next_tick = time.monotonic()
    sent = received = late = 0
    phase = "waiting"  # waiting → climbing → ready → measuring
    measuring_until = cpu0 = None
    while True:
        now = time.monotonic()
        if now >= next_beat:
            for v in vehicles:
                v.conn.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                          mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            next_beat = now + 1.0
        for v in vehicles:
            received += v.drain()
        if phase == "waiting" and all(v.sysid and v.position for v in vehicles):
            for v in vehicles:
                x, y, z = v.position
                v.hold = (x, y, z - a.altitude_m)
            phase = "climbing"
        if phase != "waiting":
            boot_ms = int((now - start) * 1000) & 0xFFFFFFFF
            for v in vehicles:
                v.setpoint(boot_ms)
                sent += 1
                # Offboard needs the stream first (PX4 v1.16: one setpoint is enough).
                if phase == "climbing" and not v.offboard:
                    v.command(mavutil.mavlink.MAV_CMD_DO_SET_MODE,
                              mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                              PX4_OFFBOARD_MAIN_MODE)
                elif phase == "climbing" and not v.armed:
                    v.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        if phase == "climbing" and all(
            v.armed and v.offboard and abs(v.position[2] - v.hold[2]) < 0.5 for v in vehicles
        ):
            phase = "ready"
            print("ready", flush=True)
        # The bench says when to measure; the setpoints keep streaming meanwhile.
        if phase == "ready" and select.select([sys.stdin], [], [], 0)[0]:
            if sys.stdin.readline().strip() != "go":
                return 1
            phase = "measuring"
            sent = received = late = 0
            cpu0 = time.process_time()
            measuring_until = time.monotonic() + a.seconds
            next_tick = time.monotonic()
        if phase == "measuring" and time.monotonic() >= measuring_until:
            cpu = time.process_time() - cpu0
            print(json.dumps({
                "vehicles": a.vehicles, "rate_hz": a.rate_hz, "seconds": a.seconds,
                "cpu_s": round(cpu, 3), "setpoints_sent": sent,
                "messages_received": received, "late_loops": late,
            }), flush=True)
            return 0
        if phase in ("waiting", "climbing") and time.monotonic() > deadline:
            unheard = [i for i, v in enumerate(vehicles) if not v.sysid]
            unplaced = [i for i, v in enumerate(vehicles) if v.sysid and not v.position]
            print(json.dumps({"error": f"not all {a.vehicles} vehicles hovering in "
                                       f"{a.timeout} s (phase {phase}; no HEARTBEAT from "
                                       f"vehicles {unheard[:10]}, no LOCAL_POSITION_NED "
                                       f"from {unplaced[:10]})"}), flush=True)
            return 1
        next_tick += period
        pause = next_tick - time.monotonic()
        if pause > 0:
            time.sleep(pause)
        else:
            late += 1
            if pause < -period:
                next_tick = time.monotonic()


if __name__ == "__main__":
    sys.exit(main())
