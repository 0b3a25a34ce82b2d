# protocol/schema.py under the real micropython binary: the one table checker both ends of
# the link (and the host's scenario and expectation files) use.
from protocol import schema
from tests.micropython.checks import check, done

FIELDS = {"id": ("int", True), "at_s": ("number", True), "name": ("str", False),
          "on": ("bool", False), "ids": ("list", False), "why": ("str|null", False)}

check(schema.problems({"id": 3, "at_s": 1}, FIELDS) == [], "a good table")
check(schema.problems({"id": 3, "at_s": 1.5, "name": "x", "on": True, "ids": [1],
                       "why": None}, FIELDS) == [], "every kind")
check(schema.problems({"at_s": 1.0}, FIELDS) == [("id", schema.MISSING)], "missing key")
check(schema.problems({"id": 1, "at_s": 0, "when": 2}, FIELDS) == [("when", schema.UNKNOWN)],
      "unknown key")
check(schema.problems({"id": True, "at_s": "1"}, FIELDS) == [("id", "int"), ("at_s", "number")],
      "bool is no number, a string no number")
check(schema.problems({"id": 2.0, "at_s": 1}, FIELDS) == [("id", "int")], "float is no int")
check(schema.is_kind(None, "str|null") and not schema.is_kind(0, "bool"), "nullable, bool")
check(schema.is_kind({}, "table") and schema.is_kind({}, "object") and schema.is_kind(5, "any"),
      "tables and any")
done("schema")
