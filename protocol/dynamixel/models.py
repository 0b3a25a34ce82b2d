"""The servo models hexhil speaks to: a model's name -> its control table and protocol.

This is the one registry of models (as python-can's ``BACKENDS`` is of interfaces); every
other floor keys its own per-protocol parts by the version found here: hil/servobus/
protocols/ (the line's packet layer, the emulated servo, the master check),
host_tools/dynamixel/ (decoding, conformance), firmware/servo_bus/ (the firmware's master).
A new Protocol 1.0 or 2.0 model is its control-table module (the same names as ax12.py or
xl430.py) and one line here. MicroPython-compatible.
"""
from protocol.dynamixel import ax12, v1, v2, xl430, xm430

DEFAULT = ax12.MODEL_NAME

# name -> (control-table module, Dynamixel protocol version)
MODELS = {
    ax12.MODEL_NAME: (ax12, 1),
    xl430.MODEL_NAME: (xl430, 2),
    xm430.MODEL_NAME: (xm430, 2),
}


def check(name):
    """``name`` if it is a model, else ValueError naming the models."""
    if name not in MODELS:
        raise ValueError("unknown servo model %r (one of %s)" % (name, ", ".join(MODELS)))
    return name


def default_model(version):
    """The model a line of protocol ``version`` is taken to carry when nothing says: the
    default model, or the first of that protocol's."""
    if MODELS[DEFAULT][1] == version:
        return DEFAULT
    for name, (_, v) in MODELS.items():
        if v == version:
            return name
    raise ValueError("no servo model speaks Protocol %s" % version)


def table(name):
    """The control-table module of a model (addresses, fields, units, limits)."""
    return MODELS[check(name)][0]


def protocol(name):
    """The Dynamixel protocol version a model speaks (1 or 2)."""
    return MODELS[check(name)][1]


CODECS = {1: v1, 2: v2}   # each protocol's packets: build, parse, names


def codec(name):
    """The packet module (protocol/dynamixel/v1.py or v2.py) of a model's protocol."""
    return CODECS[protocol(name)]


def by_number(version, model_number):
    """The model that answers a PING with ``model_number`` in protocol ``version``, or None."""
    for name, (t, v) in MODELS.items():
        if v == version and t.MODEL_NUMBER == model_number:
            return name
    return None
