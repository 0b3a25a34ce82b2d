# protocol/link_schema.py under the real micropython binary: the JSON both ends of the link
# agree on, checked against what the firmware really sends and takes.
import json

from firmware import config
from protocol import link_schema as ls
from protocol import schema
from protocol import sim_link
from tests.micropython.checks import check, done


def keys(table):
    return [row[0] for row in table]


for name, table in (("CONFIG", ls.CONFIG), ("STATS", ls.STATS), ("TACTILE", ls.TACTILE),
                    ("FAULT", ls.FAULT)):
    check(len(set(keys(table))) == len(table), name + " keys distinct")
    for key, kind, unit, meaning in table:
        check(kind in schema.KINDS and isinstance(unit, str) and meaning, name + " row " + key)
check(sorted(keys(ls.CONFIG)) == sorted(config.DEFAULTS), "CONFIG is the firmware's defaults")
check(ls.problems(config.DEFAULTS, ls.CONFIG, True) == [], "defaults match their types")
check(ls.problems({"cycle_hz": "fast"}, ls.CONFIG) == ["cycle_hz should be number, not 'fast'"],
      "a wrong type is named")
check(ls.problems({"baud": True}, ls.CONFIG) == ["baud should be int, not True"],
      "a bool is not a number")
check(ls.problems({"colour": 1}, ls.CONFIG) == ["unknown key 'colour'"], "unknown key named")
check(ls.problems([], ls.STATS) == ["not a JSON object"], "not an object")
check(ls.problems({"leg": "LF"}, ls.TACTILE, True) != [], "required keys missing")
edge = json.loads(json.dumps({ls.LEG: "LF", ls.SWITCH: 1}))
check(ls.problems(edge, ls.TACTILE) == [], "a switch edge event")
check(ls.problems({ls.NAME: "x", ls.DETAIL: "y"}, ls.FAULT, True) == [], "a fault event")
err = sim_link.error_reply("no")
check(err == b"\x0a\x00" + sim_link.ERROR_MARK + b"no", "error reply bytes")
long_err = sim_link.error_reply("x" * 5000)
check(len(long_err) == 2 + sim_link.MAX_REPLY_LEN, "error reply cut to the limit")
done("link_schema")
