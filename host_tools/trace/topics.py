"""The trace's topics, their schemas and encodings: the one place the recorder and every
reader (trace tools, replay, estimate) learn them.

==================  ==============================  ====================================
Recorder method     topic                           schema (encoding)
==================  ==============================  ====================================
``serial``          ``/serial``                     ``hexhil.SerialBytes`` (protobuf)
``can``             ``/can/raw``                    ``hexhil.CanFrame`` (protobuf)
(DBC-decoded)       ``/can/<frame name>``           ``hexhil.can.<frame name>`` (jsonschema)
``switch_edge``     ``/switches``                   ``hexhil.SwitchEdge`` (protobuf)
``telemetry``       ``/telemetry``                  ``hexhil.Telemetry`` (jsonschema)
``servo_state``     ``/servos``                     ``hexhil.ServoStates`` (protobuf)
``body_pose``       ``/body``                       ``foxglove.FrameTransform`` (protobuf)
``joints``          ``/joints``                     ``foxglove.JointStates`` (protobuf)
``fault``           ``/faults``                     ``foxglove.Log`` (protobuf)
``link``            ``/link``                       ``hexhil.LinkExchanges`` (protobuf)
``violation``       ``/bus/violations``             ``hexhil.BusViolation`` (jsonschema)
``scene``           ``/scene``                      ``foxglove.SceneUpdate`` (protobuf)
``scene_frames``    ``/scene/frames``               ``foxglove.FrameTransforms`` (protobuf)
``scene_forces``    ``/scene/forces``               ``foxglove.SceneUpdate`` (protobuf)
==================  ==============================  ====================================

Foxglove plots protobuf and jsonschema messages without plugins; its well-known names
are used where one exists (FrameTransform, JointStates, Log, and the 3D scene's
SceneUpdate and FrameTransforms: geometry once and on change, moving frames and forces at
the 10 Hz ground-truth rate, written only when the run asks for the scene). CAN has no well-known
schema, so frames are logged raw and, per DBC frame, decoded into plain numbers.
"""
from __future__ import annotations

PROFILE = ""  # MCAP profile: none of the ROS profiles apply
METADATA_NAME = "hexhil"  # the metadata record: scenario, seed, software_version...

T_SERIAL = "/serial"
T_CAN_RAW = "/can/raw"
T_CAN_PREFIX = "/can/"  # + DBC frame name: that frame's signals in SI units
T_SWITCHES = "/switches"
T_TELEMETRY = "/telemetry"
T_SERVOS = "/servos"
T_BODY = "/body"
T_JOINTS = "/joints"
T_FAULTS = "/faults"
T_LINK = "/link"
T_VIOLATIONS = "/bus/violations"  # the master's protocol mistakes (hil/servobus/master_check.py)
T_SCENE = "/scene"
T_SCENE_FRAMES = "/scene/frames"
T_SCENE_FORCES = "/scene/forces"

CAN_SCHEMA_PREFIX = "hexhil.can."  # + DBC frame name (jsonschema)

# topic -> (schema name, message encoding) for every topic but the per-frame CAN ones
CHANNELS: dict[str, tuple[str, str]] = {
    T_SERIAL: ("hexhil.SerialBytes", "protobuf"),
    T_CAN_RAW: ("hexhil.CanFrame", "protobuf"),
    T_SWITCHES: ("hexhil.SwitchEdge", "protobuf"),
    T_TELEMETRY: ("hexhil.Telemetry", "json"),
    T_SERVOS: ("hexhil.ServoStates", "protobuf"),
    T_BODY: ("foxglove.FrameTransform", "protobuf"),
    T_JOINTS: ("foxglove.JointStates", "protobuf"),
    T_FAULTS: ("foxglove.Log", "protobuf"),
    T_LINK: ("hexhil.LinkExchanges", "protobuf"),
    T_VIOLATIONS: ("hexhil.BusViolation", "json"),
    T_SCENE: ("foxglove.SceneUpdate", "protobuf"),
    T_SCENE_FRAMES: ("foxglove.FrameTransforms", "protobuf"),
    T_SCENE_FORCES: ("foxglove.SceneUpdate", "protobuf"),
}


def schema_encoding(message_encoding: str) -> str:
    """The MCAP schema encoding of a channel's message encoding."""
    return "protobuf" if message_encoding == "protobuf" else "jsonschema"
