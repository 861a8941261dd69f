#!/usr/bin/env python3
"""Fly skein's simulator (or PX4 SITL) with pymavlink, an independent MAVLink stack.

Listens where the vehicle sends (``udpin:127.0.0.1:PORT``, i.e. the vehicle's target
port, 14540+i for PX4 SITL instance i) and checks, in order:

1. every frame decodes: zero CRC/parse errors over ``--seconds`` of telemetry (messages
   unknown to pymavlink's dialect are CRC-checked here with their CRC_EXTRA);
2. the rate of every message of PX4's onboard-link table is within 20 %;
3. parameters: read MIS_TAKEOFF_ALT, set a float and a bytewise int32 parameter, each
   PARAM_SET answered by two PARAM_VALUEs;
4. OFFBOARD without a setpoint stream is refused (second COMMAND_ACK not ACCEPTED,
   mode stays), so it is with a stream gone stale, and a fresh setpoint is enough (PX4
   v1.16);
5. arm, climb with a position setpoint to z = -5 +/- 0.5 m (LOCAL_POSITION_NED);
6. NAV_LAND, landing, auto-disarm seen in HEARTBEAT.

Every wait has a deadline inside the global ``--timeout``. Exit code 0 only on full
success; the last line printed is a JSON summary.
"""

import argparse
import json
import math
import os
import struct
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402
from pymavlink.generator.mavcrc import x25crc  # noqa: E402

# px4.md: PX4 v1.16 onboard-link telemetry, Hz.
EXPECTED_RATES = {
    "ATTITUDE": 100,
    "HIGHRES_IMU": 50,
    "ATTITUDE_QUATERNION": 50,
    "GLOBAL_POSITION_INT": 50,
    "LOCAL_POSITION_NED": 30,
    "ODOMETRY": 30,
    "TIMESYNC": 10,
    "ALTITUDE": 10,
    "DISTANCE_SENSOR": 10,
    "ATTITUDE_TARGET": 10,
    "POSITION_TARGET_LOCAL_NED": 10,
    "SERVO_OUTPUT_RAW": 10,
    "VFR_HUD": 10,
    "GPS_RAW_INT": 8,
    "EXTENDED_SYS_STATE": 5,
    "SYS_STATUS": 5,
    "HEARTBEAT": 1,
    "ESTIMATOR_STATUS": 1,
    "PING": 1,
    "SYSTEM_TIME": 1,
    "SCALED_PRESSURE": 1,
    "MISSION_CURRENT": 1,
    "LINK_NODE_STATUS": 1,
    "BATTERY_STATUS": 0.5,
    "CURRENT_MODE": 0.5,
    "HOME_POSITION": 0.5,
    "VIBRATION": 0.5,
}

# Messages PX4 sends that pymavlink's dialects may not know: name and wire-order fields
# (an array's length third), to compute CRC_EXTRA as mavgen does.
EXTRA_DEFINITIONS = {
    8: (
        "LINK_NODE_STATUS",
        [
            ("uint64_t", "timestamp"),
            ("uint32_t", "tx_rate"),
            ("uint32_t", "rx_rate"),
            ("uint32_t", "messages_sent"),
            ("uint32_t", "messages_received"),
            ("uint32_t", "messages_lost"),
            ("uint16_t", "rx_parse_err"),
            ("uint16_t", "tx_overflows"),
            ("uint16_t", "rx_overflows"),
            ("uint8_t", "tx_buf"),
            ("uint8_t", "rx_buf"),
        ],
    ),
    # PX4's events interface (common.xml; older pymavlink dialects lack it).
    410: (
        "EVENT",
        [
            ("uint32_t", "id"),
            ("uint32_t", "event_time_boot_ms"),
            ("uint16_t", "sequence"),
            ("uint8_t", "destination_component"),
            ("uint8_t", "destination_system"),
            ("uint8_t", "log_levels"),
            ("uint8_t", "arguments", 40),
        ],
    ),
    411: ("CURRENT_EVENT_SEQUENCE", [("uint16_t", "sequence"), ("uint8_t", "flags")]),
}

HOLD = 50593792
OFFBOARD = 393216
LAND = 100925440
POSITION_YAW_MASK = 2552
MAV_RESULT_ACCEPTED = 0


def crc_extra(name, fields):
    crc = x25crc((name + " ").encode())
    for ftype, fname, *array_length in fields:
        crc.accumulate_str(ftype + " ")
        crc.accumulate_str(fname + " ")
        if array_length:
            crc.accumulate(array_length)
    return (crc.crc & 0xFF) ^ (crc.crc >> 8)


EXTRA_CRCS = {mid: (name, crc_extra(name, fields)) for mid, (name, fields) in EXTRA_DEFINITIONS.items()}


class Failure(Exception):
    pass


class Peer:
    def __init__(self, port, sysid, timeout):
        self.deadline = time.monotonic() + timeout
        self.sysid = sysid
        self.m = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", dialect="development", source_system=250, source_component=191
        )
        self.frames = 0
        self.bad = []
        self.unknown_verified = {}
        self.unknown_unverified = {}
        self.arrivals = {}
        self.record_rates = False
        self.last_hb_sent = 0.0
        self.stream = None  # (x, y, z) position setpoint to stream at 20 Hz
        self.last_sp_sent = 0.0
        self.sp_sent = 0
        self.last_heartbeat = None
        self.checks = []

    # ------------------------------------------------------------------ plumbing
    def remaining(self):
        return self.deadline - time.monotonic()

    def duties(self):
        now = time.monotonic()
        if self.frames > 0:  # udpin: replies go to whoever sent last; wait for the vehicle
            if now - self.last_hb_sent >= 1.0:
                self.m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                self.last_hb_sent = now
            if self.stream is not None and now - self.last_sp_sent >= 0.05:
                x, y, z = self.stream
                self.m.mav.set_position_target_local_ned_send(
                    0, self.sysid, 1, mavutil.mavlink.MAV_FRAME_LOCAL_NED, POSITION_YAW_MASK,
                    x, y, z, 0, 0, 0, 0, 0, 0, 0.0, 0.0,
                )
                self.last_sp_sent = now
                self.sp_sent += 1

    def account(self, msg):
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.bad.append(str(getattr(msg, "reason", "bad data")))
            return None
        if mtype.startswith("UNKNOWN_"):
            self.check_unknown(msg)
            return None
        if msg.get_srcSystem() != self.sysid:
            return msg
        self.frames += 1
        if self.record_rates:
            self.arrivals.setdefault(mtype, []).append(time.monotonic())
        if mtype == "HEARTBEAT" and msg.get_srcComponent() == 1:
            self.last_heartbeat = msg
        return msg

    def check_unknown(self, msg):
        data = bytes(msg.data)
        mid = data[7] | (data[8] << 8) | (data[9] << 16) if len(data) >= 10 else -1
        if len(data) < 12 or data[0] != 0xFD or mid not in EXTRA_CRCS:
            self.unknown_unverified[mid] = self.unknown_unverified.get(mid, 0) + 1
            return
        name, extra = EXTRA_CRCS[mid]
        plen = data[1]
        crc = x25crc(data[1 : 10 + plen])
        crc.accumulate([extra])
        (got,) = struct.unpack("<H", data[10 + plen : 12 + plen])
        if got != crc.crc:
            self.bad.append(f"bad CRC in {name}")
            return
        if data[5] == self.sysid:
            self.frames += 1
            self.unknown_verified[name] = self.unknown_verified.get(name, 0) + 1
            if self.record_rates:
                self.arrivals.setdefault(name, []).append(time.monotonic())

    def recv(self, timeout):
        self.duties()
        msg = self.m.recv_match(blocking=True, timeout=max(0.001, min(timeout, 0.02)))
        if msg is None:
            return None
        return self.account(msg)

    def wait(self, what, pred, timeout):
        end = time.monotonic() + min(timeout, max(0.0, self.remaining()))
        while time.monotonic() < end:
            msg = self.recv(end - time.monotonic())
            if msg is not None and pred(msg):
                return msg
        raise Failure(f"timed out waiting for {what}")

    def check(self, name, ok, detail=""):
        self.checks.append({"check": name, "ok": bool(ok), "detail": detail})
        if not ok:
            raise Failure(f"{name}: {detail}")

    # ------------------------------------------------------------------ helpers
    def command(self, command, params, confirmation=0):
        p = list(params) + [0.0] * (7 - len(params))
        self.m.mav.command_long_send(self.sysid, 1, command, confirmation, *p)

    def acks(self, command, count, timeout=3.0):
        results = []
        end = time.monotonic() + timeout
        while len(results) < count and time.monotonic() < end and self.remaining() > 0:
            msg = self.recv(end - time.monotonic())
            if msg is not None and msg.get_type() == "COMMAND_ACK" and msg.command == command:
                results.append(msg.result)
        return results

    def heartbeat(self, pred, what, timeout):
        return self.wait(
            what,
            lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1 and pred(m),
            timeout,
        )

    def param_read(self, name):
        self.m.mav.param_request_read_send(self.sysid, 1, name.encode(), -1)
        return self.wait(
            f"PARAM_VALUE {name}",
            lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name,
            3.0,
        )

    def param_set(self, name, value, ptype):
        self.m.mav.param_set_send(self.sysid, 1, name.encode(), value, ptype)
        got = []
        end = time.monotonic() + 2.0
        while len(got) < 2 and time.monotonic() < end:
            msg = self.recv(end - time.monotonic())
            if msg is not None and msg.get_type() == "PARAM_VALUE" and msg.param_id == name:
                got.append(msg)
        return got

    # ------------------------------------------------------------------ scenario
    def run(self, seconds):
        # 0. Connect.
        hb = self.heartbeat(lambda m: True, "first HEARTBEAT", 10.0)
        self.check("identity", hb.type == mavutil.mavlink.MAV_TYPE_QUADROTOR
                   and hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4,
                   f"type {hb.type} autopilot {hb.autopilot}")
        self.wait("HOME_POSITION", lambda m: m.get_type() == "HOME_POSITION", 10.0)

        # 1+2. Decode everything and measure rates.
        self.record_rates = True
        end = time.monotonic() + seconds
        while time.monotonic() < end and self.remaining() > 0:
            self.recv(end - time.monotonic())
        self.record_rates = False
        rates = {}
        for name, times in self.arrivals.items():
            if len(times) >= 2 and times[-1] > times[0]:
                rates[name] = (len(times) - 1) / (times[-1] - times[0])
        off = {}
        for name, hz in EXPECTED_RATES.items():
            got = rates.get(name, 0.0)
            if abs(got - hz) > 0.2 * hz:
                off[name] = round(got, 2)
        self.rates = {k: round(v, 2) for k, v in sorted(rates.items())}
        errors = len(self.bad) + sum(self.unknown_unverified.values())
        self.check("zero decode errors", errors == 0 and self.m.mav.total_receive_errors == 0,
                   f"bad={self.bad[:5]} unverified={self.unknown_unverified} "
                   f"total_receive_errors={self.m.mav.total_receive_errors}")
        self.check("rates within 20 %", not off, f"off: {off}")

        # 3. Parameters.
        v = self.param_read("MIS_TAKEOFF_ALT")
        self.check("param read", abs(v.param_value - 2.5) < 1e-6
                   and v.param_type == mavutil.mavlink.MAV_PARAM_TYPE_REAL32, f"{v}")
        got = self.param_set("MIS_TAKEOFF_ALT", 3.0, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
        self.check("param set float, PARAM_VALUE twice",
                   len(got) == 2 and all(abs(g.param_value - 3.0) < 1e-6 for g in got), f"{[g.param_value for g in got]}")
        as_float = struct.unpack("<f", struct.pack("<i", 5))[0]
        got = self.param_set("COM_OBL_RC_ACT", as_float, mavutil.mavlink.MAV_PARAM_TYPE_INT32)
        ints = [struct.unpack("<i", struct.pack("<f", g.param_value))[0] for g in got]
        self.check("param set int32 bytewise, PARAM_VALUE twice",
                   len(got) == 2 and ints == [5, 5]
                   and all(g.param_type == mavutil.mavlink.MAV_PARAM_TYPE_INT32 for g in got), f"{ints}")
        restore = struct.unpack("<f", struct.pack("<i", 0))[0]
        self.param_set("COM_OBL_RC_ACT", restore, mavutil.mavlink.MAV_PARAM_TYPE_INT32)

        # 4. OFFBOARD refused without a setpoint stream ...
        cmd = mavutil.mavlink.MAV_CMD_DO_SET_MODE
        self.command(cmd, [1, 6, 0])
        results = self.acks(cmd, 2)
        self.check("offboard refused without stream",
                   len(results) == 2 and results[0] == MAV_RESULT_ACCEPTED and results[1] != MAV_RESULT_ACCEPTED,
                   f"acks {results}")
        hb = self.heartbeat(lambda m: True, "HEARTBEAT", 3.0)
        self.check("mode unchanged", hb.custom_mode == HOLD, f"custom_mode {hb.custom_mode}")

        # ... and with a stream gone stale (older than COM_OF_LOSS_T) ...
        self.stream = (0.0, 0.0, 0.0)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 0.3 and self.remaining() > 0:
            self.recv(0.02)
        self.stream = None
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5 and self.remaining() > 0:
            self.recv(0.02)
        self.command(cmd, [1, 6, 0])
        results = self.acks(cmd, 2)
        self.check("offboard refused with a stale stream",
                   len(results) == 2 and results[1] != MAV_RESULT_ACCEPTED, f"acks {results}")

        # ... accepted as soon as fresh setpoints arrive (PX4 v1.16's offboardCheck: one
        # setpoint younger than COM_OF_LOSS_T; the 1 s of streaming in PX4's docs is advice).
        self.stream = (0.0, 0.0, -5.0)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 0.2 and self.remaining() > 0:
            self.recv(0.02)
        self.command(cmd, [1, 6, 0])
        results = self.acks(cmd, 2)
        self.check("offboard accepted with a fresh stream",
                   results == [MAV_RESULT_ACCEPTED, MAV_RESULT_ACCEPTED], f"acks {results}")
        self.heartbeat(lambda m: m.custom_mode == OFFBOARD, "OFFBOARD in HEARTBEAT", 3.0)

        # 5. Arm and climb to z = -5.
        arm = mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM
        self.command(arm, [1])
        results = self.acks(arm, 1)
        self.check("arm", results == [MAV_RESULT_ACCEPTED], f"acks {results}")
        self.heartbeat(lambda m: m.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED,
                       "armed HEARTBEAT", 3.0)
        p = self.wait("LOCAL_POSITION_NED at z=-5",
                      lambda m: m.get_type() == "LOCAL_POSITION_NED" and abs(m.z + 5.0) < 0.5
                      and abs(m.x) < 0.5 and abs(m.y) < 0.5, 20.0)
        self.check("climbed to z=-5", True, f"z={p.z:.2f}")

        # 6. Land (before stopping the stream), see the disarm.
        land = mavutil.mavlink.MAV_CMD_NAV_LAND
        self.command(land, [0, 0, 0, math.nan, math.nan, math.nan, math.nan])
        results = self.acks(land, 1)
        self.check("land accepted", results == [MAV_RESULT_ACCEPTED], f"acks {results}")
        self.heartbeat(lambda m: m.custom_mode == LAND, "LAND in HEARTBEAT", 3.0)
        self.stream = None
        self.wait("EXTENDED_SYS_STATE ON_GROUND",
                  lambda m: m.get_type() == "EXTENDED_SYS_STATE"
                  and m.landed_state == mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND, 30.0)
        self.heartbeat(lambda m: not (m.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED),
                       "disarmed HEARTBEAT", 15.0)
        self.check("landed and disarmed", True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--port", type=int, required=True, help="UDP port the vehicle sends to (listen here)")
    ap.add_argument("--sysid", type=int, default=1, help="vehicle system id")
    ap.add_argument("--seconds", type=float, default=8.0, help="telemetry measurement window")
    ap.add_argument("--timeout", type=float, default=120.0, help="overall deadline, seconds")
    args = ap.parse_args()

    peer = Peer(args.port, args.sysid, args.timeout)
    ok = True
    error = None
    try:
        peer.run(args.seconds)
    except Failure as e:
        ok = False
        error = str(e)
    except Exception as e:  # a crash is a failure too, with its reason
        ok = False
        error = f"{type(e).__name__}: {e}"
    summary = {
        "ok": ok,
        "error": error,
        "frames": peer.frames,
        "decode_errors": len(peer.bad) + sum(peer.unknown_unverified.values()),
        "total_receive_errors": peer.m.mav.total_receive_errors,
        "verified_outside_dialect": peer.unknown_verified,
        "setpoints_sent": peer.sp_sent,
        "rates_hz": getattr(peer, "rates", {}),
        "checks": peer.checks,
    }
    print(json.dumps(summary))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
