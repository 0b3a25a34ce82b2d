"""One small schema check for the tables a user writes or two programs exchange: each key's
kind and whether it is required. The scenario's sections, its fault entries, an expectation
file's [case] and the link's JSON (protocol/link_schema.py) are all checked by it, each
turning the problems into its own one-line error. MicroPython-compatible: the firmware side
of the link uses it too.
"""
# kind -> the Python types a value of it may have (bool is never a number)
KINDS = {"number": (int, float), "int": (int,), "bool": (bool,), "str": (str,),
         "list": (list,), "table": (dict,), "object": (dict,), "str|null": (str, type(None)),
         "any": (object,)}
UNKNOWN = "unknown"
MISSING = "missing"


def is_kind(value, kind):
    """Whether ``value`` is of ``kind`` (a KINDS name)."""
    if isinstance(value, bool) and kind in ("number", "int"):
        return False
    return isinstance(value, KINDS[kind])


def problems(obj, fields):
    """What is wrong with the table ``obj`` against ``fields`` (key -> (kind, required)):
    ``(key, what)`` pairs in the order found, ``what`` being UNKNOWN, MISSING or the kind the
    value should have; an empty list when nothing is."""
    out = []
    for key in obj:
        field = fields.get(key)
        if field is None:
            out.append((key, UNKNOWN))
        elif not is_kind(obj[key], field[0]):
            out.append((key, field[0]))
    for key in fields:
        if fields[key][1] and key not in obj:
            out.append((key, MISSING))
    return out
