"""The host's tools for each Dynamixel protocol, one folder a tool, one module a protocol:
decode/ (packets as records for humans, and the packets the trace carries beside the
serial bytes) and conformance/ (check a bus against the spec). Each folder's ``__init__``
is its registry keyed by the protocol version a model speaks (protocol/dynamixel/models.py).
"""
