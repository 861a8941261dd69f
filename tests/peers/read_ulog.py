#!/usr/bin/env python3
"""pyulog (PX4's reference ULog reader) reads flight logs and says what they hold.

Prints one JSON line: {"<file>": {"topics": [name...], "sys_name": str,
"vehicle_local_position": {"samples", "max_height_m", "north_m": [min, max],
"east_m": [min, max], "duration_s"}}}; heights are -z (NED). Exit code 0 only if every
file parsed and holds vehicle_local_position, vehicle_attitude and
vehicle_local_position_setpoint.

    python3 tests/peers/read_ulog.py a.ulg b.ulg
"""

import json
import sys

from pyulog import ULog

NEEDED = ("vehicle_local_position", "vehicle_attitude", "vehicle_local_position_setpoint")


def describe(path):
    log = ULog(path)
    topics = sorted({d.name for d in log.data_list})
    out = {"topics": topics, "sys_name": log.msg_info_dict.get("sys_name")}
    lp = [d for d in log.data_list if d.name == "vehicle_local_position"]
    if lp:
        d = lp[0].data
        t = d["timestamp"]
        out["vehicle_local_position"] = {
            "samples": len(t),
            "max_height_m": float(-min(d["z"])),
            "north_m": [float(min(d["x"])), float(max(d["x"]))],
            "east_m": [float(min(d["y"])), float(max(d["y"]))],
            "duration_s": float((t[-1] - t[0]) / 1e6) if len(t) > 1 else 0.0,
        }
    return out


def main():
    report, ok = {}, True
    for path in sys.argv[1:]:
        try:
            r = describe(path)
            ok &= all(n in r["topics"] for n in NEEDED)
        except Exception as e:  # noqa: BLE001 - report any failure to parse
            r, ok = {"error": repr(e)}, False
        report[path] = r
    print(json.dumps(report))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
