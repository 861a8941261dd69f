"""Reads an MCAP recording of skein with the reference `mcap` reader (PyPI) and prints,
as one JSON object, what every channel holds: schema name and encoding, message
encoding, message count, and facts the Rust test checks (setpoint type_masks, command
names, event types, mission names and states, JPEG magic of the camera frames,
LocationFix ranges).

usage: read_mcap.py FILE.mcap
"""
import base64
import json
import sys

from mcap.reader import make_reader


def main() -> int:
    path = sys.argv[1]
    channels = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            c = channels.setdefault(
                channel.topic,
                {
                    "schema": schema.name if schema else None,
                    "schema_encoding": schema.encoding if schema else None,
                    "message_encoding": channel.message_encoding,
                    "count": 0,
                    "json_errors": 0,
                    "facts": {},
                },
            )
            c["count"] += 1
            try:
                value = json.loads(message.data)
            except ValueError:
                c["json_errors"] += 1
                continue
            facts = c["facts"]
            if schema and schema.encoding == "jsonschema":
                json.loads(schema.data)  # the schema itself must be JSON
            if channel.topic.endswith("/sent"):
                if value.get("message") == "SET_POSITION_TARGET_LOCAL_NED":
                    facts.setdefault("type_masks", [])
                    if value["type_mask"] not in facts["type_masks"]:
                        facts["type_masks"].append(value["type_mask"])
                facts.setdefault("messages", [])
                if value.get("message") not in facts["messages"]:
                    facts["messages"].append(value.get("message"))
                if value.get("message") == "COMMAND_LONG":
                    facts.setdefault("commands", [])
                    if value["command"] not in facts["commands"]:
                        facts["commands"].append(value["command"])
            elif channel.topic == "/skein/events":
                facts.setdefault("types", [])
                if value.get("type") not in facts["types"]:
                    facts["types"].append(value.get("type"))
            elif channel.topic == "/skein/missions":
                for m in value["missions"]:
                    for key, seen in (("names", m["name"]), ("states", m["state"])):
                        if seen not in facts.setdefault(key, []):
                            facts[key].append(seen)
            elif channel.topic == "/skein/commands":
                facts.setdefault("commands", []).append(value["request"].get("command"))
            elif schema and schema.name == "foxglove.CompressedImage":
                jpeg = base64.b64decode(value["data"])
                facts["jpeg"] = jpeg[:2] == b"\xff\xd8" and jpeg[-2:] == b"\xff\xd9"
                facts["format"] = value["format"]
                facts["stamped"] = value["timestamp"]["sec"] > 1_600_000_000
            elif schema and schema.name == "foxglove.LocationFix":
                facts["lat_deg"] = value["latitude"]
                facts["lon_deg"] = value["longitude"]
            elif channel.topic.endswith("/state"):
                facts["armed_seen"] = facts.get("armed_seen", False) or value["armed"]
    stats = summary.statistics if summary else None
    print(
        json.dumps(
            {
                "channels": channels,
                "message_count": stats.message_count if stats else None,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
