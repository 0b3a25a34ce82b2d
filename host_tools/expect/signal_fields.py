"""What a ``signal`` expectation names, checked against what a trace of ours holds: its topic
(a channel of host_tools/trace/topics.py, or a CAN frame of protocol/hexhil.dbc) and its
field (the topic's protobuf schema, the frame's signals)."""
from __future__ import annotations

from hexhil.protocol.errors import BadValue


def check_signal_field(where: str, topic: str, path: str) -> None:
    """A ``signal`` expectation's topic is one a trace of ours has, and its field one that
    topic's messages hold (a protobuf topic's schema, a CAN frame's signals; the firmware's
    own ``/telemetry`` and the violations are free-form): a typo is bad input before
    anything runs, not a FAIL after it."""
    from hexhil.trace import protobuf, topics
    from hexhil.protocol.can_frames import FRAMES

    if topic.startswith(topics.T_CAN_PREFIX) and topic != topics.T_CAN_RAW:
        frame = topic[len(topics.T_CAN_PREFIX):]
        if frame not in FRAMES:
            raise BadValue(f"{where}: key 'topic': no CAN frame {frame!r} in "
                           f"protocol/hexhil.dbc ({', '.join(sorted(FRAMES))})")
        names = [sig[0] for sig in FRAMES[frame][2]]
        if path not in names:
            raise BadValue(f"{where}: key 'field': frame {frame} has no signal {path!r} "
                           f"({', '.join(names)})")
        return
    if topic not in topics.CHANNELS:
        raise BadValue(f"{where}: key 'topic': no topic {topic!r} in a trace "
                       f"({', '.join(sorted(topics.CHANNELS))}, or /can/FRAME)")
    schema, encoding = topics.CHANNELS[topic]
    if encoding != "protobuf":
        return
    desc = protobuf.CLASSES[schema].DESCRIPTOR
    repeated = False
    for part in path.replace("[", ".[").split("."):
        if not part:
            continue
        if part.startswith("["):
            if not repeated or not (part == "[*]" or part[1:-1].lstrip("-").isdigit()):
                raise BadValue(f"{where}: key 'field': {path!r}: {part} follows no list")
            repeated = False
            continue
        if desc is None or part not in desc.fields_by_name:
            have = ", ".join(desc.fields_by_name) if desc is not None else "none"
            raise BadValue(f"{where}: key 'field': {path!r}: no field {part!r} in "
                           f"{topic}'s messages (fields here: {have})")
        fd = desc.fields_by_name[part]
        desc = fd.message_type
        repeated = fd.is_repeated
